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
#ifndef itkTetrahedralMeshToImageFilter_h
#define itkTetrahedralMeshToImageFilter_h

#include "itkImageSource.h"

namespace itk
{

/** \class TetrahedralMeshToImageFilter
 * \brief Rasterizes the linear spline of a tetrahedral mesh onto an image grid.
 *
 * Every mesh point must lie on a voxel of the output grid (within 0.001 voxel) and carry its value
 * as point data; every cell must be a tetrahedron. Each voxel takes the linear (barycentric)
 * interpolation of the values of the one tetrahedron that owns it: ownership is decided with exact
 * integer predicates and a tie rule, so that a tetrahedralization of the grid's box gives every voxel
 * exactly one owner. Voxels that no cell owns take BackgroundValue. Integer pixel types get the
 * value rounded half up and clamped to their range.
 *
 * This is the decoder of DelaunayApproximationImageToMeshFilter: on that filter's output and the
 * input's grid it reproduces the approximation voxel for voxel.
 *
 * Parameters:
 * - the output grid: Size, Index, Spacing, Origin, Direction (defaults: empty, 0, 1, 0, identity),
 *   or all of them at once from SetReferenceImage(), which takes precedence when set;
 * - BackgroundValue (default 0).
 *
 * \sa DelaunayApproximationImageToMeshFilter
 * \ingroup DelaunayCompression
 */
template <typename TInputMesh, typename TOutputImage>
class ITK_TEMPLATE_EXPORT TetrahedralMeshToImageFilter : public ImageSource<TOutputImage>
{
public:
  ITK_DISALLOW_COPY_AND_MOVE(TetrahedralMeshToImageFilter);

  using Self = TetrahedralMeshToImageFilter;
  using Superclass = ImageSource<TOutputImage>;
  using Pointer = SmartPointer<Self>;
  using ConstPointer = SmartPointer<const Self>;

  itkNewMacro(Self);
  itkTypeMacro(TetrahedralMeshToImageFilter, ImageSource);

  using InputMeshType = TInputMesh;
  using OutputImageType = TOutputImage;
  using OutputPixelType = typename OutputImageType::PixelType;
  using SizeType = typename OutputImageType::SizeType;
  using IndexType = typename OutputImageType::IndexType;
  using SpacingType = typename OutputImageType::SpacingType;
  using PointType = typename OutputImageType::PointType;
  using DirectionType = typename OutputImageType::DirectionType;
  using ReferenceImageType = ImageBase<3>;

  static_assert(OutputImageType::ImageDimension == 3, "TetrahedralMeshToImageFilter makes 3D images");
  static_assert(InputMeshType::PointDimension == 3, "TetrahedralMeshToImageFilter needs a 3D mesh");

  using Superclass::SetInput;
  void
  SetInput(const InputMeshType * mesh);
  const InputMeshType *
  GetInput() const;

  itkSetMacro(Size, SizeType);
  itkGetConstReferenceMacro(Size, SizeType);
  itkSetMacro(Index, IndexType);
  itkGetConstReferenceMacro(Index, IndexType);
  itkSetMacro(Spacing, SpacingType);
  itkGetConstReferenceMacro(Spacing, SpacingType);
  itkSetMacro(Origin, PointType);
  itkGetConstReferenceMacro(Origin, PointType);
  itkSetMacro(Direction, DirectionType);
  itkGetConstReferenceMacro(Direction, DirectionType);

  /** Take the whole output grid (region, spacing, origin, direction) from this image. */
  itkSetConstObjectMacro(ReferenceImage, ReferenceImageType);
  itkGetConstObjectMacro(ReferenceImage, ReferenceImageType);

  /** Value of voxels that no tetrahedron owns (default 0). */
  itkSetMacro(BackgroundValue, OutputPixelType);
  itkGetConstMacro(BackgroundValue, OutputPixelType);

protected:
  TetrahedralMeshToImageFilter();
  ~TetrahedralMeshToImageFilter() override = default;

  void
  PrintSelf(std::ostream & os, Indent indent) const override;

  void
  GenerateOutputInformation() override;

  /** The whole output is produced at once. */
  void
  EnlargeOutputRequestedRegion(DataObject * output) override;

  void
  GenerateData() override;

private:
  SizeType                         m_Size{ { 0, 0, 0 } };
  IndexType                        m_Index{ { 0, 0, 0 } };
  SpacingType                      m_Spacing{ 1.0 };
  PointType                        m_Origin{ 0.0 };
  DirectionType                    m_Direction{ DirectionType::GetIdentity() };
  ReferenceImageType::ConstPointer m_ReferenceImage;
  OutputPixelType                  m_BackgroundValue{};
};

} // namespace itk

#ifndef ITK_MANUAL_INSTANTIATION
#  include "itkTetrahedralMeshToImageFilter.hxx"
#endif

#endif
