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
// dcv compress: a volume into a .dcv file, through the library's encoder.
#include "dcvCommand.h"
#include "itkDCVEncoder.h"

#include <algorithm>
#include <iomanip>
#include <iostream>
#include <sstream>

namespace dcv::tools
{
namespace
{
struct CompressOptions
{
  std::string   input;
  std::string   output;
  MethodOptions method;
  TargetOptions targets;
};

// The stages one after another on the encoder's thread, so that they add up to `seconds`: the residual
// layer's share is the time the points' stages waited for its thread and the choice of the file; its
// thread's own time, beside the points, is given in brackets.
void
PrintSecondsByStage(const EncoderResult::Timings & t, double seconds)
{
  const double other =
    std::max(0.0, t.total - t.smoothing - t.refinement - t.decimation - t.leastSquares - t.residualLayerOnPath);
  const double io = std::max(0.0, seconds - t.total);
  auto         stage = [seconds](double s) {
    std::ostringstream out;
    out << s << " (" << std::fixed << std::setprecision(1) << 100.0 * s / std::max(seconds, 1e-9) << "%)";
    return out.str();
  };
  std::cout << "seconds by stage: reading and writing " << stage(io) << ", smoothing " << stage(t.smoothing)
            << ", refinement " << stage(t.refinement) << ", decimation " << stage(t.decimation) << ", least squares "
            << stage(t.leastSquares) << ", residual layer " << stage(t.residualLayerOnPath) << " [" << t.residualLayer
            << " in all, beside the points], other " << stage(other) << " (rate control's coding, the PSNR)\n";
}

void
Compress(const CompressOptions & c)
{
  EncoderOptions options = c.method.Checked("compressing");
  const auto     start = std::chrono::steady_clock::now();
  EncoderResult  r;
  WithVolume(c.input, c.method.series, c.output, c.method, true, [&](auto image, const VolumeInput & volume) {
    CheckFiniteVoxels(image.GetPointer(), c.input);
    DefaultPointsForVolume(options, c.targets.points, image->GetBufferedRegion().GetNumberOfPixels());
    options.metadata.insert(options.metadata.begin(), volume.metadata.begin(), volume.metadata.end());
    CheckDicomHeaderFits(
      c.input, volume, options, c.method.dicomHeader, image->GetBufferedRegion().GetNumberOfPixels());
    try
    {
      r = itk::DCVEncode(std::move(image), options); // freed once copied: the volume's bytes less at the peak
    }
    catch (const itk::ExceptionObject & e)
    {
      throw Failure("cannot compress " + Quoted(c.input) + ": " + e.GetDescription());
    }
    catch (const std::exception & e)
    {
      throw Failure("cannot compress " + Quoted(c.input) + ": " + e.what());
    }
  });
  WriteOutputBytes(c.output, r.bytes, c.method.force);
  if (!c.method.quiet)
  {
    const double voxels = double(r.header.size.NumberOfVoxels());
    std::cout << "mode: " << (options.maximumError >= 0.0 ? "bounded error" : ModeName(options.mode)) << "\n"
              << "bytes: " << r.bytes.size() << "\n"
              << "bpv: " << double(r.bytes.size()) * 8.0 / voxels << "\n"
              << "points: " << r.header.numberOfPoints << "\n"
              << "residual layer: " << FormatResidualLayer(r.header) << "\n";
    {
      FileHeader           parsed;
      std::vector<uint8_t> payload;
      ParseFile(r.bytes, Quoted(c.output), parsed, payload);
      std::cout << "bytes by part: " << FormatByteSplit(parsed, payload.size(), r.bytes.size()) << "\n";
    }
    std::cout << "step: " << r.header.quantizationStep << "\n"
              << "scale: " << r.header.scale[0] << " " << r.header.scale[1] << " " << r.header.scale[2] << "\n"
              << "PSNR: " << FormatPSNR(r.psnr) << "\n"
              << "maximum error: " << FormatMaximumError(r.maximumError) << "\n";
    const std::string dicomHeader = FormatDicomHeaderBytes(r.header, r.bytes.size());
    if (!dicomHeader.empty())
      std::cout << "DICOM header: " << dicomHeader << "\n";
    const double seconds = SecondsSince(start);
    std::cout << "seconds: " << seconds << "\n";
    PrintSecondsByStage(r.timings, seconds);
  }
}

const RegisterCommand compress{ { "compress",
                                  "Compress a volume into a .dcv file; prints bytes, bpv, points, step, PSNR (of what "
                                  "decompress gives) and seconds",
                                  [](CLI::App & command) -> std::function<void()> {
                                    auto c = std::make_shared<CompressOptions>();
                                    AddMethodOptions(command, c->input, c->method);
                                    command.add_option("OUTPUT", c->output, "Output .dcv file")->required();
                                    c->targets = AddTargetOptions(command, c->method.encoder);
                                    return [c] { Compress(*c); };
                                  } } };
} // namespace
} // namespace dcv::tools
