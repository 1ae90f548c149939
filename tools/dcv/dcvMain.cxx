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
// dcv: the command-line face of the DelaunayCompression module. The subcommands are the files
// beside this one (dcvCompress.cxx, dcvDecompress.cxx, ...).
#include "dcvCommand.h"
#include "dcvDicomWriter.h"
#include "dcvProgress.h"
#include "dcvResidualLayer.h"
#include "dcvVersion.h"
#include "dcvVideoLayer.h"

#include "itkMacro.h"
#include "itkMultiThreaderBase.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <chrono>
#include <iostream>
#include <sstream>

namespace dcv::tools
{

std::vector<Command> &
Commands()
{
  static std::vector<Command> commands;
  return commands;
}

EncoderOptions
MethodOptions::Checked(const std::string & label) const
{
  EncoderOptions o = encoder;
  if (scale.size() == 3)
  {
    o.scale = { { scale[0], scale[1], scale[2] } };
  }
  o.progress = ProgressOutput(label, quiet);
  if (o.threads > 0)
  {
    // ITK's filters before the encoder (the bilateral filter of I*) keep to the same number.
    itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(o.threads);
  }
  try
  {
    o.mode = ParseMode(mode);
  }
  catch (const std::invalid_argument & e)
  {
    throw UsageError(std::string("--mode: ") + e.what());
  }
  try
  {
    CheckOptions(o);
  }
  catch (const std::invalid_argument & e)
  {
    throw UsageError(e.what());
  }
  return o;
}

void
AddResampleOption(CLI::App & command, MethodOptions & o)
{
  command.add_flag("--resample",
                   o.resample,
                   "Resample a DICOM series with gantry tilt or uneven slice spacing onto a regular grid along the "
                   "normal of its orientation (linear interpolation; the smallest gap) instead of refusing it");
}

void
AddMethodOptions(CLI::App & command, std::string & input, MethodOptions & o)
{
  command.add_option("INPUT", input, "Input volume (NRRD, NIfTI, MetaImage, ...) or DICOM series (a directory)")
    ->required();
  command.add_option("--series", o.series, "Series Instance UID, when the DICOM directory holds several");
  AddResampleOption(command, o);
  command
    .add_option_function<std::string>(
      "--dicom-header",
      [&o](const std::string & text) {
        if (text == "full")
          o.dicomHeader = DicomHeaderMode::Full;
        else if (text == "essential")
          o.dicomHeader = DicomHeaderMode::Essential;
        else
          throw CLI::ValidationError("--dicom-header", "must be full or essential, got " + text);
      },
      "What a DICOM series' headers keep in the .dcv file (counted in its bytes): full (every attribute of every "
      "file, private ones too) or essential (patient, study, series, equipment, frame of reference, image plane "
      "and pixel, character set, VOI LUT, per-slice position and instance). Default: full")
    ->type_name("full|essential");
  command
    .add_option("--mode,-m",
                o.mode,
                "silva (refinement), dec (+ decimation), dec+com (+ combined image approach: the paper's method), "
                "best (dec + least-squares values, without I*)")
    ->capture_default_str();
  command
    .add_option("--domain-sigma", o.encoder.domainSigma, "Bilateral filter of I* (mode dec+com): spatial sigma, voxels")
    ->capture_default_str();
  command
    .add_option("--range-sigma",
                o.encoder.rangeSigma,
                "Bilateral filter of I* (mode dec+com): intensity sigma (0: 8% of the peak)")
    ->capture_default_str();
  command.add_option("--alpha", o.encoder.alpha, "Mode dec+com: choose positions on I* until PSNR >= alpha * PSNR(I*)")
    ->capture_default_str();
  command
    .add_option(
      "--scale", o.scale, "Delaunay space per axis: SX,SY,SZ (integers 1 to 16), or 0,0,0: from the voxel spacing")
    ->delimiter(',')
    ->expected(3);
  command
    .add_option("--threads", o.encoder.threads, "Threads to use (0: one per core); the file does not depend on it")
    ->check(CLI::Range(0u, 1024u))
    ->capture_default_str();
  AddMaximumMemoryOption(command, o.encoder.maximumMemory, "encoding");
  command.add_flag("--force,-f", o.force, "Overwrite OUTPUT if it exists");
  command.add_flag("--quiet,-q", o.quiet, "Print nothing but errors");
}

void
AddMaximumMemoryOption(CLI::App & command, uint64_t & maximumMemory, const std::string & work)
{
  command
    .add_option_function<std::string>(
      "--max-memory",
      [&maximumMemory](const std::string & text) {
        // A number of bytes with an optional binary suffix: 512M, 8G, 1.5T.
        std::size_t  end = 0;
        double       value = -1.0;
        const char * suffixes = "KMGT";
        try
        {
          value = std::stod(text, &end);
        }
        catch (const std::exception &)
        {
          end = 0;
        }
        std::string suffix = text.substr(end);
        double      factor = 1.0;
        if (!suffix.empty())
        {
          const char *      at = std::strchr(suffixes, std::toupper(static_cast<unsigned char>(suffix[0])));
          const std::string rest = suffix.substr(1);
          if (at == nullptr || !(rest.empty() || rest == "B" || rest == "iB"))
          {
            value = -1.0;
          }
          else
          {
            factor = std::pow(1024.0, double(at - suffixes + 1));
          }
        }
        if (end == 0 || !(value >= 0.0) || !(value * factor < 1.8e19))
        {
          throw CLI::ValidationError("--max-memory",
                                     "must be a size in bytes (e.g. 512M, 8G; 0: no limit), got " + text);
        }
        maximumMemory = uint64_t(value * factor);
      },
      "The most memory " + work + " may need (bytes, or K, M, G, T; 0: no limit): a job that needs more is " +
        "refused before anything is allocated. Default: half of the physical memory, " +
        FormatByteCount(DefaultMaximumMemory()))
    ->type_name("SIZE");
}

void
CheckDicomHeaderFits(const std::string & input, const VolumeInput & volume, const EncoderOptions & options,
                     DicomHeaderMode mode, uint64_t voxels)
{
  if (!(options.bitsPerVoxel > 0.0) || volume.dicom.files.empty())
  {
    return;
  }
  const auto containerBytes = [](const std::vector<std::pair<std::string, std::string>> & metadata) {
    FileHeader h;
    h.size = { 2, 2, 2 };
    h.metadata = metadata;
    return SerializeFile(h, {}).size();
  };
  const double budget = std::floor(options.bitsPerVoxel * double(voxels) / 8.0);
  FileHeader   withHeader;
  withHeader.size = { 2, 2, 2 };
  withHeader.metadata = options.metadata;
  const std::size_t header = DicomHeaderBytes(withHeader);
  const std::size_t bytes = containerBytes(options.metadata);
  if (header == 0 || double(bytes) < budget)
  {
    return;
  }
  std::ostringstream message;
  message << "cannot compress " << Quoted(input) << ": its DICOM header (" << DicomHeaderModeName(mode) << ") takes "
          << header << " bytes, the file's header and metadata " << bytes << ", and --bpv " << options.bitsPerVoxel
          << " allows " << std::size_t(budget) << " bytes for the whole file";
  const auto least = [voxels](std::size_t n) { return std::ceil(double(n + 1) * 8.0 / double(voxels) * 1e4) / 1e4; };
  if (mode == DicomHeaderMode::Full)
  {
    auto essential = options.metadata;
    for (auto & kv : essential)
    {
      if (kv.first == DicomHeaderKey)
        kv.second = ReadDicomHeaders(volume.dicom.files, DicomHeaderMode::Essential);
    }
    const std::size_t smaller = containerBytes(essential);
    message << "; --dicom-header essential needs " << smaller << " bytes";
    if (!(double(smaller) < budget))
      message << ", still too many: a larger --bpv (at least " << least(smaller) << " with it, " << least(bytes)
              << " without)";
  }
  else
  {
    message << "; a larger --bpv (at least " << least(bytes) << ") makes it fit";
  }
  throw Failure(message.str());
}

std::string
FormatDicomHeaderBytes(const FileHeader & header, std::size_t fileBytes)
{
  const std::size_t bytes = DicomHeaderBytes(header);
  if (bytes == 0)
  {
    return "";
  }
  std::ostringstream text;
  text.precision(3);
  text << bytes << " bytes (" << 100.0 * double(bytes) / double(std::max<std::size_t>(1, fileBytes))
       << "% of the file)";
  return text.str();
}

TargetOptions
AddTargetOptions(CLI::App & command, EncoderOptions & e)
{
  TargetOptions t;
  t.bpv = command.add_option(
    "--bpv", e.bitsPerVoxel, "Bits per voxel of the whole file (the point count and step are chosen)");
  t.psnr = command.add_option("--psnr", e.psnr, "Quality target, dB: the smallest file whose decoded PSNR reaches it");
  t.points = command.add_option("--points,-n", e.numberOfPoints, "Number of significant points (at least 8)")
               ->check(CLI::NonNegativeNumber)
               ->capture_default_str();
  t.maximumError =
    command
      .add_option("--max-error",
                  e.maximumError,
                  "Bound on every voxel's error, in the volume's units (0: lossless): the smallest file with every "
                  "decoded voxel within it of the input")
      ->check(CLI::Validator(
        [](const std::string & text) -> std::string {
          double v = 0.0;
          return CLI::detail::lexical_cast(text, v) && v >= 0.0 && std::isfinite(v)
                   ? std::string()
                   : "--max-error must be a finite number, 0 or more (0: lossless), got " + text;
        },
        "E >= 0",
        "max-error"));
  t.bpv->excludes(t.psnr)->excludes(t.points)->excludes(t.maximumError);
  t.psnr->excludes(t.points)->excludes(t.maximumError);
  t.points->excludes(t.maximumError);
  command.add_flag("!--no-residual-layer",
                   e.residualLayer,
                   "With --bpv, points only: neither a JPEG 2000 residual layer nor a video layer is tried");
  command.add_flag("!--no-video-layer",
                   e.videoLayer,
                   "With --bpv, no video layer (HEVC or AV1) is tried: the points and JPEG 2000 only");
  command
    .add_option_function<std::string>(
      "--video-codec",
      [&e](const std::string & codec) { e.videoCodecs = ParseVideoCodecs(codec); },
      "With --bpv, the video layer's codec: both (default: each tried, the closer kept), hevc or av1 (about "
      "half the video layer's time)")
    ->check(CLI::IsMember({ "both", "hevc", "av1" }));
  command.add_option("--step",
                     e.quantizationStep,
                     "Quantization step of the values (0: with --bpv the best of 1, 2 and 4 times 1/64 of the peak, "
                     "else 1/64 of the peak, less where --psnr needs it)");
  return t;
}

std::string
FormatMaximumError(double maximumError)
{
  if (maximumError < 0.0)
    return "none (no bounded-error layer)";
  if (maximumError == 0.0)
    return "0 (lossless)";
  std::ostringstream text;
  text.precision(9);
  text << maximumError << " (every voxel within it of the input)";
  return text.str();
}

std::string
FormatPSNR(double psnr)
{
  std::ostringstream text;
  if (std::isinf(psnr) && psnr > 0.0)
    text << "inf dB (exact)";
  else
    text << psnr << " dB";
  return text.str();
}

std::string
FormatResidualLayer(const FileHeader & header)
{
  if (header.residualLayer.empty())
    return "none";
  if (header.boundedLayer)
    return std::to_string(header.residualLayer.size()) + " bytes (a bounded-error layer)";
  if (header.videoLayer)
    return std::to_string(header.residualLayer.size()) +
           (header.videoCodec == VideoCodec::AV1 ? " bytes (an AV1 stream)" : " bytes (an HEVC stream)");
  return std::to_string(StoredLayerBytes(header.residualLayer, header.size)) + " bytes (a JPEG 2000 codestream of " +
         std::to_string(header.residualLayer.size()) + ")";
}

std::string
FormatByteSplit(const FileHeader & header, std::size_t payloadBytes, std::size_t fileBytes)
{
  const std::size_t  layer = header.residualLayer.empty() ? 0
                             : header.videoLayer || header.boundedLayer
                               ? header.residualLayer.size()
                               : StoredLayerBytes(header.residualLayer, header.size);
  const std::size_t  other = fileBytes - std::min(fileBytes, payloadBytes + layer);
  const double       whole = double(std::max<std::size_t>(1, fileBytes));
  std::ostringstream text;
  text.precision(3);
  text << "points " << payloadBytes << " (" << 100.0 * double(payloadBytes) / whole << "%), layer " << layer << " ("
       << 100.0 * double(layer) / whole << "%), header and metadata " << other << " (" << 100.0 * double(other) / whole
       << "%)";
  return text.str();
}

void
DefaultPointsForVolume(EncoderOptions & options, const CLI::Option * points, uint64_t voxels)
{
  if (points != nullptr && points->count() == 0 && options.numberOfPoints > voxels)
  {
    options.numberOfPoints = std::size_t(voxels);
  }
}

double
SecondsSince(std::chrono::steady_clock::time_point start)
{
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

namespace
{
/** Exit status: 0 done, 1 the work failed (an input, a write), 2 the command line is wrong. */
constexpr int ExitFailure = 1;
constexpr int ExitUsage = 2;
} // namespace

} // namespace dcv::tools

int
main(int argc, char * argv[])
{
  using namespace dcv::tools;
  CLI::App app{ "dcv: lossy compression of 3D volumes by linear splines over adaptive Delaunay tetrahedralizations "
                "(ITK module DelaunayCompression)" };
  app.require_subcommand(1);
  // The module's version (CMake's project version) and the libraries it was built with, for bug reports.
  app.set_version_flag("--version",
                       std::string("dcv ") + dcv::ModuleVersion + "\n" + dcv::LibraryVersions() + ", " +
                         DicomLibraryVersion());
  auto & commands = Commands();
  std::sort(commands.begin(), commands.end(), [](const Command & a, const Command & b) { return a.name < b.name; });
  std::vector<std::pair<CLI::App *, std::function<void()>>> runs;
  for (const auto & c : commands)
  {
    CLI::App * command = app.add_subcommand(c.name, c.description);
    runs.emplace_back(command, c.setup(*command));
  }
  try
  {
    app.parse(argc, argv);
  }
  catch (const CLI::ParseError & e)
  {
    // Help and version exit 0, usage errors 2 (README, "Exit status").
    return app.exit(e) == 0 ? 0 : ExitUsage;
  }
  try
  {
    for (auto & [command, run] : runs)
    {
      if (command->parsed())
      {
        run();
      }
    }
  }
  catch (const UsageError & e)
  {
    std::cerr << "dcv: " << e.what() << std::endl;
    return ExitUsage;
  }
  catch (const itk::ExceptionObject & e)
  {
    std::cerr << "dcv: " << e.GetDescription() << std::endl;
    return ExitFailure;
  }
  catch (const std::exception & e)
  {
    std::cerr << "dcv: " << e.what() << std::endl;
    return ExitFailure;
  }
  return 0;
}
