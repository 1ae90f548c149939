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
// dcv decompress: a .dcv file into any image format ITK writes.
#include "dcvCodec.h"
#include "dcvCommand.h"
#include "dcvDicomWriter.h"

#include <iostream>

namespace dcv::tools
{
namespace
{
struct DecompressOptions
{
  std::string  input;
  std::string  output;
  bool         force{ false };
  bool         quiet{ false };
  bool         dicom{ false };
  bool         noCompression{ false };
  DecodeLimits limits;
};

void
Decompress(const DecompressOptions & d)
{
  CheckOutputIsNotInput({ d.input }, d.output);
  const CompressedFile file = ReadCompressedFile(d.input);
  if (!d.dicom)
  {
    CheckOutput(d.output, d.force);
  }
  const auto start = std::chrono::steady_clock::now();
  DecodeVolume(
    file,
    [&](auto image) {
      if (!d.dicom)
      {
        WriteVolume(image.GetPointer(), d.output, d.force, !d.noCompression);
        return;
      }
      const std::size_t sliceVoxels = std::size_t(file.header.size.x) * std::size_t(file.header.size.y);
      WriteDicomSeries(
        file.header,
        file.size,
        [&](int32_t z, std::vector<double> & values) {
          const auto * first = image->GetBufferPointer() + std::size_t(z) * sliceVoxels;
          values.assign(first, first + sliceVoxels);
        },
        d.output,
        d.force);
    },
    d.limits);
  if (!d.quiet)
  {
    std::cout << "seconds: " << SecondsSince(start) << "\n";
  }
}

const RegisterCommand decompress{
  { "decompress",
    "Decode a .dcv file into any image format ITK writes (gzip-compressed where the "
    "format allows)",
    [](CLI::App & command) -> std::function<void()> {
      auto d = std::make_shared<DecompressOptions>();
      command.add_option("INPUT", d->input, "Input .dcv file")->required();
      command.add_option("OUTPUT", d->output, "Output volume (format from its extension)")->required();
      command.add_flag("--force,-f", d->force, "Overwrite OUTPUT if it exists");
      AddMaximumMemoryOption(command, d->limits.maximumMemory, "decoding");
      command.add_flag("--dicom",
                       d->dicom,
                       "OUTPUT is a directory: write a DICOM series (one file per slice, a derived lossy series "
                       "of the original study)");
      command.add_flag("--no-compression",
                       d->noCompression,
                       "Write OUTPUT without gzip where the format has it (.nrrd, .mha): larger, and faster to "
                       "write and to read");
      command.add_flag("--quiet,-q", d->quiet, "Print nothing but errors");
      return [d] { Decompress(*d); };
    } }
};
} // namespace
} // namespace dcv::tools
