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
// dcv: the command-line face of the DelaunayCompression module.
#include "dcvApproximation.h"
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "dcvPhantom.h"
#include "dcvVolumeHeader.h"
#include "itkDCVGridPoint.h"
#include "itkDCVImageIOFactory.h"
#include "itkDelaunayApproximationImageToMeshFilter.h"
#include "itkTetrahedralMeshToImageFilter.h"

#include "itkCommand.h"
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"
#include "itkImageIOFactory.h"
#include "itkImportImageFilter.h"
#include "itkMesh.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <unistd.h>

namespace fs = std::filesystem;

namespace
{
constexpr unsigned int Dimension = 3;
using MeshType = itk::Mesh<double, Dimension>;

using dcv::Failure; // printed as "dcv: message" with exit status 1
using dcv::Quoted;

/** Refuses to clobber an existing file unless forced, and checks that ITK can write the format. */
void
CheckOutput(const std::string & output, bool force, bool compressed = false)
{
  if (fs::exists(output) && !force)
  {
    throw Failure(Quoted(output) + " already exists; use --force to overwrite it");
  }
  if (fs::is_directory(output))
  {
    throw Failure(Quoted(output) + " is a directory");
  }
  const fs::path parent = fs::absolute(output).parent_path();
  if (!fs::is_directory(parent))
  {
    throw Failure("cannot write " + Quoted(output) + ": directory " + Quoted(parent.string()) + " does not exist");
  }
  if (compressed)
  {
    if (fs::path(output).extension() != ".dcv")
    {
      throw Failure("cannot write " + Quoted(output) + ": a compressed volume's file name ends in .dcv");
    }
  }
  else if (!itk::ImageIOFactory::CreateImageIO(output.c_str(), itk::IOFileModeEnum::WriteMode))
  {
    throw Failure("cannot write " + Quoted(output) + ": no image format is known for that file name "
                  "(use .nrrd, .nii.gz, .mha, ...)");
  }
}

/** Writes through a temporary file in the same directory, renamed at the end, for the formats
 * that are one file; so a failure never leaves a half-written output. */
template <typename TImage>
void
WriteImage(const TImage * image, const std::string & output)
{
  const fs::path    target(output);
  const std::string name = target.filename().string();
  std::string       extension = target.extension().string();
  if (extension == ".gz")
  {
    extension = target.stem().extension().string() + extension;
  }
  const bool singleFile = extension == ".nrrd" || extension == ".nii" || extension == ".nii.gz" || extension == ".mha";
  const fs::path temporary =
    singleFile ? target.parent_path() / (".dcv-" + std::to_string(::getpid()) + "-" + name) : target;
  auto writer = itk::ImageFileWriter<TImage>::New();
  writer->SetInput(image);
  writer->SetFileName(temporary.string());
  writer->UseCompressionOn();
  try
  {
    writer->Update();
    if (singleFile)
    {
      fs::rename(temporary, target);
    }
  }
  catch (...)
  {
    std::error_code ignored;
    if (singleFile)
    {
      fs::remove(temporary, ignored);
    }
    throw;
  }
}

/** Shows a filter's progress on stderr when it is a terminal. */
class ProgressBar : public itk::Command
{
public:
  using Self = ProgressBar;
  using Pointer = itk::SmartPointer<Self>;
  itkNewMacro(Self);
  void
  Execute(itk::Object * caller, const itk::EventObject & event) override
  {
    Execute(static_cast<const itk::Object *>(caller), event);
  }
  void
  Execute(const itk::Object * caller, const itk::EventObject & event) override
  {
    const auto * process = dynamic_cast<const itk::ProcessObject *>(caller);
    if (process && itk::ProgressEvent().CheckEvent(&event))
    {
      const int percent = int(process->GetProgress() * 100.0f);
      if (percent != m_Last)
      {
        m_Last = percent;
        std::fprintf(stderr, "\r%s %3d%%", m_Label.c_str(), percent);
        if (percent >= 100)
        {
          std::fprintf(stderr, "\r%*s\r", int(m_Label.size()) + 6, "");
        }
        std::fflush(stderr);
      }
    }
  }
  std::string m_Label;

private:
  int m_Last{ -1 };
};

void
Observe(itk::ProcessObject * process, const std::string & label, bool quiet)
{
  if (!quiet && ::isatty(2))
  {
    auto bar = ProgressBar::New();
    bar->m_Label = label;
    process->AddObserver(itk::ProgressEvent(), bar);
  }
}

struct ApproximateOptions
{
  std::string input;
  std::string output;
  std::size_t points{ 10000 };
  std::string mode{ "best" };
  double      domainSigma{ 1.0 };
  double      rangeSigma{ 0.0 };
  double      alpha{ 0.9 };
  double      bpv{ 0.0 };  // compress: bits per voxel of the whole file (0: use --points)
  double      step{ 0.0 }; // compress: quantization step of the values (0: automatic)
  bool        compressed{ false }; // OUTPUT is a .dcv file
  bool        force{ false };
  bool        quiet{ false };
};

/** The approximation filter set up from the options (shared by approximate and compress). */
template <typename TImage>
typename itk::DelaunayApproximationImageToMeshFilter<TImage, MeshType>::Pointer
MakeApproximationFilter(const TImage * image, const ApproximateOptions & o)
{
  auto approximate = itk::DelaunayApproximationImageToMeshFilter<TImage, MeshType>::New();
  approximate->SetInput(image);
  approximate->SetNumberOfPoints(o.points);
  approximate->SetMode(dcv::ParseMode(o.mode));
  approximate->SetDomainSigma(o.domainSigma);
  approximate->SetRangeSigma(o.rangeSigma);
  approximate->SetAlpha(o.alpha);
  Observe(approximate, "approximating", o.quiet);
  return approximate;
}

template <typename TImage>
typename TImage::Pointer
ReadTypedImage(const std::string & path)
{
  auto reader = itk::ImageFileReader<TImage>::New();
  reader->SetFileName(path);
  try
  {
    reader->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read " + Quoted(path) + ": " + e.GetDescription());
  }
  return reader->GetOutput();
}

template <typename TPixel>
void
Approximate(const ApproximateOptions & o)
{
  using ImageType = itk::Image<TPixel, Dimension>;
  const auto image = ReadTypedImage<ImageType>(o.input);

  const auto start = std::chrono::steady_clock::now();
  auto       approximate = MakeApproximationFilter<ImageType>(image, o);
  auto rasterize = itk::TetrahedralMeshToImageFilter<MeshType, ImageType>::New();
  rasterize->SetInput(approximate->GetOutput());
  rasterize->SetReferenceImage(image);
  rasterize->Update();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const ImageType * result = rasterize->GetOutput();
  const auto        n = image->GetBufferedRegion().GetNumberOfPixels();

  const double      error = dcv::SquaredError(image->GetBufferPointer(), result->GetBufferPointer(), n);
  const double      psnr = dcv::PSNR(error, n, dcv::PSNRPeak(image->GetBufferPointer(), n));
  WriteImage(result, o.output);
  if (!o.quiet)
  {
    std::cout << "mode: " << o.mode << "\n"
              << "points: " << approximate->GetOutput()->GetNumberOfPoints() << "\n"
              << "PSNR: " << psnr << " dB\n"
              << "seconds: " << seconds << "\n";
  }
}

template <typename T>
constexpr dcv::PixelType
PixelTypeOf()
{
  using dcv::PixelType;
  if constexpr (std::is_same<T, uint8_t>::value)
    return PixelType::UInt8;
  else if constexpr (std::is_same<T, int8_t>::value)
    return PixelType::Int8;
  else if constexpr (std::is_same<T, uint16_t>::value)
    return PixelType::UInt16;
  else if constexpr (std::is_same<T, int16_t>::value)
    return PixelType::Int16;
  else if constexpr (std::is_same<T, uint32_t>::value)
    return PixelType::UInt32;
  else if constexpr (std::is_same<T, int32_t>::value)
    return PixelType::Int32;
  else if constexpr (std::is_same<T, float>::value)
    return PixelType::Float32;
  else
    return PixelType::Float64;
}

/** Decodes a .dcv file's bytes into an image of its pixel type, in its physical space. */
template <typename TPixel>
typename itk::Image<TPixel, Dimension>::Pointer
DecodeImage(const dcv::FileHeader & header, const std::vector<uint8_t> & payload, const std::string & name)
{
  using ImageType = itk::Image<TPixel, Dimension>;
  const dcv::Approximation a = dcv::DecodePayload(
    payload, header.size, header.numberOfPoints, header.quantizationOrigin, header.quantizationStep, name);
  auto                     image = ImageType::New();
  typename ImageType::SizeType size;
  size[0] = itk::SizeValueType(header.size.x);
  size[1] = itk::SizeValueType(header.size.y);
  size[2] = itk::SizeValueType(header.size.z);
  image->SetRegions(size);
  typename ImageType::SpacingType   spacing;
  typename ImageType::PointType     origin;
  typename ImageType::DirectionType direction;
  for (unsigned int i = 0; i < 3; ++i)
  {
    spacing[i] = header.spacing[i];
    origin[i] = header.origin[i];
    for (unsigned int j = 0; j < 3; ++j)
      direction(i, j) = header.direction[3 * i + j];
  }
  image->SetSpacing(spacing);
  image->SetOrigin(origin);
  image->SetDirection(direction);
  image->Allocate();
  dcv::Rasterize(a, image->GetBufferPointer());
  return image;
}

template <typename TPixel>
void
Compress(const ApproximateOptions & o)
{
  using ImageType = itk::Image<TPixel, Dimension>;
  const auto   image = ReadTypedImage<ImageType>(o.input);
  const auto   start = std::chrono::steady_clock::now();
  const auto   region = image->GetBufferedRegion();
  const auto   n = region.GetNumberOfPixels();
  const double peak = dcv::PSNRPeak(image->GetBufferPointer(), n);
  // --step 0: with --bpv rate control chooses the step, with --points it is the default (1/64 of the peak).
  const double givenStep =
    o.step > 0.0 || o.bpv > 0.0 ? o.step : dcv::DefaultQuantizationStep(peak, std::is_integral<TPixel>::value);

  dcv::FileHeader header;
  header.pixelType = PixelTypeOf<TPixel>();
  header.mode = uint8_t(dcv::ParseMode(o.mode));
  header.size = dcv::GridSize{ int32_t(region.GetSize()[0]), int32_t(region.GetSize()[1]), int32_t(region.GetSize()[2]) };
  for (unsigned int i = 0; i < 3; ++i)
  {
    header.spacing[i] = image->GetSpacing()[i];
    for (unsigned int j = 0; j < 3; ++j)
      header.direction[3 * i + j] = image->GetDirection()(i, j);
  }
  itk::Point<double, 3> first;
  image->TransformIndexToPhysicalPoint(region.GetIndex(), first);
  for (unsigned int i = 0; i < 3; ++i)
    header.origin[i] = first[i];

  auto approximate = MakeApproximationFilter<ImageType>(image, o);
  approximate->SetQuantizationStep(givenStep);
  // Rate control (--bpv) is the filter's: the method runs once, then adjusts its point count.
  approximate->SetBitsPerVoxel(o.bpv);
  try
  {
    approximate->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot compress " + Quoted(o.input) + ": " + e.GetDescription());
  }
  const MeshType *   mesh = approximate->GetOutput();
  dcv::Approximation a;
  a.grid = header.size;
  for (itk::IdentifierType i = 0; i < mesh->GetNumberOfPoints(); ++i)
  {
    dcv::GridPoint g;
    if (!itk::PhysicalPointToGridPoint(image.GetPointer(), region, mesh->GetPoint(i), g))
    {
      throw Failure("internal error: an approximation point of " + Quoted(o.input) + " is off the voxel grid");
    }
    a.points.push_back(g);
    a.values.push_back(mesh->GetPointData()->ElementAt(i));
  }
  header.quantizationOrigin = approximate->GetQuantizationOrigin();
  const double step = approximate->GetChosenQuantizationStep();
  header.quantizationStep = step;
  header.numberOfPoints = uint32_t(a.points.size());
  const std::vector<uint8_t> bytes = dcv::SerializeFile(header, dcv::EncodePayload(a, header.quantizationOrigin, step));
  if (o.bpv > 0.0 && double(bytes.size()) > std::floor(o.bpv * double(n) / 8.0))
  {
    throw Failure("internal error: " + std::to_string(bytes.size()) + " bytes exceed the --bpv budget");
  }
  dcv::WriteFileAtomically(o.output, bytes);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // The PSNR of what decompress will write: decode the very bytes written.
  dcv::FileHeader      parsed;
  std::vector<uint8_t> payload;
  dcv::ParseFile(bytes, o.output, parsed, payload);
  const auto   decoded = DecodeImage<TPixel>(parsed, payload, o.output);
  const double psnr = dcv::PSNR(dcv::SquaredError(image->GetBufferPointer(), decoded->GetBufferPointer(), n), n, peak);
  if (!o.quiet)
  {
    std::cout << "mode: " << o.mode << "\n"
              << "bytes: " << bytes.size() << "\n"
              << "bpv: " << double(bytes.size()) * 8.0 / double(n) << "\n"
              << "points: " << parsed.numberOfPoints << "\n"
              << "step: " << step << "\n"
              << "PSNR: " << psnr << " dB\n"
              << "seconds: " << seconds << "\n";
  }
}

void
RunDecompress(const std::string & input, const std::string & output, bool force, bool quiet)
{
  const auto           bytes = dcv::ReadWholeFile(input);
  dcv::FileHeader      header;
  std::vector<uint8_t> payload;
  dcv::ParseFile(bytes, Quoted(input), header, payload);
  CheckOutput(output, force);
  const auto start = std::chrono::steady_clock::now();
  dcv::VisitPixelType(header.pixelType, [&](auto pixel) {
    WriteImage(DecodeImage<decltype(pixel)>(header, payload, Quoted(input)).GetPointer(), output);
  });
  if (!quiet)
  {
    std::cout << "seconds: " << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
              << "\n";
  }
}

void
RunInfo(const std::string & input)
{
  const auto           bytes = dcv::ReadWholeFile(input);
  dcv::FileHeader      h;
  std::vector<uint8_t> payload;
  dcv::ParseFile(bytes, Quoted(input), h, payload);
  const double voxels = double(h.size.NumberOfVoxels());
  std::cout << "file: " << input << "\n"
            << "version: " << int(dcv::FileHeader::Version) << "\n"
            << "bytes: " << bytes.size() << " (payload " << payload.size() << ")\n"
            << "bpv: " << double(bytes.size()) * 8.0 / voxels << "\n"
            << "size: " << h.size.x << " " << h.size.y << " " << h.size.z << "\n"
            << "pixel type: " << dcv::PixelTypeName(h.pixelType) << "\n"
            << "spacing: " << h.spacing[0] << " " << h.spacing[1] << " " << h.spacing[2] << "\n"
            << "origin: " << h.origin[0] << " " << h.origin[1] << " " << h.origin[2] << "\n"
            << "direction:";
  for (double d : h.direction)
    std::cout << " " << d;
  std::cout << "\n"
            << "mode: " << (h.mode <= 3 ? dcv::ModeName(dcv::Mode(h.mode)) : "unknown") << "\n"
            << "points: " << h.numberOfPoints << "\n"
            << "quantization: " << h.quantizationOrigin << " + k * " << h.quantizationStep << "\n";
  for (const auto & kv : h.metadata)
    std::cout << "metadata: " << kv.first << " = " << kv.second << "\n";
}

/** Checks the options shared by approximate and compress, then runs `Action<T>` for the input's
 * pixel type. */
template <template <typename> class Action>
void
Dispatch(const ApproximateOptions & o)
{
  auto io = dcv::ReadVolumeHeader(o.input);
  if (o.points < 8)
  {
    throw Failure("--points must be at least 8 (the corners of the volume), got " + std::to_string(o.points));
  }
  try
  {
    dcv::ParseMode(o.mode);
  }
  catch (const std::invalid_argument & e)
  {
    throw Failure(std::string("--mode: ") + e.what());
  }
  if (!(o.domainSigma > 0.0))
  {
    throw Failure("--domain-sigma must be positive, got " + std::to_string(o.domainSigma));
  }
  if (!(o.rangeSigma >= 0.0))
  {
    throw Failure("--range-sigma must be positive, or 0 for automatic, got " + std::to_string(o.rangeSigma));
  }
  if (!(o.alpha > 0.0))
  {
    throw Failure("--alpha must be positive, got " + std::to_string(o.alpha));
  }
  if (!(o.bpv >= 0.0) || !(o.step >= 0.0))
  {
    throw Failure("--bpv and --step must be positive (or 0: not set)");
  }
  CheckOutput(o.output, o.force, o.compressed);
  using C = itk::IOComponentEnum;
  switch (io->GetComponentType())
  {
    case C::UCHAR:
      return Action<uint8_t>::Run(o);
    case C::CHAR:
      return Action<int8_t>::Run(o);
    case C::USHORT:
      return Action<uint16_t>::Run(o);
    case C::SHORT:
      return Action<int16_t>::Run(o);
    case C::UINT:
      return Action<uint32_t>::Run(o);
    case C::INT:
      return Action<int32_t>::Run(o);
    case C::FLOAT:
      return Action<float>::Run(o);
    case C::DOUBLE:
      return Action<double>::Run(o);
    default:
      throw Failure(Quoted(o.input) + " has " + itk::ImageIOBase::GetComponentTypeAsString(io->GetComponentType()) +
                    " voxels; dcv handles 8, 16 and 32-bit integers, float and double");
  }
}

template <typename T>
struct ApproximateAction
{
  static void
  Run(const ApproximateOptions & o)
  {
    Approximate<T>(o);
  }
};
template <typename T>
struct CompressAction
{
  static void
  Run(const ApproximateOptions & o)
  {
    Compress<T>(o);
  }
};

void
RunPhantom(const std::string & output, int size, bool force)
{
  if (size < 2 || size > 1024)
  {
    throw Failure("--size must be 2 to 1024, got " + std::to_string(size));
  }
  CheckOutput(output, force);
  using ImageType = itk::Image<uint8_t, Dimension>;
  const dcv::GridSize grid{ size, size, size };
  std::vector<uint8_t> voxels = dcv::SheppLoganPhantom(grid);
  auto                 image = ImageType::New();
  ImageType::SizeType  extent;
  extent.Fill(itk::SizeValueType(size));
  image->SetRegions(extent);
  image->Allocate();
  std::copy(voxels.begin(), voxels.end(), image->GetBufferPointer());
  WriteImage(image.GetPointer(), output);
}
} // namespace

int
main(int argc, char * argv[])
{
  CLI::App app{ "dcv: lossy compression of 3D volumes by linear splines over adaptive Delaunay tetrahedralizations "
                "(ITK module DelaunayCompression)" };
  app.require_subcommand(1);
  itk::DCVImageIOFactory::RegisterOneFactory(); // .dcv files are volumes like any other for dcv
  app.set_version_flag("--version", "dcv 0.1.0");

  // The method's options, shared by approximate and compress.
  auto addMethodOptions = [](CLI::App * command, ApproximateOptions & o) {
    command->add_option("INPUT", o.input, "Input volume (NRRD, NIfTI, MetaImage, ...)")->required();
    command->add_option("--points,-n", o.points, "Number of significant points (at least 8)")->capture_default_str();
    command
      ->add_option("--mode,-m",
                   o.mode,
                   "silva (refinement), dec (+ decimation), dec+com (+ combined image approach: the paper's "
                   "method), best (+ least-squares values)")
      ->capture_default_str();
    command->add_option("--domain-sigma", o.domainSigma, "Bilateral filter of I*: spatial sigma, voxels")
      ->capture_default_str();
    command
      ->add_option("--range-sigma", o.rangeSigma, "Bilateral filter of I*: intensity sigma (0: 8% of the intensity range)")
      ->capture_default_str();
    command->add_option("--alpha", o.alpha, "Choose positions on I* until PSNR >= alpha * PSNR(I*)")
      ->capture_default_str();
    command->add_flag("--force,-f", o.force, "Overwrite OUTPUT if it exists");
    command->add_flag("--quiet,-q", o.quiet, "Print nothing but errors");
  };

  ApproximateOptions approximateOptions;
  auto * approximate = app.add_subcommand(
    "approximate", "Approximate a volume by a linear spline over an adaptive Delaunay tetrahedralization and write "
                   "the approximation with the input's geometry and pixel type; prints points, PSNR and seconds");
  addMethodOptions(approximate, approximateOptions);
  approximate->add_option("OUTPUT", approximateOptions.output, "Output volume (format from its extension)")->required();

  ApproximateOptions compressOptions;
  compressOptions.compressed = true;
  auto *             compress = app.add_subcommand(
    "compress", "Compress a volume into a .dcv file; prints bytes, bpv, points, PSNR (of what decompress gives) and seconds");
  addMethodOptions(compress, compressOptions);
  compress->add_option("OUTPUT", compressOptions.output, "Output .dcv file")->required();
  compress->add_option("--bpv", compressOptions.bpv, "Bits per voxel of the whole file (then --points is chosen)");
  compress->add_option("--step",
                       compressOptions.step,
                       "Quantization step of the values (0: with --bpv the best of 1, 2 and 4 times 1/64 of the peak, "
                       "with --points 1/64 of the peak)");

  std::string decompressInput, decompressOutput;
  bool        decompressForce = false, decompressQuiet = false;
  auto *      decompress = app.add_subcommand("decompress", "Decode a .dcv file into any image format ITK writes");
  decompress->add_option("INPUT", decompressInput, "Input .dcv file")->required();
  decompress->add_option("OUTPUT", decompressOutput, "Output volume (format from its extension)")->required();
  decompress->add_flag("--force,-f", decompressForce, "Overwrite OUTPUT if it exists");
  decompress->add_flag("--quiet,-q", decompressQuiet, "Print nothing but errors");

  std::string infoInput;
  auto *      info = app.add_subcommand("info", "Print the header of a .dcv file");
  info->add_option("FILE", infoInput, "A .dcv file")->required();

  std::string phantomOutput;
  int         phantomSize = 128;
  bool        phantomForce = false;
  auto *      phantom = app.add_subcommand("phantom", "Write a 3D Shepp-Logan head phantom (uint8)");
  phantom->add_option("OUTPUT", phantomOutput, "Output volume (format from its extension)")->required();
  phantom->add_option("--size,-s", phantomSize, "Voxels along each axis")->capture_default_str();
  phantom->add_flag("--force,-f", phantomForce, "Overwrite OUTPUT if it exists");

  try
  {
    app.parse(argc, argv);
  }
  catch (const CLI::ParseError & e)
  {
    return app.exit(e);
  }

  try
  {
    if (*approximate)
    {
      Dispatch<ApproximateAction>(approximateOptions);
    }
    else if (*compress)
    {
      Dispatch<CompressAction>(compressOptions);
    }
    else if (*decompress)
    {
      RunDecompress(decompressInput, decompressOutput, decompressForce, decompressQuiet);
    }
    else if (*info)
    {
      RunInfo(infoInput);
    }
    else if (*phantom)
    {
      RunPhantom(phantomOutput, phantomSize, phantomForce);
    }
  }
  catch (const Failure & e)
  {
    std::cerr << "dcv: " << e.what() << std::endl;
    return 1;
  }
  catch (const itk::ExceptionObject & e)
  {
    std::cerr << "dcv: " << e.GetDescription() << std::endl;
    return 1;
  }
  catch (const std::exception & e)
  {
    std::cerr << "dcv: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
