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
// size and orientation), and the attributes a derived series must carry, as .dcv metadata.
#include "dcvFileFormat.h"

#include <array>
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
 * geometry are checked later): (UID, files) pairs. Failure naming the directory when GDCM cannot. */
std::vector<std::pair<std::string, std::vector<std::string>>>
ListDicomSeries(const std::string & directory);

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
  unsigned              rows{ 0 };
  unsigned              columns{ 0 };
};

/** The geometry of every slice of the series, from each file's header. */
std::vector<DicomSlice>
ReadDicomSlices(const DicomSeries & series);

/** Refuses, with a message naming the series and what was found, slices of different size or
 * orientation, slices not stacked along the normal of their orientation (gantry tilt), uneven spacing
 * and missing slices. */
void
CheckDicomSlices(const std::string & name, const std::vector<DicomSlice> & slices);

} // namespace dcv::tools

#endif
