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
// dcv convert: a volume as compress reads it (a DICOM series in Hounsfield units, NRRD, NIfTI, ...)
// into any image format ITK writes, losslessly: what the other codecs of a comparison are given.
#include "dcvCommand.h"

namespace dcv::tools
{
namespace
{
struct ConvertOptions
{
  std::string   input;
  std::string   output;
  MethodOptions method; // --series, --resample, --force, --quiet
};

const RegisterCommand convert{
  { "convert",
    "Write a volume (or DICOM series) as compress reads it into any image format ITK "
    "writes, losslessly",
    [](CLI::App & command) -> std::function<void()> {
      auto c = std::make_shared<ConvertOptions>();
      command.add_option("INPUT", c->input, "Input volume (NRRD, NIfTI, MetaImage, ...) or DICOM series")->required();
      command.add_option("OUTPUT", c->output, "Output volume (.nrrd, .nii.gz, .mha, ...)")->required();
      command.add_option("--series", c->method.series, "Series Instance UID");
      AddResampleOption(command, c->method);
      command.add_flag("--force,-f", c->method.force, "Overwrite OUTPUT if it exists");
      command.add_flag("--quiet,-q", c->method.quiet, "Print nothing but errors");
      return [c] {
        WithVolume(c->input, c->method.series, c->output, c->method, false, [&](auto image, const VolumeInput &) {
          WriteVolume(image.GetPointer(), c->output, c->method.force);
        });
      };
    } }
};
} // namespace
} // namespace dcv::tools
