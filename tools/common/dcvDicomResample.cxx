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
// DICOM series in, --resample: a tilted or unevenly spaced series onto a regular grid along the normal
// of its orientation (the geometry is worked out by CheckDicomSlices).
#include "dcvDicom.h"
#include "dcvTools.h"

#include "dcvGDCM.h"
#include "itkImageSeriesReader.h"
#include "itkLinearInterpolateImageFunction.h"
#include "itkResampleImageFilter.h"

#include <algorithm>
#include <limits>

namespace dcv::tools
{

itk::Image<float, 3>::Pointer
ReadResampledDicomSeries(const DicomSeries & series, const DicomResampling & r)
{
  using ImageType = itk::Image<float, 3>;
  auto reader = itk::ImageSeriesReader<ImageType>::New();
  reader->SetImageIO(GDCM().newImageIO());
  reader->SetFileNames(series.files);
  reader->MetaDataDictionaryArrayUpdateOff();
  // The reader would warn of the uneven spacing that is resampled here.
  reader->SetSpacingWarningRelThreshold(std::numeric_limits<double>::infinity());
  try
  {
    reader->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read the DICOM series " + Quoted(series.files.front()) + ": " + e.GetDescription());
  }
  ImageType::Pointer stack = reader->GetOutput();
  stack->DisconnectPipeline();
  const std::size_t sliceVoxels = std::size_t(r.columns) * std::size_t(r.rows);
  const float *     in = stack->GetBufferPointer();
  const float       minimum = *std::min_element(in, in + sliceVoxels * r.along.size());

  // Uneven spacing: slice m at m * spacing along the normal, linear between the two slices around it.
  ImageType::Pointer even = stack;
  if (r.uneven)
  {
    even = ImageType::New();
    ImageType::SizeType size{ { r.columns, r.rows, r.slices } };
    even->SetRegions(size);
    even->Allocate();
    std::size_t k = 0;
    for (std::size_t m = 0; m < r.slices; ++m)
    {
      const double t = std::min(double(m) * r.spacing[2], r.along.back());
      while (k + 2 < r.along.size() && r.along[k + 1] < t)
        ++k;
      const double  w = std::clamp((t - r.along[k]) / (r.along[k + 1] - r.along[k]), 0.0, 1.0);
      const float * a = in + k * sliceVoxels;
      const float * b = a + sliceVoxels;
      float *       out = even->GetBufferPointer() + m * sliceVoxels;
      for (std::size_t i = 0; i < sliceVoxels; ++i)
        out[i] = float((1.0 - w) * a[i] + w * b[i]);
    }
  }
  PlaceOnGrid(*even, r);
  if (!r.tilted)
  {
    return even;
  }
  const ImageType::PointType     origin = even->GetOrigin();
  const ImageType::SpacingType   spacing = even->GetSpacing();
  const ImageType::DirectionType direction = even->GetDirection();
  // The slices as they lie: each offset by the tilt, the third axis slanted (not orthogonal to the
  // others, which ITK's index-to-point mapping allows); resampled onto the orientation's normal.
  std::array<double, 3> slant;
  for (unsigned i = 0; i < 3; ++i)
    slant[i] = r.direction[3 * i + 2] + r.shear[i];
  const double             length = std::sqrt(slant[0] * slant[0] + slant[1] * slant[1] + slant[2] * slant[2]);
  ImageType::SpacingType   slantSpacing = spacing;
  ImageType::DirectionType slantDirection = direction;
  slantSpacing[2] = spacing[2] * length;
  for (unsigned i = 0; i < 3; ++i)
    slantDirection(i, 2) = slant[i] / length;
  even->SetOrigin(origin);
  even->SetSpacing(slantSpacing);
  even->SetDirection(slantDirection);

  auto resampler = itk::ResampleImageFilter<ImageType, ImageType>::New();
  resampler->SetInput(even);
  resampler->SetInterpolator(itk::LinearInterpolateImageFunction<ImageType, double>::New());
  resampler->SetOutputOrigin(origin);
  resampler->SetOutputSpacing(spacing);
  resampler->SetOutputDirection(direction);
  resampler->SetSize(ImageType::SizeType{ { r.columns, r.rows, r.slices } });
  resampler->SetDefaultPixelValue(minimum); // where no slice reaches: air, for CT
  try
  {
    resampler->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot resample the DICOM series " + Quoted(series.files.front()) + ": " + e.GetDescription());
  }
  return resampler->GetOutput();
}

} // namespace dcv::tools
