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
// DCVBilateralImageFilter against ITK's BilateralImageFilter: the same voxels, bit for bit.
#include "itkDCVBilateralImageFilter.h"
#include "itkExtractImageFilter.h"
#include "itkImageRegionConstIterator.h"
#include "itkImageRegionIterator.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>

namespace
{
/** A volume of noise over blocks (edges the range kernel must keep), with a non-zero start index, an
 * anisotropic spacing and an origin off zero. */
template <typename TImage>
typename TImage::Pointer
NoisyBlocks(typename TImage::SizeType size, double low, double high, unsigned seed)
{
  auto                        image = TImage::New();
  typename TImage::RegionType region;
  typename TImage::IndexType  start = { { 3, -2, 5 } };
  region.SetIndex(start);
  region.SetSize(size);
  image->SetRegions(region);
  const double spacing[3] = { 0.7, 0.9, 2.5 };
  image->SetSpacing(spacing);
  const double origin[3] = { -12.3, 4.56, 78.9 };
  image->SetOrigin(origin);
  image->Allocate();
  std::mt19937                           random(seed);
  std::uniform_real_distribution<double> noise(-0.08, 0.08);
  for (itk::ImageRegionIterator<TImage> it(image, region); !it.IsAtEnd(); ++it)
  {
    const auto   i = it.GetIndex();
    const bool   block = ((i[0] / 4) + (i[1] / 3) + (i[2] / 2)) % 2 == 0;
    const double v = (block ? 0.7 : 0.2) + noise(random);
    it.Set(static_cast<typename TImage::PixelType>(low + (high - low) * v));
  }
  return image;
}

/** Both filters of `image` with the same settings over `requested` (the whole image when empty); true
 * when every voxel has the same bits. */
template <typename TImage>
void
ExpectSameAsITK(const TImage * image, double domainSigmaVoxels, double domainMu, double rangeSigma,
                typename TImage::RegionType requested = {})
{
  using OutputType = itk::Image<float, 3>;
  auto itkFilter = itk::BilateralImageFilter<TImage, OutputType>::New();
  auto ours = itk::DCVBilateralImageFilter<TImage, OutputType>::New();
  typename itk::BilateralImageFilter<TImage, OutputType>::ArrayType sigmas;
  for (unsigned d = 0; d < 3; ++d)
    sigmas[d] = domainSigmaVoxels * image->GetSpacing()[d];
  if (requested.GetNumberOfPixels() == 0)
    requested = image->GetLargestPossibleRegion();
  for (auto * f : { static_cast<itk::BilateralImageFilter<TImage, OutputType> *>(itkFilter.GetPointer()),
                    static_cast<itk::BilateralImageFilter<TImage, OutputType> *>(ours.GetPointer()) })
  {
    f->SetInput(image);
    f->SetDomainSigma(sigmas);
    f->SetDomainMu(domainMu);
    f->SetRangeSigma(rangeSigma);
    f->GetOutput()->SetRequestedRegion(requested);
    f->Update();
  }
  std::size_t                               differing = 0, count = 0;
  itk::ImageRegionConstIterator<OutputType> a(itkFilter->GetOutput(), requested), b(ours->GetOutput(), requested);
  for (; !a.IsAtEnd(); ++a, ++b, ++count)
  {
    const float x = a.Get(), y = b.Get();
    differing += std::memcmp(&x, &y, sizeof(float)) != 0 ? 1 : 0;
  }
  EXPECT_EQ(count, requested.GetNumberOfPixels());
  EXPECT_EQ(differing, 0u) << "of " << count << " voxels";
}
} // namespace

TEST(DCVBilateralImageFilter, SameVoxelsAsITKOnIntegers)
{
  using ImageType = itk::Image<int16_t, 3>;
  const auto image = NoisyBlocks<ImageType>({ { 21, 17, 9 } }, -1000.0, 2000.0, 1);
  ExpectSameAsITK(image.GetPointer(), 1.0, 1.5, 240.0); // the encoder's kernel (radius 2)
  ExpectSameAsITK(image.GetPointer(), 1.0, 2.5, 240.0); // ITK's default kernel (radius 3)
  ExpectSameAsITK(image.GetPointer(), 0.6, 2.5, 50.0);  // a narrow range: many neighbours left out
  // A range too wide for the table of integer distances (4 sigma >= 2^20): the general path.
  using WideImage = itk::Image<int32_t, 3>;
  ExpectSameAsITK(NoisyBlocks<WideImage>({ { 15, 10, 8 } }, -3e7, 4e7, 5).GetPointer(), 1.0, 1.5, 2e6);
}

TEST(DCVBilateralImageFilter, SameVoxelsAsITKOnBytesAndFloats)
{
  using ByteImage = itk::Image<uint8_t, 3>;
  ExpectSameAsITK(NoisyBlocks<ByteImage>({ { 16, 12, 7 } }, 0.0, 255.0, 2).GetPointer(), 1.0, 1.5, 20.0);
  using FloatImage = itk::Image<float, 3>;
  ExpectSameAsITK(NoisyBlocks<FloatImage>({ { 13, 11, 6 } }, -1.0, 1.0, 3).GetPointer(), 1.3, 1.5, 0.1);
}

TEST(DCVBilateralImageFilter, SameVoxelsAsITKOnARequestedSlice)
{
  // How the encoder samples I*: one slice requested, of the whole volume and of a slab extracted around it.
  using ImageType = itk::Image<int16_t, 3>;
  const auto image = NoisyBlocks<ImageType>({ { 20, 14, 12 } }, 0.0, 3000.0, 4);
  auto       slab = image->GetLargestPossibleRegion();
  slab.SetIndex(2, slab.GetIndex(2) + 4);
  slab.SetSize(2, 5);
  auto extract = itk::ExtractImageFilter<ImageType, ImageType>::New();
  extract->SetInput(image);
  extract->SetExtractionRegion(slab);
  extract->Update();
  auto slice = slab;
  slice.SetIndex(2, slab.GetIndex(2) + 2);
  slice.SetSize(2, 1);
  ExpectSameAsITK(extract->GetOutput(), 1.0, 1.5, 240.0, slice);
  ExpectSameAsITK(image.GetPointer(), 1.0, 1.5, 240.0, slice);
}

TEST(DCVBilateralImageFilter, NameAndParameters)
{
  auto filter = itk::DCVBilateralImageFilter<itk::Image<int16_t, 3>, itk::Image<float, 3>>::New();
  EXPECT_STREQ(filter->GetNameOfClass(), "DCVBilateralImageFilter");
  EXPECT_EQ(filter->GetNumberOfRangeGaussianSamples(), 100u); // ITK's default, kept
}
