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
#ifndef itkDCVImageInformation_h
#define itkDCVImageInformation_h

#include "dcvFileFormat.h"
#include "itkImageBase.h"
#include "itkImageIOBase.h"

#include <cmath>
#include <string>
#include <vector>

/** \file itkDCVImageInformation.h
 * The one mapping between a .dcv header's image information and ITK's: the grid (size, spacing,
 * origin, direction) for images and for image IO, grid points and physical points, and pixel types.
 * \ingroup DelaunayCompression
 */
namespace itk
{

/** The header's grid from a region of the image: its size, and the physical point of its first voxel
 * as origin (a region that does not start at index 0 keeps its place in space). */
inline void
CopyDCVGeometry(const ImageBase<3> * image, const ImageRegion<3> & region, dcv::FileHeader & h)
{
  h.size = dcv::GridSize{ int32_t(region.GetSize()[0]), int32_t(region.GetSize()[1]), int32_t(region.GetSize()[2]) };
  ImageBase<3>::PointType first;
  image->TransformIndexToPhysicalPoint(region.GetIndex(), first);
  for (unsigned int i = 0; i < 3; ++i)
  {
    h.spacing[i] = image->GetSpacing()[i];
    h.origin[i] = first[i];
    for (unsigned int j = 0; j < 3; ++j)
    {
      h.direction[3 * i + j] = image->GetDirection()(i, j);
    }
  }
}

/** The image's largest possible region (index 0), spacing, origin and direction from the header. */
inline void
CopyDCVGeometry(const dcv::FileHeader & h, ImageBase<3> * image)
{
  ImageBase<3>::SizeType      size;
  ImageBase<3>::SpacingType   spacing;
  ImageBase<3>::PointType     origin;
  ImageBase<3>::DirectionType direction;
  for (unsigned int i = 0; i < 3; ++i)
  {
    size[i] = SizeValueType((&h.size.x)[i]);
    spacing[i] = h.spacing[i];
    origin[i] = h.origin[i];
    for (unsigned int j = 0; j < 3; ++j)
    {
      direction(i, j) = h.direction[3 * i + j];
    }
  }
  image->SetLargestPossibleRegion(ImageRegion<3>(size));
  image->SetSpacing(spacing);
  image->SetOrigin(origin);
  image->SetDirection(direction);
}

/** The image IO's dimensions, spacing, origin and direction from the header (ITK's IO keeps
 * directions by column: axis i's direction vector). */
inline void
CopyDCVGeometry(const dcv::FileHeader & h, ImageIOBase * io)
{
  io->SetNumberOfDimensions(3);
  for (unsigned int i = 0; i < 3; ++i)
  {
    io->SetDimensions(i, SizeValueType((&h.size.x)[i]));
    io->SetSpacing(i, h.spacing[i]);
    io->SetOrigin(i, h.origin[i]);
    std::vector<double> axis(3);
    for (unsigned int r = 0; r < 3; ++r)
    {
      axis[r] = h.direction[3 * r + i];
    }
    io->SetDirection(i, axis);
  }
}

/** The header's grid from an image IO about to write (the inverse of the above). */
inline void
CopyDCVGeometry(const ImageIOBase * io, dcv::FileHeader & h)
{
  for (unsigned int i = 0; i < 3; ++i)
  {
    (&h.size.x)[i] = int32_t(io->GetDimensions(i));
    h.spacing[i] = io->GetSpacing(i);
    h.origin[i] = io->GetOrigin(i);
    const std::vector<double> axis = io->GetDirection(i);
    for (unsigned int r = 0; r < 3; ++r)
    {
      h.direction[3 * r + i] = axis[r];
    }
  }
}

/** The grid position (relative to the region's first index) of the voxel of `image` at physical
 * point p, when p lies on a voxel of `region` (within 1e-3 voxel); false otherwise. One rule for
 * every place that turns a mesh point back into a voxel of the .dcv grid. */
template <typename TPoint>
bool
PhysicalPointToGridPoint(const ImageBase<3> * image, const ImageRegion<3> & region, const TPoint & p,
                         dcv::GridPoint & g)
{
  typename ImageBase<3>::PointType physical;
  physical.CastFrom(p);
  const auto continuous = image->TransformPhysicalPointToContinuousIndex<double>(physical);
  for (unsigned int d = 0; d < 3; ++d)
  {
    const double c = continuous[d] - double(region.GetIndex()[d]);
    const double r = std::round(c);
    if (std::abs(c - r) > 1e-3 || r < 0 || r >= double(region.GetSize()[d]))
    {
      return false;
    }
    g[d] = int32_t(r);
  }
  return true;
}

/** The physical point of grid position g of `image`'s region (the inverse of the above). */
inline ImageBase<3>::PointType
GridPointToPhysicalPoint(const ImageBase<3> * image, const ImageRegion<3> & region, const dcv::GridPoint & g)
{
  ImageBase<3>::IndexType index;
  for (unsigned int d = 0; d < 3; ++d)
  {
    index[d] = region.GetIndex()[d] + g[d];
  }
  ImageBase<3>::PointType p;
  image->TransformIndexToPhysicalPoint(index, p);
  return p;
}

/** The .dcv pixel type of an ITK component type; throws ExceptionObject naming `file` for any other
 * (64-bit integers, unknown). */
inline dcv::PixelType
DCVPixelType(IOComponentEnum component, const std::string & file)
{
  switch (component)
  {
    case IOComponentEnum::UCHAR:
      return dcv::PixelType::UInt8;
    case IOComponentEnum::CHAR:
      return dcv::PixelType::Int8;
    case IOComponentEnum::USHORT:
      return dcv::PixelType::UInt16;
    case IOComponentEnum::SHORT:
      return dcv::PixelType::Int16;
    case IOComponentEnum::UINT:
      return dcv::PixelType::UInt32;
    case IOComponentEnum::INT:
      return dcv::PixelType::Int32;
    case IOComponentEnum::FLOAT:
      return dcv::PixelType::Float32;
    case IOComponentEnum::DOUBLE:
      return dcv::PixelType::Float64;
    default:
      itkGenericExceptionMacro(<< file << " has " << ImageIOBase::GetComponentTypeAsString(component)
                               << " voxels; .dcv holds 8, 16 and 32-bit integers, float and double");
  }
}

/** The ITK component type of a .dcv pixel type. */
inline IOComponentEnum
DCVComponentType(dcv::PixelType type)
{
  IOComponentEnum component = IOComponentEnum::UNKNOWNCOMPONENTTYPE;
  dcv::VisitPixelType(type,
                      [&component](auto pixel) { component = ImageIOBase::MapPixelType<decltype(pixel)>::CType; });
  return component;
}

} // namespace itk

#endif
