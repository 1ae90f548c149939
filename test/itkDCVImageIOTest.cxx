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
// ImageFileReader opens .dcv files through DCVImageIO.
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "dcvPhantom.h"
#include "dcvRefinementEngine.h"
#include "dcvTestUtilities.h"
#include "itkDCVImageIO.h"
#include "itkDCVImageIOFactory.h"

#include "itkImageFileReader.h"

#include <unistd.h>

namespace
{
using namespace dcv;

TEST(DCVImageIO, ImageFileReaderDecodesAFile)
{
  itk::DCVImageIOFactory::RegisterOneFactory();
  itk::DCVImageIOFactory::RegisterOneFactory(); // harmless twice

  const GridSize           grid{ 30, 26, 22 };
  const auto               voxels = SheppLoganPhantom(grid);
  const std::vector<float> image(voxels.begin(), voxels.end());
  RefinementParameters     p = ParametersForMode(Mode::Dec);
  p.quantizationStep = 2.0;
  p.valueMin = 0.0;
  p.valueMax = 255.0;
  RefinementEngine engine(image.data(), grid, p);
  engine.Approximate(300);
  const Approximation a = engine.GetApproximation();

  FileHeader h;
  h.size = grid;
  h.spacing = { 0.5, 1.0, 2.0 };
  h.origin = { 1.0, -2.0, 3.0 };
  h.direction = { 0, -1, 0, 1, 0, 0, 0, 0, 1 };
  h.quantizationStep = 2.0;
  h.numberOfPoints = uint32_t(a.points.size());
  const std::string path =
    (std::filesystem::temp_directory_path() / ("dcv-io-" + std::to_string(::getpid()) + ".dcv")).string();
  WriteFileAtomically(path, SerializeFile(h, EncodePayload(a, 0.0, 2.0)));

  using ImageType = itk::Image<uint8_t, 3>;
  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(path);
  ASSERT_NO_THROW(reader->Update());
  EXPECT_STREQ(reader->GetImageIO()->GetNameOfClass(), "DCVImageIO");
  const ImageType * out = reader->GetOutput();
  EXPECT_EQ(out->GetLargestPossibleRegion().GetSize()[0], 30u);
  EXPECT_EQ(out->GetLargestPossibleRegion().GetSize()[2], 22u);
  EXPECT_EQ(out->GetSpacing()[2], 2.0);
  EXPECT_EQ(out->GetOrigin()[1], -2.0);
  EXPECT_EQ(out->GetDirection()(0, 1), -1.0);
  EXPECT_EQ(out->GetDirection()(1, 0), 1.0);
  std::vector<uint8_t> expected(grid.NumberOfVoxels());
  Rasterize(a, expected.data());
  EXPECT_TRUE(std::equal(expected.begin(), expected.end(), out->GetBufferPointer()));

  // A damaged file gets an exception naming it.
  auto bytes = ReadWholeFile(path);
  bytes[bytes.size() / 2] ^= 1;
  WriteFileAtomically(path, bytes);
  auto again = itk::ImageFileReader<ImageType>::New();
  again->SetFileName(path);
  try
  {
    again->Update();
    FAIL() << "a damaged .dcv file was read";
  }
  catch (const itk::ExceptionObject & e)
  {
    EXPECT_NE(std::string(e.GetDescription()).find("CRC-32"), std::string::npos) << e.GetDescription();
    EXPECT_NE(std::string(e.GetDescription()).find(path), std::string::npos) << e.GetDescription();
  }
  std::filesystem::remove(path);
}

TEST(DCVImageIO, RecognisesOnlyDcvFiles)
{
  auto io = itk::DCVImageIO::New();
  EXPECT_FALSE(io->CanReadFile("volume.nrrd"));
  EXPECT_FALSE(io->CanReadFile("/nonexistent/volume.dcv"));
  EXPECT_TRUE(io->CanWriteFile("volume.dcv"));
  EXPECT_FALSE(io->CanWriteFile("volume.nrrd"));
}

} // namespace

#include "itkDCVImageSource.h"
#include "itkImageRegionConstIteratorWithIndex.h"

namespace
{
TEST(DCVImageSource, DecodesWholeVolumesAndOnlyTheRequestedRegion)
{
  using namespace dcv;
  const GridSize           grid{ 36, 30, 28 };
  const auto               voxels = SheppLoganPhantom(grid);
  const std::vector<float> image(voxels.begin(), voxels.end());
  RefinementParameters     p = ParametersForMode(Mode::Silva);
  RefinementEngine         engine(image.data(), grid, p);
  engine.Approximate(500);
  const Approximation a = engine.GetApproximation();
  FileHeader          h;
  h.size = grid;
  h.quantizationStep = 1.0;
  h.numberOfPoints = uint32_t(a.points.size());
  const std::string path =
    (std::filesystem::temp_directory_path() / ("dcv-source-" + std::to_string(::getpid()) + ".dcv")).string();
  WriteFileAtomically(path, SerializeFile(h, EncodePayload(a, 0.0, 1.0)));

  using ImageType = itk::Image<uint8_t, 3>;
  auto source = itk::DCVImageSource<ImageType>::New();
  source->SetFileName(path);
  source->Update();
  std::vector<uint8_t> expected(grid.NumberOfVoxels());
  Rasterize(a, expected.data());
  EXPECT_TRUE(std::equal(expected.begin(), expected.end(), source->GetOutput()->GetBufferPointer()));
  const auto allCells = source->GetNumberOfRasterizedCells();
  EXPECT_EQ(allCells, a.tetrahedra.size());

  // One slab, requested from a fresh source: the same voxels, far fewer cells.
  ImageType::RegionType slab({ { 5, 7, 10 } }, { { 20, 15, 3 } });
  auto                  part = itk::DCVImageSource<ImageType>::New();
  part->SetFileName(path);
  part->UpdateOutputInformation();
  part->GetOutput()->SetRequestedRegion(slab);
  part->Update();
  EXPECT_EQ(part->GetOutput()->GetBufferedRegion(), slab);
  EXPECT_LT(part->GetNumberOfRasterizedCells(), allCells / 2);
  for (itk::ImageRegionConstIteratorWithIndex<ImageType> it(part->GetOutput(), slab); !it.IsAtEnd(); ++it)
  {
    const auto i = it.GetIndex();
    ASSERT_EQ(it.Get(), expected[grid.Offset(int32_t(i[0]), int32_t(i[1]), int32_t(i[2]))]) << i;
  }
  std::filesystem::remove(path);

  auto missing = itk::DCVImageSource<ImageType>::New();
  missing->SetFileName(path);
  EXPECT_THROW(missing->Update(), itk::ExceptionObject);
}
} // namespace

#include "itkDCVMeshIO.h"
#include "itkDCVMeshIOFactory.h"
#include "itkDelaunayApproximationImageToMeshFilter.h"
#include "itkMesh.h"
#include "itkMeshFileReader.h"
#include "itkMeshFileWriter.h"
#include "itkTetrahedralMeshToImageFilter.h"

namespace
{
TEST(DCVMeshIO, MeshRoundTripThroughMeshFileWriterAndReader)
{
  itk::DCVMeshIOFactory::RegisterOneFactory();
  using ImageType = itk::Image<uint8_t, 3>;
  using MeshType = itk::Mesh<float, 3>;
  const dcv::GridSize grid{ 26, 24, 20 };
  const auto          image = dcv::test::PhantomImage(grid, true);

  auto approximate = itk::DelaunayApproximationImageToMeshFilter<ImageType, MeshType>::New();
  approximate->SetInput(image);
  approximate->SetNumberOfPoints(250);
  approximate->SetMode(dcv::Mode::Dec);
  approximate->SetQuantizationStep(1.0);
  approximate->Update();

  const std::string path =
    (std::filesystem::temp_directory_path() / ("dcv-mesh-" + std::to_string(::getpid()) + ".dcv")).string();
  auto io = itk::DCVMeshIO::New();
  io->SetReferenceImage(image);
  EXPECT_EQ(io->GetDecodedPixelType(), dcv::PixelType::UInt8); // the reference image's
  io->SetQuantizationOrigin(approximate->GetQuantizationOrigin());
  auto writer = itk::MeshFileWriter<MeshType>::New();
  writer->SetMeshIO(io);
  writer->SetInput(approximate->GetOutput());
  writer->SetFileName(path);
  // Without the values' step the writer refuses, and writes nothing.
  try
  {
    writer->Update();
    FAIL() << "a mesh was written without its quantization step";
  }
  catch (const itk::ExceptionObject & e)
  {
    EXPECT_NE(std::string(e.GetDescription()).find("QuantizationStep"), std::string::npos) << e.GetDescription();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  io->SetQuantizationStep(approximate->GetChosenQuantizationStep());
  ASSERT_NO_THROW(writer->Update());
  EXPECT_EQ(dcv::ReadCompressedFile(path).header.pixelType, dcv::PixelType::UInt8);
  EXPECT_EQ(dcv::ReadCompressedFile(path).header.mode, dcv::FileHeader::UnknownMode);

  auto reader = itk::MeshFileReader<MeshType>::New();
  reader->SetFileName(path);
  ASSERT_NO_THROW(reader->Update());
  const MeshType * mesh = reader->GetOutput();
  EXPECT_EQ(mesh->GetNumberOfPoints(), 250u);
  EXPECT_EQ(mesh->GetNumberOfCells(), approximate->GetOutput()->GetNumberOfCells());
  EXPECT_EQ(mesh->GetCells()->Begin()->Value()->GetType(), itk::CellGeometryEnum::TETRAHEDRON_CELL);

  // Both meshes decode to the same volume.
  auto rasterize = [&image](const MeshType * m) {
    auto f = itk::TetrahedralMeshToImageFilter<MeshType, ImageType>::New();
    f->SetInput(m);
    f->SetReferenceImage(image);
    f->Update();
    return ImageType::Pointer(f->GetOutput());
  };
  const auto before = rasterize(approximate->GetOutput());
  const auto after = rasterize(mesh);
  EXPECT_TRUE(std::equal(
    before->GetBufferPointer(), before->GetBufferPointer() + grid.NumberOfVoxels(), after->GetBufferPointer()));

  // A mesh off the grid, or no grid at all, is refused with a clear error and no file.
  std::filesystem::remove(path);
  auto moved = MeshType::New();
  moved->Graft(approximate->GetOutput());
  MeshType::PointType p = moved->GetPoint(9);
  p[0] += 0.3;
  moved->SetPoint(9, p);
  writer->SetInput(moved);
  try
  {
    writer->Update();
    FAIL() << "a point off the grid was written";
  }
  catch (const itk::ExceptionObject & e)
  {
    EXPECT_NE(std::string(e.GetDescription()).find("is not on a voxel"), std::string::npos) << e.GetDescription();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  auto bare = itk::MeshFileWriter<MeshType>::New();
  bare->SetMeshIO(itk::DCVMeshIO::New());
  bare->SetInput(approximate->GetOutput());
  bare->SetFileName(path);
  EXPECT_THROW(bare->Update(), itk::ExceptionObject);
  EXPECT_FALSE(std::filesystem::exists(path));
}
} // namespace
