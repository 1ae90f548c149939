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
#ifndef dcvGDCM_h
#define dcvGDCM_h

// GDCM, through which DICOM is read, sits in a library of its own (DelaunayCompressionGDCM) that the
// programs load on first use: GDCM fills its data dictionaries as soon as its library is loaded, which
// took 26 of the 40 ms every dcv run needed to start, DICOM or not (docs/profile.md).
#include "itkImageIOBase.h"

#include <string>
#include <utility>
#include <vector>

namespace dcv::tools
{

/** The DICOM series of a directory: (Series Instance UID, files sorted along the slice normal) pairs. */
using DicomSeriesList = std::vector<std::pair<std::string, std::vector<std::string>>>;

/** What the library DelaunayCompressionGDCM gives (dcvGDCMFunctions() returns it). */
struct GDCMFunctions
{
  /** A new itk::GDCMImageIO. */
  itk::ImageIOBase::Pointer (*newImageIO)();
  /** itk::GDCMSeriesFileNames of `directory`, grouped by Series Instance UID alone; itk::ExceptionObject
   * when GDCM cannot list it. */
  DicomSeriesList (*seriesFileNames)(const std::string & directory);
};

/** GDCM's functions, its library loaded on the first call; loading it also registers GDCM's ImageIO with
 * ITK's factories, so that ITK's readers and writers then take DICOM file names. Failure naming the
 * library when it cannot be loaded. */
const GDCMFunctions &
GDCM();

} // namespace dcv::tools

#endif
