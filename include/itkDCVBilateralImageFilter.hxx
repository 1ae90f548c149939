/*=========================================================================
 *
 *  Copyright NumFOCUS
 *
 *  Licensed under the Apache License, Version 2.0 (the "License");
 *  you may not use this file except in compliance with the License.
 *  You may obtain a copy of the License at
 *
 *         http://www.apache.org/licenses/LICENSE-2.0.txt
 *
 *  Unless required by applicable law or agreed to in writing, software
 *  distributed under the License is distributed on an "AS IS" BASIS,
 *  WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
 *  See the License for the specific language governing permissions and
 *  limitations under the License.
 *
 *=========================================================================*/
#ifndef itkDCVBilateralImageFilter_hxx
#define itkDCVBilateralImageFilter_hxx

#include "itkDCVBilateralImageFilter.h"
#include "itkGaussianImageSource.h"
#include "itkImageRegionConstIterator.h"
#include "itkMath.h"
#include "itkTotalProgressReporter.h"

#include <algorithm>
#include <cmath>
#include <type_traits>

namespace itk
{

template <typename TInputImage, typename TOutputImage>
void
DCVBilateralImageFilter<TInputImage, TOutputImage>::BeforeThreadedGenerateData()
{
  // The domain kernel and the range table exactly as BilateralImageFilter::BeforeThreadedGenerateData
  // makes them (its own members are private), without its statistics of the whole input.
  const TInputImage *  input = this->GetInput();
  const auto           spacing = input->GetSpacing();
  const auto           origin = input->GetOrigin();
  const auto           sigmas = this->GetDomainSigma();
  Size<ImageDimension> kernelSize;
  for (unsigned int d = 0; d < ImageDimension; ++d)
  {
    m_KernelRadius[d] = this->GetAutomaticKernelSize()
                          ? SizeValueType(std::ceil(this->GetDomainMu() * sigmas[d] / spacing[d]))
                          : this->GetRadius()[d];
    kernelSize[d] = 2 * m_KernelRadius[d] + 1;
  }
  using GaussianImageType = Image<double, ImageDimension>;
  auto gaussian = GaussianImageSource<GaussianImageType>::New();
  gaussian->SetSize(kernelSize);
  gaussian->SetSpacing(spacing);
  gaussian->SetOrigin(origin);
  gaussian->SetScale(1.0);
  gaussian->SetNormalized(true);
  typename GaussianImageSource<GaussianImageType>::ArrayType mean, sigma;
  for (unsigned int d = 0; d < ImageDimension; ++d)
  {
    mean[d] = spacing[d] * m_KernelRadius[d] + origin[d];
    sigma[d] = sigmas[d];
  }
  gaussian->SetSigma(sigma);
  gaussian->SetMean(mean);
  gaussian->Update();
  const auto * kernelImage = gaussian->GetOutput();
  double       norm = 0.0;
  for (ImageRegionConstIterator<GaussianImageType> it(kernelImage, kernelImage->GetBufferedRegion()); !it.IsAtEnd();
       ++it)
  {
    norm += it.Get();
  }
  m_Kernel.clear();
  m_Steps.clear();
  const auto & offsets = input->GetOffsetTable();
  for (ImageRegionConstIterator<GaussianImageType> it(kernelImage, kernelImage->GetBufferedRegion()); !it.IsAtEnd();
       ++it)
  {
    m_Kernel.push_back(it.Get() / norm);
    int64_t step = 0;
    for (unsigned int d = 0; d < ImageDimension; ++d)
    {
      step += (int64_t(it.GetIndex()[d]) - int64_t(m_KernelRadius[d])) * int64_t(offsets[d]);
    }
    m_Steps.push_back(step);
  }

  const double rangeSigma = this->GetRangeSigma();
  const double rangeVariance = rangeSigma * rangeSigma;
  const double rangeDenominator = rangeSigma * std::sqrt(2.0 * Math::pi);
  const auto   samples = this->GetNumberOfRangeGaussianSamples();
  m_Threshold = RangeMu * rangeSigma;
  const double tableDelta = m_Threshold / double(samples);
  m_RangeTable.resize(samples);
  double v = 0.0;
  for (unsigned long i = 0; i < samples; ++i, v += tableDelta)
  {
    m_RangeTable[i] = std::exp(-0.5 * v * v / rangeVariance) / rangeDenominator;
  }
  m_TableScale = double(samples) / m_Threshold;
  // Integer pixels: the weight of each integer distance below the threshold, then one 0 for the rest
  // (none when the threshold is so wide that the table would not pay).
  m_IntegerWeights.clear();
  if (IntegerDistances && m_Threshold < double(MaximumIntegerWeights))
  {
    for (int64_t d = 0; double(d) < m_Threshold; ++d)
      m_IntegerWeights.push_back(m_RangeTable[Math::Floor<SizeValueType>(double(d) * m_TableScale)]);
    m_IntegerWeights.push_back(0.0);
  }
}

template <typename TInputImage, typename TOutputImage>
void
DCVBilateralImageFilter<TInputImage, TOutputImage>::DynamicThreadedGenerateData(
  const OutputImageRegionType & outputRegionForThread)
{
  using RealType = typename NumericTraits<typename TOutputImage::PixelType>::RealType;
  const TInputImage *   input = this->GetInput();
  TOutputImage *        output = this->GetOutput();
  const auto            buffered = input->GetBufferedRegion();
  const auto *          pixels = input->GetBufferPointer();
  const auto &          offsets = input->GetOffsetTable();
  const std::size_t     taps = m_Kernel.size();
  const double          threshold = m_Threshold, scale = m_TableScale;
  const double *        kernel = m_Kernel.data();
  const int64_t *       steps = m_Steps.data();
  const double *        table = m_RangeTable.data();
  TotalProgressReporter progress(this, output->GetRequestedRegion().GetNumberOfPixels());

  // One neighbour's terms, added as ITK adds them. A neighbour beyond the range threshold adds +0 to sums
  // that start at +0 and stay positive: the same sums as ITK's branch, without its mispredictions (the
  // sign of the distance and the threshold test depend on the data). Integer pixels are at integer
  // distances, whose range weights (0 from the threshold on) are a table of their own; a real pixel
  // keeps the select, since a non-finite pixel times 0 would be NaN.
  const double * integerWeights = m_IntegerWeights.data();
  const int64_t  lastDistance = int64_t(m_IntegerWeights.size()) - 1;
  auto           add = [&](std::size_t i, RealType pixel, RealType center, RealType & value, RealType & norm) {
    if constexpr (IntegerDistances)
    {
      if (lastDistance >= 0)
      {
        const int64_t  distance = std::abs(int64_t(pixel) - int64_t(center));
        const RealType product = kernel[i] * integerWeights[std::min(distance, lastDistance)];
        norm += product;
        value += pixel * product;
        return;
      }
    }
    const RealType distance = std::abs(pixel - center); // ITK negates negative distances: the same value
    const bool     near = distance < threshold;
    const RealType product = kernel[i] * table[Math::Floor<SizeValueType>(near ? distance * scale : 0.0)];
    norm += near ? product : 0.0;
    value += near ? pixel * product : 0.0;
  };

  // Lines along x. Interior voxels read their neighbours by offsets, four at a time (four independent
  // chains of sums keep the core busy; each voxel's own sums stay in ITK's order); the others by
  // clamped indices (ITK's zero-flux Neumann condition on the buffered region).
  const auto lineLength = outputRegionForThread.GetSize(0);
  auto       lineRegion = outputRegionForThread;
  lineRegion.SetSize(0, 1);
  Index<ImageDimension> low, high;
  for (unsigned int d = 0; d < ImageDimension; ++d)
  {
    low[d] = buffered.GetIndex(d);
    high[d] = buffered.GetIndex(d) + IndexValueType(buffered.GetSize(d)) - 1;
  }
  std::vector<Index<ImageDimension>> kernelOffsets(taps);
  {
    Index<ImageDimension> k;
    k.Fill(0);
    for (std::size_t i = 0; i < taps; ++i)
    {
      for (unsigned int d = 0; d < ImageDimension; ++d)
        kernelOffsets[i][d] = k[d] - IndexValueType(m_KernelRadius[d]);
      for (unsigned int d = 0; d < ImageDimension; ++d) // the next index, x fastest
      {
        if (++k[d] <= IndexValueType(2 * m_KernelRadius[d]))
          break;
        k[d] = 0;
      }
    }
  }
  using OutputPixelType = typename TOutputImage::PixelType;
  constexpr SizeValueType block = 4;
  for (ImageRegionConstIterator<TOutputImage> line(output, lineRegion); !line.IsAtEnd(); ++line)
  {
    const Index<ImageDimension> first = line.GetIndex();
    bool                        rowInside = true;
    for (unsigned int d = 1; d < ImageDimension; ++d)
    {
      rowInside = rowInside && first[d] - IndexValueType(m_KernelRadius[d]) >= low[d] &&
                  first[d] + IndexValueType(m_KernelRadius[d]) <= high[d];
    }
    OutputPixelType * out = output->GetBufferPointer() + output->ComputeOffset(first);
    const auto *      c = pixels + input->ComputeOffset(first); // the line's first voxel
    // The interior voxels of the line: [begin, end).
    const IndexValueType r = IndexValueType(m_KernelRadius[0]);
    SizeValueType        begin = 0, end = 0;
    if (rowInside)
    {
      const IndexValueType from = std::max(first[0], low[0] + r),
                           to = std::min(first[0] + IndexValueType(lineLength), high[0] - r + 1);
      if (from < to)
      {
        begin = SizeValueType(from - first[0]);
        end = SizeValueType(to - first[0]);
      }
    }
    for (SizeValueType n = 0; n < lineLength; ++n)
    {
      if (n >= begin && n + block <= end)
      {
        RealType value[block] = {}, norm[block] = {}, center[block];
        for (SizeValueType k = 0; k < block; ++k)
          center[k] = static_cast<RealType>(c[n + k]);
        for (std::size_t i = 0; i < taps; ++i)
        {
          const auto * p = c + int64_t(n) + steps[i];
          for (SizeValueType k = 0; k < block; ++k)
            add(i, static_cast<RealType>(p[k]), center[k], value[k], norm[k]);
        }
        for (SizeValueType k = 0; k < block; ++k)
          out[n + k] = static_cast<OutputPixelType>(value[k] / norm[k]);
        n += block - 1;
        continue;
      }
      const RealType center = static_cast<RealType>(c[n]);
      RealType       value = 0.0, norm = 0.0;
      if (n >= begin && n < end)
      {
        for (std::size_t i = 0; i < taps; ++i)
          add(i, static_cast<RealType>(c[int64_t(n) + steps[i]]), center, value, norm);
      }
      else
      {
        Index<ImageDimension> index = first;
        index[0] += IndexValueType(n);
        for (std::size_t i = 0; i < taps; ++i)
        {
          int64_t offset = 0;
          for (unsigned int d = 0; d < ImageDimension; ++d)
          {
            const IndexValueType at = std::clamp(index[d] + kernelOffsets[i][d], low[d], high[d]);
            offset += int64_t(at - low[d]) * int64_t(offsets[d]);
          }
          add(i, static_cast<RealType>(pixels[offset]), center, value, norm);
        }
      }
      out[n] = static_cast<OutputPixelType>(value / norm);
    }
    progress.Completed(lineLength);
  }
}

} // namespace itk

#endif
