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
#ifndef dcvDicom_h
#define dcvDicom_h

// DICOM series in: the series of a directory (or of one DICOM file), the choice among several, the
// checks a derived volume needs (slices stacked along their normal, even spacing, none missing, one
// size and orientation) or, when asked, the resampling of a tilted or unevenly spaced series onto a
// grid, and the attributes a derived series must carry, as .dcv metadata.
#include "dcvFileFormat.h"
#include "dcvGDCM.h"

#include "itkImage.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace dcv::tools
{

/** One DICOM series of a directory. */
struct DicomSeries
{
  std::string              uid;
  std::string              description;
  std::string              modality;
  std::vector<std::string> files; // sorted along the slice normal
  unsigned                 rows{ 0 };
  unsigned                 columns{ 0 };
};

/** Whether `path` is a directory, or a file that GDCM reads as DICOM. */
bool
IsDicomInput(const std::string & path);

/** The series of `path` (a directory, or one DICOM file standing for its series): the one whose UID is
 * `uid`, or the only one. Throws Failure listing the series when there are several and no `uid`, and when
 * there is none. `skipped` counts the files of the directory that are not DICOM. */
DicomSeries
FindDicomSeries(const std::string & path, const std::string & uid, std::size_t & skipped);

/** The DICOM series of one directory as GDCM groups them (by Series Instance UID alone: size and
 * geometry are checked later): (UID, files) pairs. Failure naming the directory when GDCM cannot, or
 * naming a file cut short inside its header (CheckDicomHeaders), before GDCM reads any. */
DicomSeriesList
ListDicomSeries(const std::string & directory);

/** ListDicomSeries of a directory whose files CheckDicomHeaders has checked. */
DicomSeriesList
ListCheckedDicomSeries(const std::string & directory);

/** The pixel type of the series after rescale (int16 for CT in Hounsfield units). */
PixelType
DicomPixelType(const DicomSeries & series);

/** The attributes of the series' first slice that a derived series carries (patient, study, frame of
 * reference, modality, body part, series, equipment, acquisition), as keyword/value pairs. */
std::vector<std::pair<std::string, std::string>>
DicomMetadata(const DicomSeries & series);

/** Per-slice geometry read from each file: position and orientation (patient), rows and columns. */
struct DicomSlice
{
  std::array<double, 3> position{ { 0, 0, 0 } };
  std::array<double, 6> orientation{ { 1, 0, 0, 0, 1, 0 } };
  std::array<double, 2> pixelSpacing{ { 1, 1 } }; // along a row, down a column
  unsigned              rows{ 0 };
  unsigned              columns{ 0 };
  bool                  positioned{ true }; // false: Secondary Capture without Image Position (Patient)
};

/** The geometry of every slice of the series, from each file's header. */
std::vector<DicomSlice>
ReadDicomSlices(const DicomSeries & series);

/** How a series is put on a grid: slices `spacing` mm apart along the normal of the orientation, from the
 * first slice's plane to the last one's. `needed`: a tilted or unevenly spaced series, resampled onto it
 * (ReadResampledDicomSeries); else the grid is the slices' own. */
struct DicomResampling
{
  bool                  needed{ false };
  bool                  tilted{ false };        // gantry tilt: the slices are offset across the normal
  bool                  uneven{ false };        // uneven spacing: slices interpolated onto the new spacing
  std::string           description;            // what was done, e.g. "uneven slice spacing 5-7.5 mm -> 5 mm, ..."
  std::array<double, 3> origin{ { 0, 0, 0 } };  // the first slice's position
  std::array<double, 9> direction{ {} };        // row major; columns: row, column, normal towards the last slice
  std::array<double, 3> spacing{ { 1, 1, 1 } }; // pixel spacing, then the new slice spacing
  std::array<double, 3> shear{ { 0, 0, 0 } };   // tilt: offset across the normal per mm along it
  std::vector<double>   along;                  // each slice's distance from the first along the normal
  std::size_t           slices{ 0 };            // of the grid
  unsigned              rows{ 0 };
  unsigned              columns{ 0 };
};

/** Refuses, with a message naming the series and what was found, slices of different size or
 * orientation, slices not stacked along the normal of their orientation (gantry tilt), uneven spacing
 * and missing slices. With `resample`, a tilted or unevenly spaced series (not one with missing slices)
 * is accepted instead, and the result says how to put it on a grid; without it, the messages of those
 * two refusals name --resample. */
DicomResampling
CheckDicomSlices(const std::string & name, const std::vector<DicomSlice> & slices, bool resample = false);

/** Puts `image` on the grid `r` describes: its origin, spacing and direction. */
template <typename TImage>
void
PlaceOnGrid(TImage & image, const DicomResampling & r)
{
  typename TImage::DirectionType direction;
  for (unsigned i = 0; i < 3; ++i)
  {
    for (unsigned j = 0; j < 3; ++j)
      direction(i, j) = r.direction[3 * i + j];
  }
  image.SetOrigin(r.origin.data());
  image.SetSpacing(r.spacing.data());
  image.SetDirection(direction);
}

/** Reads the series (as floats, rescaled) and resamples it as `r` says: linearly between neighbouring
 * slices onto the new spacing, then, for a tilted series, onto the grid of the orientation's normal with
 * ITK's ResampleImageFilter (linear interpolation; where no slice reaches: the series' minimum). */
itk::Image<float, 3>::Pointer
ReadResampledDicomSeries(const DicomSeries & series, const DicomResampling & r);

/** `image` rounded (integer types) and clamped to the range of T, with its geometry. */
template <typename T>
typename itk::Image<T, 3>::Pointer
RoundedImage(const itk::Image<float, 3> * image)
{
  auto out = itk::Image<T, 3>::New();
  out->CopyInformation(image);
  out->SetRegions(image->GetLargestPossibleRegion());
  out->Allocate();
  const std::size_t n = image->GetLargestPossibleRegion().GetNumberOfPixels();
  const float *     in = image->GetBufferPointer();
  T *               to = out->GetBufferPointer();
  for (std::size_t i = 0; i < n; ++i)
  {
    double v = in[i];
    if (std::numeric_limits<T>::is_integer)
    {
      v = std::clamp(std::round(v), double(std::numeric_limits<T>::lowest()), double(std::numeric_limits<T>::max()));
    }
    to[i] = T(v);
  }
  return out;
}

} // namespace dcv::tools

#endif
