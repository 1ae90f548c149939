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
#include "dcvVtkWriter.h"

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <limits>
#include <stdexcept>

namespace dcv::tools
{
namespace
{
constexpr uint8_t VtkTetra = 10; // VTK_TETRA

bool
HostIsBigEndian()
{
  const uint16_t one = 1;
  uint8_t        first = 0;
  std::memcpy(&first, &one, 1);
  return first == 0;
}

/** n values of type T as bytes in the byte order asked for. */
template <typename T>
std::vector<uint8_t>
Bytes(const T * values, std::size_t n, bool bigEndian)
{
  std::vector<uint8_t> bytes(n * sizeof(T));
  if (n > 0)
  {
    std::memcpy(bytes.data(), values, bytes.size());
  }
  if (sizeof(T) > 1 && bigEndian != HostIsBigEndian())
  {
    for (std::size_t i = 0; i < bytes.size(); i += sizeof(T))
    {
      std::reverse(bytes.begin() + std::ptrdiff_t(i), bytes.begin() + std::ptrdiff_t(i + sizeof(T)));
    }
  }
  return bytes;
}

/** The points as x, y, z, x, y, z, ... */
std::vector<double>
Coordinates(const TetrahedralMesh & mesh)
{
  std::vector<double> xyz;
  xyz.reserve(3 * mesh.points.size());
  for (const auto & p : mesh.points)
  {
    xyz.insert(xyz.end(), p.begin(), p.end());
  }
  return xyz;
}

/** The connectivity in type T: four indices a cell, each cell preceded by its count (4) when `counts`. */
template <typename T>
std::vector<T>
Connectivity(const TetrahedralMesh & mesh, bool counts)
{
  std::vector<T> out;
  out.reserve((counts ? 5 : 4) * mesh.tetrahedra.size());
  for (const auto & t : mesh.tetrahedra)
  {
    if (counts)
    {
      out.push_back(T(4));
    }
    for (uint32_t i : t)
    {
      out.push_back(T(i));
    }
  }
  return out;
}

void
Check(const TetrahedralMesh & mesh)
{
  if (mesh.values.size() != mesh.points.size())
  {
    throw std::invalid_argument("a mesh has " + std::to_string(mesh.points.size()) + " points and " +
                                std::to_string(mesh.values.size()) + " values");
  }
  for (const auto & t : mesh.tetrahedra)
  {
    for (uint32_t i : t)
    {
      if (i >= mesh.points.size())
      {
        throw std::invalid_argument("a tetrahedron of the mesh names point " + std::to_string(i) + " of " +
                                    std::to_string(mesh.points.size()));
      }
    }
  }
  const bool named = !mesh.valueName.empty() && std::all_of(mesh.valueName.begin(), mesh.valueName.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
  if (!named)
  {
    throw std::invalid_argument("the name of a mesh's values is letters, digits, '_' and '-': '" + mesh.valueName +
                                "'");
  }
}

/** One array as the XML format's zlib compressor lays it out: UInt64 header (number of blocks,
 * block size, size of the last block if partial, else 0, then each block's compressed size), then the
 * blocks, each compressed on its own. */
std::vector<uint8_t>
Compressed(const std::vector<uint8_t> & raw, int level)
{
  constexpr std::size_t blockSize = std::size_t(1) << 16;
  const std::size_t     blocks = (raw.size() + blockSize - 1) / blockSize;
  std::vector<uint64_t> header{ blocks, blockSize, raw.size() % blockSize };
  std::vector<uint8_t>  data;
  std::vector<uint8_t>  block(compressBound(uLong(blockSize)));
  for (std::size_t b = 0; b < blocks; ++b)
  {
    const std::size_t first = b * blockSize;
    const std::size_t size = std::min(blockSize, raw.size() - first);
    uLongf            length = uLongf(block.size());
    if (compress2(block.data(), &length, raw.data() + first, uLong(size), level) != Z_OK)
    {
      throw std::runtime_error("zlib failed to compress a block of the mesh");
    }
    header.push_back(length);
    data.insert(data.end(), block.begin(), block.begin() + std::ptrdiff_t(length));
  }
  std::vector<uint8_t> out = Bytes(header.data(), header.size(), false);
  out.insert(out.end(), data.begin(), data.end());
  return out;
}

void
WriteXml(const TetrahedralMesh & mesh, std::ostream & out, int level)
{
  struct Array
  {
    std::string          type;
    std::string          name;
    int                  components;
    std::vector<uint8_t> data; // compressed
  };
  const std::size_t n = mesh.points.size();
  const std::size_t m = mesh.tetrahedra.size();
  // 32-bit indices while they fit (half the bytes to compress), 64-bit beyond.
  const bool narrow =
    n <= std::size_t(std::numeric_limits<int32_t>::max()) && 4 * m <= std::size_t(std::numeric_limits<int32_t>::max());
  const std::string    indexType = narrow ? "Int32" : "Int64";
  std::vector<uint8_t> connectivity, offsets;
  if (narrow)
  {
    const auto c = Connectivity<int32_t>(mesh, false);
    connectivity = Bytes(c.data(), c.size(), false);
    std::vector<int32_t> o(m);
    for (std::size_t i = 0; i < m; ++i)
      o[i] = int32_t(4 * (i + 1));
    offsets = Bytes(o.data(), o.size(), false);
  }
  else
  {
    const auto c = Connectivity<int64_t>(mesh, false);
    connectivity = Bytes(c.data(), c.size(), false);
    std::vector<int64_t> o(m);
    for (std::size_t i = 0; i < m; ++i)
      o[i] = int64_t(4 * (i + 1));
    offsets = Bytes(o.data(), o.size(), false);
  }
  const std::vector<double>  xyz = Coordinates(mesh);
  const std::vector<uint8_t> types(m, VtkTetra);
  const Array                arrays[] = {
                   { "Float64", mesh.valueName, 1, Compressed(Bytes(mesh.values.data(), n, false), level) },
                   { "Float64", "Points", 3, Compressed(Bytes(xyz.data(), xyz.size(), false), level) },
                   { indexType, "connectivity", 1, Compressed(connectivity, level) },
                   { indexType, "offsets", 1, Compressed(offsets, level) },
                   { "UInt8", "types", 1, Compressed(types, level) },
  };
  std::vector<uint64_t> offset{ 0 };
  for (const Array & a : arrays)
  {
    offset.push_back(offset.back() + a.data.size());
  }
  auto element = [&](std::size_t i, const char * indent) {
    const Array & a = arrays[i];
    out << indent << "<DataArray type=\"" << a.type << "\" Name=\"" << a.name << "\"";
    if (a.components != 1)
    {
      out << " NumberOfComponents=\"" << a.components << "\"";
    }
    out << " format=\"appended\" offset=\"" << offset[i] << "\"/>\n";
  };
  out << "<?xml version=\"1.0\"?>\n"
      << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\" "
         "compressor=\"vtkZLibDataCompressor\">\n"
      << "  <UnstructuredGrid>\n"
      << "    <Piece NumberOfPoints=\"" << n << "\" NumberOfCells=\"" << m << "\">\n"
      << "      <PointData Scalars=\"" << mesh.valueName << "\">\n";
  element(0, "        ");
  out << "      </PointData>\n"
      << "      <Points>\n";
  element(1, "        ");
  out << "      </Points>\n"
      << "      <Cells>\n";
  element(2, "        ");
  element(3, "        ");
  element(4, "        ");
  out << "      </Cells>\n"
      << "    </Piece>\n"
      << "  </UnstructuredGrid>\n"
      << "  <AppendedData encoding=\"raw\">\n"
      << "   _";
  for (const Array & a : arrays)
  {
    out.write(reinterpret_cast<const char *>(a.data.data()), std::streamsize(a.data.size()));
  }
  out << "\n  </AppendedData>\n"
      << "</VTKFile>\n";
}

void
WriteLegacy(const TetrahedralMesh & mesh, std::ostream & out)
{
  const std::size_t n = mesh.points.size();
  const std::size_t m = mesh.tetrahedra.size();
  // Version 3.0 counts the cell list (a count and four indices a cell) in 32-bit integers.
  if (n > std::size_t(std::numeric_limits<int32_t>::max()) || 5 * m > std::size_t(std::numeric_limits<int32_t>::max()))
  {
    throw std::invalid_argument("the mesh has too many cells for the legacy .vtk format (" + std::to_string(m) +
                                "); write a .vtu file");
  }
  auto write = [&out](const std::vector<uint8_t> & bytes) {
    out.write(reinterpret_cast<const char *>(bytes.data()), std::streamsize(bytes.size()));
    out << "\n";
  };
  out << "# vtk DataFile Version 3.0\n"
      << "DelaunayCompression: linear spline over a Delaunay tetrahedralization\n"
      << "BINARY\n"
      << "DATASET UNSTRUCTURED_GRID\n"
      << "POINTS " << n << " double\n";
  const std::vector<double> xyz = Coordinates(mesh);
  write(Bytes(xyz.data(), xyz.size(), true));
  out << "CELLS " << m << " " << 5 * m << "\n";
  const auto cells = Connectivity<int32_t>(mesh, true);
  write(Bytes(cells.data(), cells.size(), true));
  out << "CELL_TYPES " << m << "\n";
  const std::vector<int32_t> types(m, int32_t(VtkTetra));
  write(Bytes(types.data(), types.size(), true));
  out << "POINT_DATA " << n << "\n"
      << "SCALARS " << mesh.valueName << " double 1\n"
      << "LOOKUP_TABLE default\n";
  write(Bytes(mesh.values.data(), n, true));
}
} // namespace

VtkFormat
VtkFormatOf(const std::string & path)
{
  const std::string extension = std::filesystem::path(path).extension().string();
  if (extension == ".vtu")
  {
    return VtkFormat::XmlUnstructuredGrid;
  }
  if (extension == ".vtk")
  {
    return VtkFormat::Legacy;
  }
  throw std::invalid_argument("'" + path + "': a mesh's file name ends in .vtu (VTK XML) or .vtk (VTK legacy)");
}

void
WriteVtk(const TetrahedralMesh & mesh, VtkFormat format, std::ostream & out, int compressionLevel)
{
  Check(mesh);
  if (format == VtkFormat::XmlUnstructuredGrid)
  {
    WriteXml(mesh, out, compressionLevel);
  }
  else
  {
    WriteLegacy(mesh, out);
  }
}

} // namespace dcv::tools
