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
// The ITK face: DelaunayApproximationImageToMeshFilter and TetrahedralMeshToImageFilter.
#include "dcvPhantom.h"
#include "dcvRefinementEngine.h"
#include "dcvTestUtilities.h"
#include "itkDelaunayApproximationImageToMeshFilter.h"
#include "itkTetrahedralMeshToImageFilter.h"

#include "itkCommand.h"
#include "itkMesh.h"
#include "itkTriangleCell.h"

namespace
{
using ImageType = itk::Image<uint8_t, 3>;
using MeshType = itk::Mesh<float, 3>;
using ApproximationFilter = itk::DelaunayApproximationImageToMeshFilter<ImageType, MeshType>;
using RasterizeFilter = itk::TetrahedralMeshToImageFilter<MeshType, ImageType>;

/** A phantom with a rotated, anisotropic, shifted grid that starts at a non-zero index. */
ImageType::Pointer
MakePhantomImage(const dcv::GridSize & grid)
{
  return dcv::test::PhantomImage(grid, true, { { 2, -3, 4 } });
}

TEST(DelaunayApproximationImageToMeshFilter, SetGetAndPrintSelf)
{
  auto filter = ApproximationFilter::New();
  EXPECT_STREQ(filter->GetNameOfClass(), "DelaunayApproximationImageToMeshFilter");
  EXPECT_EQ(filter->GetNumberOfPoints(), 10000u);
  filter->SetNumberOfPoints(500);
  EXPECT_EQ(filter->GetNumberOfPoints(), 500u);
  filter->SetNumberOfPoints(3);
  EXPECT_EQ(filter->GetNumberOfPoints(), 8u); // clamped: the corners are always there
  EXPECT_EQ(filter->GetSquaredError(), 0.0);
  EXPECT_EQ(filter->GetMode(), dcv::Mode::Best);
  filter->SetMode(dcv::Mode::DecCom);
  EXPECT_EQ(filter->GetMode(), dcv::Mode::DecCom);
  EXPECT_EQ(filter->GetDomainSigma(), 1.0);
  EXPECT_EQ(filter->GetRangeSigma(), 0.0); // automatic
  EXPECT_EQ(filter->GetAlpha(), 0.9);
  EXPECT_EQ(filter->GetBitsPerVoxel(), 0.0); // off
  filter->SetBitsPerVoxel(0.125);
  EXPECT_EQ(filter->GetBitsPerVoxel(), 0.125);
  filter->SetAlpha(0.8);
  EXPECT_EQ(filter->GetAlpha(), 0.8);
  std::ostringstream os;
  filter->Print(os);
  EXPECT_NE(os.str().find("NumberOfPoints: 8"), std::string::npos);
  EXPECT_NE(os.str().find("MeanSquaredError: 0"), std::string::npos);
  EXPECT_NE(os.str().find("Mode: dec+com"), std::string::npos);
  EXPECT_NE(os.str().find("Alpha: 0.8"), std::string::npos);
  EXPECT_NE(os.str().find("BitsPerVoxel: 0.125"), std::string::npos);
}

TEST(DelaunayApproximationImageToMeshFilter, RefusesBadParameters)
{
  auto image = MakePhantomImage(dcv::GridSize{ 12, 12, 12 });
  for (int which = 0; which < 4; ++which)
  {
    auto approximate = ApproximationFilter::New();
    approximate->SetInput(image);
    approximate->SetNumberOfPoints(50);
    if (which == 0)
      approximate->SetAlpha(0.0);
    if (which == 1)
      approximate->SetDomainSigma(-1.0);
    if (which == 2)
      approximate->SetRangeSigma(-1.0);
    if (which == 3)
      approximate->SetBitsPerVoxel(-0.1);
    try
    {
      approximate->Update();
      FAIL() << "bad parameter " << which << " accepted";
    }
    catch (const itk::ExceptionObject & e)
    {
      EXPECT_NE(std::string(e.GetDescription()).find("must be positive"), std::string::npos) << e.GetDescription();
      EXPECT_NE(std::string(e.GetDescription())
                  .find(which == 0   ? "Alpha"
                        : which == 3 ? "BitsPerVoxel"
                                     : "Sigma"),
                std::string::npos);
    }
  }
}

TEST(DelaunayApproximationImageToMeshFilter, EveryModeRunsThroughTheFilter)
{
  auto image = MakePhantomImage(dcv::GridSize{ 24, 22, 20 });
  for (dcv::Mode mode : { dcv::Mode::Silva, dcv::Mode::Dec, dcv::Mode::DecCom, dcv::Mode::Best })
  {
    auto approximate = ApproximationFilter::New();
    approximate->SetInput(image);
    approximate->SetNumberOfPoints(300);
    approximate->SetMode(mode);
    approximate->Update();
    EXPECT_EQ(approximate->GetOutput()->GetNumberOfPoints(), 300u) << dcv::ModeName(mode);
    EXPECT_GT(approximate->GetSquaredError(), 0.0);
  }
}

TEST(TetrahedralMeshToImageFilter, SetGetAndPrintSelf)
{
  auto filter = RasterizeFilter::New();
  EXPECT_STREQ(filter->GetNameOfClass(), "TetrahedralMeshToImageFilter");
  EXPECT_EQ(filter->GetBackgroundValue(), 0);
  filter->SetBackgroundValue(7);
  EXPECT_EQ(filter->GetBackgroundValue(), 7);
  ImageType::SizeType size{ { 3, 4, 5 } };
  filter->SetSize(size);
  EXPECT_EQ(filter->GetSize(), size);
  ImageType::SpacingType spacing(2.0);
  filter->SetSpacing(spacing);
  EXPECT_EQ(filter->GetSpacing(), spacing);
  EXPECT_EQ(filter->GetReferenceImage(), nullptr);
  std::ostringstream os;
  filter->Print(os);
  EXPECT_NE(os.str().find("BackgroundValue: 7"), std::string::npos);
  EXPECT_NE(os.str().find("Size: [3, 4, 5]"), std::string::npos);
}

TEST(DelaunayApproximationImageToMeshFilter, MeshInPhysicalSpaceDecodesToTheEngineOutput)
{
  const dcv::GridSize grid{ 30, 26, 22 };
  auto                image = MakePhantomImage(grid);
  auto                approximate = ApproximationFilter::New();
  approximate->SetInput(image);
  approximate->SetNumberOfPoints(600);
  approximate->SetMode(dcv::Mode::Silva); // vertex values are then the image's, checked below
  int  progressEvents = 0;
  auto observer = itk::CStyleCommand::New();
  observer->SetClientData(&progressEvents);
  observer->SetCallback([](itk::Object *, const itk::EventObject &, void * count) { ++*static_cast<int *>(count); });
  approximate->AddObserver(itk::ProgressEvent(), observer);
  approximate->Update();
  EXPECT_GT(progressEvents, 2);

  const MeshType * mesh = approximate->GetOutput();
  ASSERT_EQ(mesh->GetNumberOfPoints(), 600u);
  ASSERT_EQ(mesh->GetPointData()->Size(), 600u);
  ASSERT_GT(mesh->GetNumberOfCells(), 600u);
  for (auto it = mesh->GetCells()->Begin(); it != mesh->GetCells()->End(); ++it)
  {
    ASSERT_EQ(it->Value()->GetType(), itk::CellGeometryEnum::TETRAHEDRON_CELL);
  }
  // Each point sits on a voxel of the input, with the input's value there.
  for (itk::IdentifierType i = 0; i < mesh->GetNumberOfPoints(); ++i)
  {
    const auto index = image->TransformPhysicalPointToIndex(mesh->GetPoint(i));
    ASSERT_TRUE(image->GetBufferedRegion().IsInside(index));
    EXPECT_EQ(mesh->GetPointData()->ElementAt(i), float(image->GetPixel(index)));
  }

  // Decoding the mesh onto the input's grid reproduces the engine's approximation exactly.
  auto rasterize = RasterizeFilter::New();
  rasterize->SetInput(mesh);
  rasterize->SetReferenceImage(image);
  rasterize->Update();
  const ImageType * decoded = rasterize->GetOutput();
  EXPECT_EQ(decoded->GetLargestPossibleRegion(), image->GetLargestPossibleRegion());
  EXPECT_EQ(decoded->GetDirection(), image->GetDirection());

  // The Delaunay space follows the spacing 0.5, 1, 2.5.
  EXPECT_EQ(approximate->GetChosenScale(), (dcv::GridScale{ { 1, 2, 5 } }));
  std::vector<float>        voxels(image->GetBufferPointer(), image->GetBufferPointer() + grid.NumberOfVoxels());
  dcv::RefinementParameters parameters;
  parameters.scale = approximate->GetChosenScale();
  dcv::RefinementEngine engine(voxels.data(), grid, parameters);
  engine.Refine(600);
  std::vector<uint8_t> expected(grid.NumberOfVoxels());
  dcv::Rasterize(engine.GetApproximation(), expected.data());
  EXPECT_TRUE(std::equal(expected.begin(), expected.end(), decoded->GetBufferPointer()));
  EXPECT_NEAR(approximate->GetSquaredError(), engine.GetSquaredError(), 1e-9 * engine.GetSquaredError());
  EXPECT_NEAR(approximate->GetMeanSquaredError(), engine.GetSquaredError() / grid.NumberOfVoxels(), 1e-6);
}

TEST(DelaunayApproximationImageToMeshFilter, RefusesAFlatImage)
{
  auto                image = ImageType::New();
  ImageType::SizeType size{ { 10, 10, 1 } };
  image->SetRegions(size);
  image->Allocate(true);
  auto approximate = ApproximationFilter::New();
  approximate->SetInput(image);
  try
  {
    approximate->Update();
    FAIL() << "a 10x10x1 image was accepted";
  }
  catch (const itk::ExceptionObject & e)
  {
    EXPECT_NE(std::string(e.GetDescription()).find("each axis needs 2"), std::string::npos) << e.GetDescription();
  }
}

TEST(DelaunayApproximationImageToMeshFilter, AbortStopsTheRefinement)
{
  auto image = MakePhantomImage(dcv::GridSize{ 24, 24, 24 });
  auto approximate = ApproximationFilter::New();
  approximate->SetInput(image);
  approximate->SetNumberOfPoints(2000);
  auto observer = itk::CStyleCommand::New();
  observer->SetClientData(approximate.GetPointer());
  observer->SetCallback([](itk::Object *, const itk::EventObject &, void * filter) {
    auto * f = static_cast<ApproximationFilter *>(filter);
    if (f->GetProgress() > 0.1f)
    {
      f->AbortGenerateDataOn();
    }
  });
  approximate->AddObserver(itk::ProgressEvent(), observer);
  EXPECT_THROW(approximate->Update(), itk::ProcessAborted);
}

/** A two-cell mesh on a 4x4x4 grid, for the rasterizer's error cases. */
MeshType::Pointer
SmallMesh()
{
  auto                              mesh = MeshType::New();
  const std::vector<dcv::GridPoint> corners = dcv::test::Corners(dcv::GridSize{ 4, 4, 4 });
  for (std::size_t i = 0; i < corners.size(); ++i)
  {
    MeshType::PointType p;
    for (int d = 0; d < 3; ++d)
      p[d] = corners[i][d];
    mesh->SetPoint(i, p);
    mesh->SetPointData(i, float(i));
  }
  for (const auto & t : dcv::Tetrahedralize(corners))
  {
    MeshType::CellAutoPointer cell;
    cell.TakeOwnership(new itk::TetrahedronCell<MeshType::CellType>);
    for (unsigned k = 0; k < 4; ++k)
      cell->SetPointId(k, t[k]);
    mesh->SetCell(mesh->GetNumberOfCells(), cell);
  }
  return mesh;
}

std::string
RasterizeError(const MeshType * mesh)
{
  auto rasterize = RasterizeFilter::New();
  rasterize->SetInput(mesh);
  ImageType::SizeType size{ { 4, 4, 4 } };
  rasterize->SetSize(size);
  try
  {
    rasterize->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    return e.GetDescription();
  }
  return "";
}

TEST(TetrahedralMeshToImageFilter, RasterizesAMeshOnItsGrid)
{
  auto mesh = SmallMesh();
  EXPECT_EQ(RasterizeError(mesh), "");
}

TEST(TetrahedralMeshToImageFilter, RefusesPointsOffTheGrid)
{
  auto                mesh = SmallMesh();
  MeshType::PointType p;
  p[0] = 1.5;
  p[1] = 0;
  p[2] = 0;
  mesh->SetPoint(3, p);
  EXPECT_NE(RasterizeError(mesh).find("is not on a voxel"), std::string::npos);
  p[0] = 9;
  mesh->SetPoint(3, p);
  EXPECT_NE(RasterizeError(mesh).find("is not on a voxel"), std::string::npos);
}

TEST(TetrahedralMeshToImageFilter, RefusesCellsThatAreNotTetrahedra)
{
  auto                      mesh = SmallMesh();
  MeshType::CellAutoPointer triangle;
  triangle.TakeOwnership(new itk::TriangleCell<MeshType::CellType>);
  triangle->SetPointId(0, 0);
  triangle->SetPointId(1, 1);
  triangle->SetPointId(2, 2);
  mesh->SetCell(mesh->GetNumberOfCells(), triangle);
  EXPECT_NE(RasterizeError(mesh).find("is not a tetrahedron"), std::string::npos);
}

TEST(TetrahedralMeshToImageFilter, RefusesPointsWithoutValues)
{
  auto mesh = SmallMesh();
  mesh->SetPointData(MeshType::PointDataContainer::New());
  EXPECT_NE(RasterizeError(mesh).find("point data"), std::string::npos);
}

} // namespace
