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
// dcv mesh: the spline of a .dcv file as a VTK mesh. VTK's own readers (python3-vtk9) read what it
// writes, and the mesh probed at the voxel centres gives the voxels `dcv decompress` writes.
#include "dcvCodec.h"
#include "dcvTestUtilities.h"
#include "dcvVtkWriter.h"

#include "itkImageFileWriter.h"

#include <zlib.h>

#include <cmath>
#include <cstring>
#include <map>
#include <sstream>

namespace
{
namespace fs = std::filesystem;

using dcv::test::Result;
using dcv::test::RunCommand;
using dcv::test::RunDcv;
using dcv::test::TemporaryDirectory;

/** The `key: value` lines of a program's output. */
std::map<std::string, std::string>
Figures(const std::string & output)
{
  std::map<std::string, std::string> figures;
  std::istringstream                 lines(output);
  for (std::string line; std::getline(lines, line);)
  {
    const auto colon = line.find(": ");
    if (colon != std::string::npos)
    {
      figures[line.substr(0, colon)] = line.substr(colon + 2);
    }
  }
  return figures;
}

/** Why python3 with VTK cannot run here, or "" when it can. */
std::string
VtkPythonMissing()
{
  if (!fs::exists(DCV_VTK_PYTHON))
  {
    return std::string(DCV_VTK_PYTHON) + " is absent";
  }
  const Result r =
    RunCommand(std::string(DCV_VTK_PYTHON) + " -c 'import numpy, vtkmodules.vtkIOXML, vtkmodules.vtkIOLegacy, "
                                             "vtkmodules.vtkFiltersCore' 2>&1");
  return r.status == 0 ? "" : std::string(DCV_VTK_PYTHON) + " cannot import VTK and numpy (python3-vtk9): " + r.output;
}

#define DCV_REQUIRE_VTK_PYTHON()                                                                                       \
  if (const std::string missing = VtkPythonMissing(); !missing.empty())                                                \
  {                                                                                                                    \
    GTEST_SKIP() << "needs python3 with VTK to read the meshes: " << missing;                                          \
  }

/** A small oblique, anisotropic phantom (direction, spacing and origin all count) compressed to points
 * only, so that the decoded voxels are the spline's. */
std::string
CompressedPhantom(const TemporaryDirectory & directory, int32_t points)
{
  using ImageType = itk::Image<uint8_t, 3>;
  auto writer = itk::ImageFileWriter<ImageType>::New();
  writer->SetInput(dcv::test::PhantomImage({ 28, 24, 16 }, true));
  writer->SetFileName(directory / "phantom.nrrd");
  writer->Update();
  const std::string file = directory / "phantom.dcv";
  const Result      r =
    RunDcv("compress " + directory / "phantom.nrrd" + " " + file + " --points " + std::to_string(points) + " -q");
  EXPECT_EQ(r.status, 0) << r.output;
  return file;
}

TEST(MeshExport, VtkReadsTheSplineTheDecoderRasterizes)
{
  DCV_REQUIRE_VTK_PYTHON();
  TemporaryDirectory directory;
  const std::string  dcvFile = CompressedPhantom(directory, 500);
  const auto         info = Figures(RunDcv("info " + dcvFile).output);
  ASSERT_EQ(info.at("points"), "500");
  ASSERT_EQ(info.at("residual layer"), "none");

  // What the library decodes: the reference counts, and the geometry the mesh must be in.
  const dcv::CompressedFile file = dcv::ReadCompressedFile(dcvFile);
  const dcv::Approximation  a = dcv::DecodeMesh(file);
  ASSERT_EQ(a.points.size(), 500u);
  const dcv::FileHeader & h = file.header;

  const std::string decoded = directory / "decoded.nrrd";
  ASSERT_EQ(RunDcv("decompress " + dcvFile + " " + decoded + " -q").status, 0);
  auto reader = itk::ImageFileReader<itk::Image<uint8_t, 3>>::New();
  reader->SetFileName(decoded);
  reader->Update();
  const uint8_t * voxels = reader->GetOutput()->GetBufferPointer();
  const uint64_t  n = h.size.NumberOfVoxels();

  std::ostringstream geometry;
  geometry.precision(17);
  geometry << h.size.x << " " << h.size.y << " " << h.size.z;
  for (double v : h.origin)
    geometry << " " << v;
  for (double v : h.spacing)
    geometry << " " << v;
  for (double v : h.direction)
    geometry << " " << v;

  for (const char * extension : { ".vtu", ".vtk" })
  {
    SCOPED_TRACE(extension);
    const std::string mesh = directory / ("mesh" + std::string(extension));
    const Result      written = RunDcv("mesh " + dcvFile + " " + mesh);
    ASSERT_EQ(written.status, 0) << written.output;
    const auto printed = Figures(written.output);
    EXPECT_EQ(printed.at("points"), "500");
    EXPECT_EQ(printed.at("tetrahedra"), std::to_string(a.tetrahedra.size()));
    EXPECT_EQ(printed.at("bytes"), std::to_string(fs::file_size(mesh)));
    EXPECT_NE(printed.find("seconds"), printed.end());

    const std::string probed = directory / "probed.raw";
    const Result r = RunCommand(std::string(DCV_VTK_PYTHON) + " " + DCV_MESH_PROBE + " " + mesh + " " + probed + " " +
                                geometry.str() + " 2>&1");
    ASSERT_EQ(r.status, 0) << r.output;
    const auto vtk = Figures(r.output);
    EXPECT_EQ(vtk.at("points"), "500") << r.output;
    EXPECT_EQ(vtk.at("cells"), std::to_string(a.tetrahedra.size())) << r.output;
    EXPECT_EQ(vtk.at("all tetrahedra"), "1") << r.output;
    EXPECT_EQ(vtk.at("value array"), "1") << r.output;
    // The corners are points, so the mesh's bounds are the volume's physical box.
    std::istringstream bounds(vtk.at("bounds"));
    double             b[6];
    for (double & v : b)
      bounds >> v;
    for (int d = 0; d < 3; ++d)
    {
      double lo = h.origin[d], hi = h.origin[d];
      for (int axis = 0; axis < 3; ++axis)
      {
        const double extent = h.direction[3 * d + axis] * h.spacing[axis] * double((&h.size.x)[axis] - 1);
        (extent < 0 ? lo : hi) += extent;
      }
      EXPECT_NEAR(b[2 * d], lo, 1e-9);
      EXPECT_NEAR(b[2 * d + 1], hi, 1e-9);
    }

    // Every voxel centre lies in the mesh (the 8 corners are points), and the decoded voxel is the
    // spline there rounded and clamped. The spline is continuous, so a voxel on a face shared by two
    // cells has the same value in both (up to floating point), and rounding moves it by at most half a
    // quantum: 0.5 + 1e-6 bounds every voxel, faces and box boundary included; a tie (a spline value
    // within 1e-9 of k + 1/2) could round either way and still stays within it.
    const std::string bytes = dcv::test::FileBytes(probed);
    ASSERT_EQ(bytes.size(), n * sizeof(double));
    std::vector<double> spline(n);
    std::memcpy(spline.data(), bytes.data(), bytes.size());
    EXPECT_EQ(vtk.at("probed"), std::to_string(n)) << "voxel centres VTK found no cell for";
    double   worst = 0.0;
    uint64_t outside = 0;
    for (uint64_t i = 0; i < n; ++i)
    {
      if (std::isnan(spline[i]))
      {
        ++outside;
        continue;
      }
      const double expected = std::min(255.0, std::max(0.0, spline[i]));
      worst = std::max(worst, std::abs(expected - double(voxels[i])));
    }
    EXPECT_EQ(outside, 0u);
    EXPECT_LE(worst, 0.5 + 1e-6);
  }
}

TEST(MeshExport, RefusesBadInputsAndExistingOutputs)
{
  TemporaryDirectory directory;
  const std::string  dcvFile = CompressedPhantom(directory, 100);
  const std::string  mesh = directory / "mesh.vtu";

  // Not a .dcv file: a clear error naming it, status 1, nothing written.
  Result r = RunDcv("mesh " + directory / "phantom.nrrd" + " " + mesh);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("phantom.nrrd"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(mesh));
  r = RunDcv("mesh " + directory / "missing.dcv" + " " + mesh);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("missing.dcv"), std::string::npos) << r.output;

  // A format it does not write (a usage error), a missing directory.
  r = RunDcv("mesh " + dcvFile + " " + directory / "mesh.obj");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find(".vtu"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(directory / "mesh.obj"));
  r = RunDcv("mesh " + dcvFile + " " + directory / "no/mesh.vtu");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("does not exist"), std::string::npos) << r.output;

  // An existing output stays as it is without --force, and is replaced with it.
  {
    std::ofstream(mesh) << "keep me";
  }
  r = RunDcv("mesh " + dcvFile + " " + mesh);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("--force"), std::string::npos) << r.output;
  EXPECT_EQ(dcv::test::FileBytes(mesh), "keep me");
  r = RunDcv("mesh " + dcvFile + " " + mesh + " --force --quiet");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, "");
  EXPECT_EQ(dcv::test::FileBytes(mesh).substr(0, 21), "<?xml version=\"1.0\"?>");
  // No temporary file is left behind.
  for (const auto & entry : fs::directory_iterator(fs::path(mesh).parent_path()))
  {
    EXPECT_NE(entry.path().filename().string().rfind(".dcv-", 0), 0u) << entry.path();
  }

  // Usage errors exit 2, as every usage error of dcv does.
  EXPECT_EQ(RunDcv("mesh " + dcvFile).status, 2);
  EXPECT_EQ(RunDcv("mesh " + dcvFile + " " + mesh + " --bogus").status, 2);
  EXPECT_NE(RunDcv("mesh --help").output.find("residual layer"), std::string::npos);
}

/** A mesh of two tetrahedra sharing a face, for the writer alone. */
dcv::tools::TetrahedralMesh
TwoTetrahedra()
{
  dcv::tools::TetrahedralMesh mesh;
  mesh.points = { { 0, 0, 0 }, { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 }, { 1, 1, 1.5 } };
  mesh.values = { 1.0, -2.5, 3.25, 4.0, 1e10 };
  mesh.tetrahedra = { { 0, 1, 2, 3 }, { 1, 2, 3, 4 } };
  mesh.valueName = "value";
  return mesh;
}

TEST(VtkWriter, LegacyBinaryIsBigEndian)
{
  std::ostringstream out;
  dcv::tools::WriteVtk(TwoTetrahedra(), dcv::tools::VtkFormat::Legacy, out);
  const std::string s = out.str();
  EXPECT_EQ(s.rfind("# vtk DataFile Version 3.0\n", 0), 0u);
  const std::string scalars = "LOOKUP_TABLE default\n";
  const auto        at = s.find(scalars);
  ASSERT_NE(at, std::string::npos);
  // The second value, -2.5, is C0 04 00 00 00 00 00 00 in big-endian IEEE 754.
  const unsigned char expected[8] = { 0xC0, 0x04, 0, 0, 0, 0, 0, 0 };
  EXPECT_EQ(std::memcmp(s.data() + at + scalars.size() + 8, expected, 8), 0);
  // The cells: count 4 then the indices, as big-endian 32-bit integers.
  const std::string cells = "CELLS 2 10\n";
  const auto        c = s.find(cells);
  ASSERT_NE(c, std::string::npos);
  const unsigned char four[4] = { 0, 0, 0, 4 };
  EXPECT_EQ(std::memcmp(s.data() + c + cells.size(), four, 4), 0);
}

TEST(VtkWriter, XmlBlocksInflateToTheValues)
{
  std::ostringstream out;
  const auto         mesh = TwoTetrahedra();
  dcv::tools::WriteVtk(mesh, dcv::tools::VtkFormat::XmlUnstructuredGrid, out);
  const std::string s = out.str();
  EXPECT_NE(s.find("header_type=\"UInt64\""), std::string::npos);
  EXPECT_NE(s.find("Name=\"value\" format=\"appended\" offset=\"0\""), std::string::npos);
  // The first array (the values) starts after the underscore: one block, its header, then zlib.
  const auto start = s.find("encoding=\"raw\">");
  ASSERT_NE(start, std::string::npos);
  const auto underscore = s.find('_', start);
  uint64_t   header[4];
  std::memcpy(header, s.data() + underscore + 1, sizeof(header));
  EXPECT_EQ(header[0], 1u);                      // blocks
  EXPECT_EQ(header[2], mesh.values.size() * 8u); // the last (only) block is partial
  std::vector<double> values(mesh.values.size());
  uLongf              length = uLongf(values.size() * sizeof(double));
  ASSERT_EQ(uncompress(reinterpret_cast<Bytef *>(values.data()),
                       &length,
                       reinterpret_cast<const Bytef *>(s.data() + underscore + 1 + sizeof(header)),
                       uLong(header[3])),
            Z_OK);
  EXPECT_EQ(values, mesh.values);
}

TEST(VtkWriter, RefusesInconsistentMeshes)
{
  std::ostringstream out;
  auto               mesh = TwoTetrahedra();
  mesh.tetrahedra[1][3] = 5;
  EXPECT_THROW(dcv::tools::WriteVtk(mesh, dcv::tools::VtkFormat::Legacy, out), std::invalid_argument);
  mesh = TwoTetrahedra();
  mesh.values.pop_back();
  EXPECT_THROW(dcv::tools::WriteVtk(mesh, dcv::tools::VtkFormat::XmlUnstructuredGrid, out), std::invalid_argument);
  mesh = TwoTetrahedra();
  mesh.valueName = "two words";
  EXPECT_THROW(dcv::tools::WriteVtk(mesh, dcv::tools::VtkFormat::Legacy, out), std::invalid_argument);
  EXPECT_THROW(dcv::tools::VtkFormatOf("mesh.obj"), std::invalid_argument);
}
} // namespace
