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
#ifndef dcvCommand_h
#define dcvCommand_h

// The subcommands of dcv. Each lives in a file of its own that registers itself with a
// RegisterCommand object: adding a subcommand is adding a file.
#include "dcvEncoder.h"
#include "dcvTools.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <functional>
#include <iostream>
#include <string>
#include <type_traits>
#include <vector>

namespace dcv::tools
{

/** A subcommand: its name, one line of help, and `setup`, which declares its options on `command`
 * and returns what runs it once the arguments are parsed. */
struct Command
{
  std::string                                              name;
  std::string                                              description;
  std::function<std::function<void()>(CLI::App & command)> setup;
};

/** Every registered subcommand. */
std::vector<Command> &
Commands();

struct RegisterCommand
{
  explicit RegisterCommand(Command command) { Commands().push_back(std::move(command)); }
};

/** The method's options as approximate and compress take them. */
struct MethodOptions
{
  EncoderOptions       encoder;
  std::string          mode{ "best" };
  std::vector<int32_t> scale;             // --scale, when given
  std::string          series;            // --series: the Series Instance UID of a DICOM input
  bool                 resample{ false }; // --resample: a tilted or unevenly spaced DICOM series onto a grid
  DicomHeaderMode      dicomHeader{ DicomHeaderMode::Full }; // --dicom-header: what of a DICOM series' headers is kept
  bool                 force{ false };
  bool                 quiet{ false };

  /** The encoder options with the mode parsed, every value checked (Failure otherwise), and progress
   * shown as `label` on a terminal unless quiet. */
  EncoderOptions
  Checked(const std::string & label) const;
};

/** Opens INPUT (a volume file or a DICOM series), checks OUTPUT (CheckOutput), notes skipped non-DICOM
 * files, says how a series was resampled, then calls f(image, input) with the image read in its own
 * pixel type. */
template <typename TFunction>
void
WithVolume(const std::string & input, const std::string & series, const std::string & output, const MethodOptions & o,
           bool dcvFile, TFunction && f)
{
  const VolumeInput        volume = OpenVolume(input, series, o.resample, o.dicomHeader);
  std::vector<std::string> inputs = volume.dicom.files;
  inputs.push_back(input);
  CheckOutputIsNotInput(inputs, output); // before "already exists": the more useful message
  CheckOutput(output, o.force, dcvFile);
  if (volume.skipped > 0 && !o.quiet)
  {
    std::cerr << "dcv: skipped " << volume.skipped << " files of " << Quoted(input) << " that are not DICOM"
              << std::endl;
  }
  if (volume.resampling.needed && !o.quiet)
  {
    std::cout << "resampled: " << volume.resampling.description << std::endl;
  }
  VisitPixelType(volume.type, [&](auto pixel) { f(ReadVolume<decltype(pixel)>(volume), volume); });
}

/** Refuses (Failure naming `input`, the bytes the header needs and the option that makes it fit) a
 * DICOM series whose stored header (the metadata of `options`) does not fit the bit budget of a volume
 * of `voxels` at all; nothing without a budget or a header. */
void
CheckDicomHeaderFits(const std::string & input, const VolumeInput & volume, const EncoderOptions & options,
                     DicomHeaderMode mode, uint64_t voxels);

/** "DICOM header: N bytes (P% of the file)", or "" for a file without one. */
std::string
FormatDicomHeaderBytes(const FileHeader & header, std::size_t fileBytes);

/** Declares --resample (MethodOptions::resample) on a command. */
void
AddResampleOption(CLI::App & command, MethodOptions & o);

/** Refuses (Failure) a volume with NaN or infinite voxels, or values beyond the float range the encoder
 * works in, naming `input`: the quantization and the PSNR need finite values. */
template <typename TImage>
void
CheckFiniteVoxels(const TImage * image, const std::string & input)
{
  using T = typename TImage::PixelType;
  if constexpr (std::is_floating_point_v<T>)
  {
    const std::size_t n = image->GetBufferedRegion().GetNumberOfPixels();
    const T *         voxels = image->GetBufferPointer();
    std::size_t       nonFinite = 0;
    std::size_t       beyondFloat = 0;
    for (std::size_t i = 0; i < n; ++i)
    {
      if (!std::isfinite(voxels[i]))
        ++nonFinite;
      else if (!std::isfinite(static_cast<float>(voxels[i])))
        ++beyondFloat;
    }
    if (nonFinite > 0)
    {
      throw Failure(Quoted(input) + " holds " + std::to_string(nonFinite) +
                    " non-finite voxels (NaN or infinite); dcv codes finite values only");
    }
    if (beyondFloat > 0)
    {
      throw Failure(Quoted(input) + " holds " + std::to_string(beyondFloat) +
                    " voxels beyond the range of float (3.4e38), which the encoder works in");
    }
  }
}

/** A PSNR as compress and approximate print it: "inf dB (exact)" when nothing differs. */
std::string
FormatPSNR(double psnr);

/** The bound a file keeps, as compress and info print it: "0 (lossless)", "2 (every voxel within it of the
 * input)", or "none" (negative: a file without a bounded-error layer). */
std::string
FormatMaximumError(double maximumError);

/** The residual layer as compress and info print it: the bytes it takes in the file, and those of the whole
 * JPEG 2000 codestream a decoder rebuilds from them (its markers restored), or of the HEVC or AV1 stream of a video
 * layer; "none" without a layer. */
std::string
FormatResidualLayer(const FileHeader & header);

/** How a file's bytes split: "points P (p%), layer L (l%), header and metadata H (h%)"; the points are the
 * payload, the layer is its stored bytes (JPEG 2000, HEVC or AV1). */
std::string
FormatByteSplit(const FileHeader & header, std::size_t payloadBytes, std::size_t fileBytes);

/** The default --points (10000) for a volume of `voxels`: at most the voxels, so that a small volume
 * needs no option; a count given on the command line is kept, and refused if too large. */
void
DefaultPointsForVolume(EncoderOptions & options, const CLI::Option * points, uint64_t voxels);

/** Declares INPUT, the method's options (--resample included), --max-memory, --force and --quiet on a
 * command. */
void
AddMethodOptions(CLI::App & command, std::string & input, MethodOptions & o);

/** Declares --max-memory SIZE (bytes, or with a suffix K, M, G, T: powers of 1024; 0: no limit): the most
 * memory the command's `work` ("decoding", "encoding") may need (default: half of the physical memory). */
void
AddMaximumMemoryOption(CLI::App & command, uint64_t & maximumMemory, const std::string & work);

/** The encoder's target options of compress and batch (--bpv, --psnr, --points, mutually exclusive),
 * --step and --no-residual-layer; returns the three targets' options, so callers can ask which was given. */
struct TargetOptions
{
  CLI::Option * bpv;
  CLI::Option * psnr;
  CLI::Option * points;
  CLI::Option * maximumError;
};
TargetOptions
AddTargetOptions(CLI::App & command, EncoderOptions & e);

/** Seconds since `start`. */
double
SecondsSince(std::chrono::steady_clock::time_point start);

} // namespace dcv::tools

#endif
