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
// dcv mesh: the tetrahedral mesh of a .dcv file (its linear spline) as a VTK file, for direct
// rendering; no voxel is decoded.
#include "dcvResidualLayer.h"
#include "dcvCodec.h"
#include "dcvCommand.h"
#include "dcvVtkWriter.h"

#include <filesystem>
#include <fstream>
#include <iostream>

namespace dcv::tools
{
namespace
{
/** The name of the vertex values in the files written (and in the help and README). */
constexpr const char * ValueName = "value";

struct MeshOptions
{
  std::string  input;
  std::string  output;
  bool         force{ false };
  bool         quiet{ false };
  DecodeLimits limits;
};

/** The spline of a file as a mesh: its points in physical space (the header's geometry, by the one
 * mapping of itkDCVImageInformation.h), its tetrahedra, its dequantized values. */
TetrahedralMesh
SplineMesh(const CompressedFile & file, const Approximation & a)
{
  auto grid = itk::ImageBase<3>::New();
  itk::CopyDCVGeometry(file.header, grid.GetPointer());
  const auto &    region = grid->GetLargestPossibleRegion();
  TetrahedralMesh mesh;
  mesh.valueName = ValueName;
  mesh.points.reserve(a.points.size());
  for (const GridPoint & g : a.points)
  {
    const auto p = itk::GridPointToPhysicalPoint(grid.GetPointer(), region, g);
    mesh.points.push_back({ p[0], p[1], p[2] });
  }
  mesh.values = a.values;
  mesh.tetrahedra.assign(a.tetrahedra.begin(), a.tetrahedra.end());
  return mesh;
}

void
Mesh(const MeshOptions & m)
{
  VtkFormat format;
  try
  {
    format = VtkFormatOf(m.output);
  }
  catch (const std::invalid_argument & e)
  {
    throw UsageError(std::string("cannot write ") + e.what());
  }
  CheckOutputIsNotInput({ m.input }, m.output);
  const CompressedFile file = ReadCompressedFile(m.input);
  CheckOutputPath(m.output, m.force);
  const auto            start = std::chrono::steady_clock::now();
  const Approximation   a = DecodeMesh(file, m.limits);
  const TetrahedralMesh mesh = SplineMesh(file, a);
  PendingOutput         pending(m.output, m.force, false);
  try
  {
    std::ofstream out(pending.Path(), std::ios::binary | std::ios::trunc);
    if (!out)
    {
      throw Failure("cannot write " + Quoted(m.output) + ": cannot create a file in its directory");
    }
    WriteVtk(mesh, format, out);
    out.close();
    if (!out)
    {
      throw Failure("cannot write " + Quoted(m.output) + ": write failed (disk full?)");
    }
  }
  catch (const std::invalid_argument & e)
  {
    throw Failure("cannot write " + Quoted(m.output) + ": " + e.what());
  }
  pending.Commit();
  if (!m.quiet)
  {
    std::cout << "points: " << mesh.points.size() << "\n"
              << "tetrahedra: " << mesh.tetrahedra.size() << "\n"
              << "bytes: " << std::filesystem::file_size(m.output) << "\n"
              << "seconds: " << SecondsSince(start) << "\n";
    if (!file.header.residualLayer.empty())
    {
      std::cout << "residual layer: not part of the mesh, which is the spline ("
                << (file.header.videoLayer ? file.header.residualLayer.size()
                                           : StoredLayerBytes(file.header.residualLayer, file.header.size))
                << " bytes of the file)\n";
    }
  }
}

const RegisterCommand mesh{
  { "mesh",
    std::string("Write the tetrahedral mesh of a .dcv file (its spline; point data \"") + ValueName +
      "\") as VTK .vtu or .vtk without decoding voxels; prints points, tetrahedra, bytes and seconds",
    [](CLI::App & command) -> std::function<void()> {
      auto m = std::make_shared<MeshOptions>();
      command.add_option("INPUT", m->input, "Input .dcv file")->required();
      command
        .add_option("OUTPUT",
                    m->output,
                    "Output mesh: .vtu (VTK XML UnstructuredGrid, zlib-compressed) or .vtk (VTK legacy, binary)")
        ->required();
      command.add_flag("--force,-f", m->force, "Overwrite OUTPUT if it exists");
      AddMaximumMemoryOption(command, m->limits.maximumMemory, "decoding");
      command.add_flag("--quiet,-q", m->quiet, "Print nothing but errors");
      command.footer("The mesh is the spline the points define: a residual layer (JPEG 2000 of what the spline "
                     "leaves), if the file has one, is voxels and not part of it; `dcv decompress` adds it.\n");
      return [m] { Mesh(*m); };
    } }
};
} // namespace
} // namespace dcv::tools
