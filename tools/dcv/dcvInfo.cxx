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
// dcv info: the header of a .dcv file.
#include "dcvCommand.h"
#include "dcvBoundedLayer.h"

#include <iostream>

namespace dcv::tools
{
namespace
{
void
Info(const std::string & input)
{
  const CompressedFile file = ReadCompressedFile(input);
  const FileHeader &   h = file.header;
  const double         voxels = double(h.size.NumberOfVoxels());
  std::cout << "file: " << input << "\n"
            << "version: " << int(FileHeader::Version) << "\n"
            << "bytes: " << file.size << " (payload " << file.payload.size() << ")\n"
            << "bytes by part: " << FormatByteSplit(h, file.payload.size(), file.size) << "\n"
            << "bpv: " << double(file.size) * 8.0 / voxels << "\n"
            << "size: " << h.size.x << " " << h.size.y << " " << h.size.z << "\n"
            << "pixel type: " << PixelTypeName(h.pixelType) << "\n"
            << "spacing: " << h.spacing[0] << " " << h.spacing[1] << " " << h.spacing[2] << "\n"
            << "origin: " << h.origin[0] << " " << h.origin[1] << " " << h.origin[2] << "\n"
            << "direction:";
  for (double d : h.direction)
    std::cout << " " << d;
  std::cout << "\n"
            << "mode: "
            << (h.mode <= uint8_t(Mode::Best)       ? ModeName(Mode(h.mode))
                : h.mode == FileHeader::BoundedMode ? "bounded error"
                                                    : "unknown")
            << "\n"
            << "points: " << h.numberOfPoints << "\n"
            << "scale: " << h.scale[0] << " " << h.scale[1] << " " << h.scale[2] << "\n"
            << "quantization: " << h.quantizationOrigin << " + k * " << h.quantizationStep << "\n"
            << "residual layer: ";
  if (h.residualLayer.empty())
    std::cout << "none\n";
  else
  {
    std::cout << FormatResidualLayer(h) << ", step " << h.residualStep;
    if (h.residualLevels > 0)
      std::cout << ", inter-slice wavelet of " << h.residualLevels << " levels";
    std::cout << "\n";
  }
  std::cout << "maximum error: "
            << FormatMaximumError(
                 h.boundedLayer ? ReadBoundedLayerHeader(h.residualLayer, h.size, file.name).maximumError : -1.0)
            << "\n";
  std::cout << "memory to decode: " << FormatByteCount(DecodingMemory(h, DecodeOutput::Volume)) << " (mesh alone "
            << FormatByteCount(DecodingMemory(h, DecodeOutput::Mesh)) << ")\n";
  for (const auto & kv : h.metadata)
  {
    if (kv.first == DicomHeaderKey)
    {
      // Bytes, not text: what it holds and what it costs.
      const DicomHeaderBlock block = SplitDicomHeader(kv.second, file.name);
      std::size_t            own = 0;
      for (const auto & f : block.files)
        own += f.size();
      std::cout << "DICOM header: " << FormatDicomHeaderBytes(h, file.size) << ", " << block.files.size() << " files, "
                << (block.mode == 0 ? "full" : "essential") << ", " << block.common.size() << " bytes common to all, "
                << own << " per file in all (before deflation)\n";
    }
    else
      std::cout << "metadata: " << kv.first << " = " << kv.second << "\n";
  }
}

const RegisterCommand info{ { "info",
                              "Print the header of a .dcv file",
                              [](CLI::App & command) -> std::function<void()> {
                                auto input = std::make_shared<std::string>();
                                command.add_option("FILE", *input, "A .dcv file")->required();
                                return [input] { Info(*input); };
                              } } };
} // namespace
} // namespace dcv::tools
