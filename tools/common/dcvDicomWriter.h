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
#ifndef dcvDicomWriter_h
#define dcvDicomWriter_h

// DICOM series out (DCMTK): a decoded .dcv volume as one file per slice, a derived, lossy series of the
// original study (its patient, study and frame of reference from the .dcv metadata), or of a new
// placeholder study when the volume did not come from DICOM.
#include "dcvFileFormat.h"

#include <functional>
#include <string>
#include <vector>

namespace dcv::tools
{

/** Writes the volume `voxels` (the header's grid, x fastest, as doubles of the decoded values, slice by
 * slice through `slice`) into `directory`: IM000001.dcm, ... The directory must not exist or be empty
 * (unless `force`); the series is written to a temporary directory beside it and renamed at the end, so
 * that a failure leaves nothing. `compressedBytes` gives the Lossy Image Compression Ratio. */
void
WriteDicomSeries(const FileHeader & header, std::size_t compressedBytes,
                 const std::function<void(int32_t z, std::vector<double> & values)> & slice,
                 const std::string & directory, bool force);

/** "DCMTK 3.6.7": the DICOM writer's library and the version the programs were built with. */
std::string
DicomLibraryVersion();

} // namespace dcv::tools

#endif
