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

// The library DelaunayCompressionGDCM, loaded by the programs when they meet DICOM (dcvGDCM.h): the only
// code of the project that links GDCM.
#include "dcvGDCM.h"

#include "itkGDCMImageIO.h"
#include "itkGDCMImageIOFactory.h"
#include "itkGDCMSeriesFileNames.h"

namespace
{
itk::ImageIOBase::Pointer
NewImageIO()
{
  return itk::GDCMImageIO::New().GetPointer();
}

dcv::tools::DicomSeriesList
SeriesFileNames(const std::string & directory)
{
  auto names = itk::GDCMSeriesFileNames::New();
  names->SetUseSeriesDetails(false); // by Series Instance UID alone: size and geometry are checked later
  names->SetDirectory(directory);
  dcv::tools::DicomSeriesList series;
  for (const auto & uid : names->GetSeriesUIDs())
  {
    series.emplace_back(uid, names->GetFileNames(uid));
  }
  return series;
}
} // namespace

/** Called once, by the loader (dcvGDCM.cxx). */
extern "C" __attribute__((visibility("default"))) const dcv::tools::GDCMFunctions *
dcvGDCMFunctions()
{
  static const dcv::tools::GDCMFunctions functions{ NewImageIO, SeriesFileNames };
  itk::GDCMImageIOFactory::RegisterOneFactory();
  return &functions;
}
