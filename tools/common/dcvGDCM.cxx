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
#include "dcvGDCM.h"
#include "dcvTools.h"

#include <filesystem>
#include <mutex>
#include <string>

#include <dlfcn.h>

namespace dcv::tools
{

const GDCMFunctions &
GDCM()
{
  static std::mutex            mutex;
  static const GDCMFunctions * functions = nullptr;
  const std::lock_guard        lock(mutex);
  if (!functions)
  {
    // Beside the module's library, in the build tree as installed. Found from where that library is, not
    // through the program's RUNPATH: a dlopen called through a wrapper (AddressSanitizer's) searches the
    // wrapper's RUNPATH instead. Else wherever the dynamic loader finds it.
    std::string path = DCV_GDCM_LIBRARY;
    Dl_info     module;
    if (dladdr(reinterpret_cast<void *>(&dcv::PSNR), &module) && module.dli_fname)
    {
      const std::string beside = (std::filesystem::path(module.dli_fname).parent_path() / DCV_GDCM_LIBRARY).string();
      if (std::filesystem::exists(beside))
        path = beside;
    }
    void *     library = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    const auto get =
      library ? reinterpret_cast<const GDCMFunctions * (*)()>(dlsym(library, "dcvGDCMFunctions")) : nullptr;
    if (!get)
    {
      const char * error = dlerror();
      throw Failure(std::string("DICOM is read by GDCM through the library ") + DCV_GDCM_LIBRARY +
                    ", which cannot be loaded: " + (error ? error : "unknown error"));
    }
    functions = get(); // the library stays loaded: ITK's factories now hold GDCM's
  }
  return *functions;
}

} // namespace dcv::tools
