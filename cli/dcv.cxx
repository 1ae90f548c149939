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
#include "dcvPhantom.h"
#include "dcvVolumeHeader.h"
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
CheckOutput(const std::string & output, bool force)
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
  if (!itk::ImageIOFactory::CreateImageIO(output.c_str(), itk::IOFileModeEnum::WriteMode))
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

/** Peak of the PSNR: 255 for 8-bit data, else the range of the original volume. */
template <typename TPixel>
double
Peak(const TPixel * data, std::size_t n)
{
  if (sizeof(TPixel) == 1 && std::is_integral<TPixel>::value)
  {
    return 255.0;
  }
  const auto range = std::minmax_element(data, data + n);
  return std::max(1e-12, double(*range.second) - double(*range.first));
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
  bool        force{ false };
  bool        quiet{ false };
};

template <typename TPixel>
void
Approximate(const ApproximateOptions & o)
{
  using ImageType = itk::Image<TPixel, Dimension>;
  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(o.input);
  try
  {
    reader->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read " + Quoted(o.input) + ": " + e.GetDescription());
  }
  const ImageType * image = reader->GetOutput();

  const auto start = std::chrono::steady_clock::now();
  auto       approximate = itk::DelaunayApproximationImageToMeshFilter<ImageType, MeshType>::New();
  approximate->SetInput(image);
  approximate->SetNumberOfPoints(o.points);
  approximate->SetMode(dcv::ParseMode(o.mode));
  approximate->SetDomainSigma(o.domainSigma);
  approximate->SetRangeSigma(o.rangeSigma);
  approximate->SetAlpha(o.alpha);
  Observe(approximate, "approximating", o.quiet);
  auto rasterize = itk::TetrahedralMeshToImageFilter<MeshType, ImageType>::New();
  rasterize->SetInput(approximate->GetOutput());
  rasterize->SetReferenceImage(image);
  rasterize->Update();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const ImageType * result = rasterize->GetOutput();
  const auto        n = image->GetBufferedRegion().GetNumberOfPixels();
  const double      error = dcv::SquaredError(image->GetBufferPointer(), result->GetBufferPointer(), n);
  const double      psnr = dcv::PSNR(error, n, Peak(image->GetBufferPointer(), n));
  WriteImage(result, o.output);
  if (!o.quiet)
  {
    std::cout << "mode: " << o.mode << "\n"
              << "points: " << approximate->GetOutput()->GetNumberOfPoints() << "\n"
              << "PSNR: " << psnr << " dB\n"
              << "seconds: " << seconds << "\n";
  }
}

void
RunApproximate(const ApproximateOptions & o)
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
  CheckOutput(o.output, o.force);
  using C = itk::IOComponentEnum;
  switch (io->GetComponentType())
  {
    case C::UCHAR:
      return Approximate<uint8_t>(o);
    case C::CHAR:
      return Approximate<int8_t>(o);
    case C::USHORT:
      return Approximate<uint16_t>(o);
    case C::SHORT:
      return Approximate<int16_t>(o);
    case C::UINT:
      return Approximate<uint32_t>(o);
    case C::INT:
      return Approximate<int32_t>(o);
    case C::FLOAT:
      return Approximate<float>(o);
    case C::DOUBLE:
      return Approximate<double>(o);
    default:
      throw Failure(Quoted(o.input) + " has " + itk::ImageIOBase::GetComponentTypeAsString(io->GetComponentType()) +
                    " voxels; dcv handles 8, 16 and 32-bit integers, float and double");
  }
}

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
  app.set_version_flag("--version", "dcv 0.1.0");

  ApproximateOptions approximateOptions;
  auto * approximate = app.add_subcommand(
    "approximate", "Approximate a volume by a linear spline over an adaptive Delaunay tetrahedralization and write "
                   "the approximation with the input's geometry and pixel type; prints points, PSNR and seconds");
  approximate->add_option("INPUT", approximateOptions.input, "Input volume (NRRD, NIfTI, MetaImage, ...)")->required();
  approximate->add_option("OUTPUT", approximateOptions.output, "Output volume (format from its extension)")->required();
  approximate->add_option("--points,-n", approximateOptions.points, "Number of significant points (at least 8)")
    ->capture_default_str();
  approximate
    ->add_option("--mode,-m",
                 approximateOptions.mode,
                 "silva (refinement), dec (+ decimation), dec+com (+ combined image approach: the paper's "
                 "method), best (+ least-squares values)")
    ->capture_default_str();
  approximate
    ->add_option("--domain-sigma", approximateOptions.domainSigma, "Bilateral filter of I*: spatial sigma, voxels")
    ->capture_default_str();
  approximate
    ->add_option("--range-sigma", approximateOptions.rangeSigma, "Bilateral filter of I*: intensity sigma (0: 8% of the intensity range)")
    ->capture_default_str();
  approximate
    ->add_option("--alpha", approximateOptions.alpha, "Choose positions on I* until PSNR >= alpha * PSNR(I*)")
    ->capture_default_str();
  approximate->add_flag("--force,-f", approximateOptions.force, "Overwrite OUTPUT if it exists");
  approximate->add_flag("--quiet,-q", approximateOptions.quiet, "Print nothing but errors");

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
      RunApproximate(approximateOptions);
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
