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
#include "dcvVersion.h"
#include "dcvVideoLayer.h"

#include "itkConfigure.h"

#include <CGAL/version_macros.h>
// The path names the system OpenJPEG 2.5: ITK ships an older, mangled openjpeg.h on its include path.
#include <openjpeg-2.5/openjpeg.h>

namespace dcv
{

std::string
LibraryVersions()
{
  // ITK_VERSION_STRING is major.minor only: the patch level is in its own macro.
  return "ITK " + std::to_string(ITK_VERSION_MAJOR) + "." + std::to_string(ITK_VERSION_MINOR) + "." +
         std::to_string(ITK_VERSION_PATCH) + ", CGAL " + CGAL_VERSION_STR + ", OpenJPEG " + opj_version() + ", " +
         VideoLibraryVersions();
}

} // namespace dcv
