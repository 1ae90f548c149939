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
#ifndef itkDCVMeshIO_h
#define itkDCVMeshIO_h

#include "DelaunayCompressionExport.h"
#include "dcvFileFormat.h"
#include "itkImageBase.h"
#include "itkMeshIOBase.h"

namespace itk
{

/** \class DCVMeshIO
 * \brief Reads and writes .dcv files (docs/format.md) as tetrahedral meshes.
 *
 * Reading (MeshFileReader) gives the Delaunay tetrahedralization of the file's points as tetrahedron
 * cells, the points in physical coordinates, and the vertex values as point data: the spline. A file's
 * residual layer (voxels, not a mesh) is not read here; DCVImageIO adds it to the image.
 *
 * Writing (MeshFileWriter) stores the points and their point data: the mesh's cells are not stored,
 * since a reader rebuilds them as the Delaunay tetrahedralization of the points. The IO must be told the
 * voxel grid with SetReferenceImage(); every point must lie on a voxel of it (within 0.001 voxel) and the
 * grid's 8 corners must be points, otherwise writing fails with a clear error. Values are rounded to
 * the lattice QuantizationOrigin + k QuantizationStep: set both as the approximation filter reports
 * them (GetQuantizationOrigin(), GetChosenQuantizationStep()); writing refuses a step left at 0.
 * DecodedPixelType, the pixel type a decoder gives the volume, is the reference image's pixel type
 * when it is an itk::Image of a .dcv pixel type, else it must be set. Scale, the Delaunay space of the
 * cells a reader rebuilds, is by default the one the approximation filter chooses from the reference
 * image's spacing (dcv::AutomaticScale); set it as the filter reports it (GetChosenScale()) otherwise. The file's mode
 * is "unknown" (FileHeader::UnknownMode): the points were not chosen by the encoder. For a file at a bit rate, write
 * the image with ImageFileWriter (DCVImageIO) instead. \ingroup DelaunayCompression
 */
class DelaunayCompression_EXPORT DCVMeshIO : public MeshIOBase
{
public:
  ITK_DISALLOW_COPY_AND_MOVE(DCVMeshIO);

  using Self = DCVMeshIO;
  using Superclass = MeshIOBase;
  using Pointer = SmartPointer<Self>;
  using ConstPointer = SmartPointer<const Self>;

  itkNewMacro(Self);
  itkTypeMacro(DCVMeshIO, MeshIOBase);

  /** The voxel grid of the points (needed for writing). */
  itkSetConstObjectMacro(ReferenceImage, ImageBase<3>);
  itkGetConstObjectMacro(ReferenceImage, ImageBase<3>);
  itkSetMacro(QuantizationOrigin, double);
  itkGetConstMacro(QuantizationOrigin, double);
  itkSetMacro(QuantizationStep, double);
  itkGetConstMacro(QuantizationStep, double);
  /** Reading: the most memory (bytes) that decoding a file may need (dcv::DecodingMemory() of the mesh:
   * about 1 KiB per point); default dcv::DefaultMaximumMemory(), half of the physical memory; 0: no
   * limit. A file that needs more is refused before anything is allocated from its numbers. */
  itkSetMacro(MaximumMemory, uint64_t);
  itkGetConstMacro(MaximumMemory, uint64_t);
  void
  SetDecodedPixelType(dcv::PixelType type)
  {
    m_DecodedPixelType = type;
    m_DecodedPixelTypeSet = true;
    this->Modified();
  }
  /** Scale of the Delaunay space (default 0, 0, 0: from the reference image's spacing). */
  void
  SetScale(const dcv::GridScale & scale)
  {
    m_Scale = scale;
    this->Modified();
  }
  const dcv::GridScale &
  GetScale() const
  {
    return m_Scale;
  }
  /** The set type, else the reference image's (float32 when neither says). */
  dcv::PixelType
  GetDecodedPixelType() const;

  bool
  CanReadFile(const char * fileName) override;
  void
  ReadMeshInformation() override;
  void
  ReadPoints(void * buffer) override;
  void
  ReadCells(void * buffer) override;
  void
  ReadPointData(void * buffer) override;
  void
  ReadCellData(void *) override
  {}

  bool
  CanWriteFile(const char * fileName) override;
  void
  WriteMeshInformation() override
  {}
  void
  WritePoints(void * buffer) override;
  void
  WriteCells(void *) override
  {}
  void
  WritePointData(void * buffer) override;
  void
  WriteCellData(void *) override
  {}
  void
  Write() override;

protected:
  DCVMeshIO();
  ~DCVMeshIO() override = default;
  void
  PrintSelf(std::ostream & os, Indent indent) const override;

private:
  void
  Decode();

  ImageBase<3>::ConstPointer m_ReferenceImage;
  double                     m_QuantizationOrigin{ 0.0 };
  double                     m_QuantizationStep{ 0.0 };
  uint64_t                   m_MaximumMemory{ dcv::DefaultMaximumMemory() };
  dcv::PixelType             m_DecodedPixelType{ dcv::PixelType::Float32 };
  bool                       m_DecodedPixelTypeSet{ false };
  dcv::GridScale             m_Scale{ { 0, 0, 0 } };
  dcv::FileHeader            m_Header;
  std::vector<double>        m_Points; // physical coordinates, written or read
  std::vector<double>        m_Values;
  std::vector<uint32_t>      m_Cells; // read: type, 4, ids per cell
};

} // namespace itk

#endif
