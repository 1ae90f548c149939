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
#ifndef itkDelaunayApproximationImageToMeshFilter_h
#define itkDelaunayApproximationImageToMeshFilter_h

#include "dcvEncoder.h"
#include "itkImageToMeshFilter.h"
#include "itkTetrahedronCell.h"

namespace itk
{

/** \class DelaunayApproximationImageToMeshFilter
 * \brief Approximates a 3D image by a linear spline over an adaptive Delaunay tetrahedralization.
 *
 * The output is a tetrahedral mesh whose points are significant points of the image (grid
 * positions, in physical coordinates) with the spline's values at them as point data. Rasterizing the
 * mesh with TetrahedralMeshToImageFilter onto the input's grid gives the approximation; the points
 * and values alone determine it, since their Delaunay tetrahedralization is unique.
 *
 * Method: R. Jovanovic and R. A. Lorentz, "A combined image approach to compression of volumetric
 * data using Delaunay tetrahedralization": Silva's greedy refinement on tetrahedra (start from the
 * 8 corners, then alternately insert the voxel of largest error and the worst voxel of the cell with
 * the largest squared-error sum), refinement/decimation with the approximate removal cost, and the
 * combined image approach with I* = BilateralImageFilter(I); plus least-squares vertex values.
 *
 * Parameters:
 * - NumberOfPoints (default 10000, at least 8): the number of significant points. Fewer are used
 *   when the approximation becomes exact earlier.
 * - Mode (default dcv::Mode::Best): silva, dec, dec+com (the paper's columns) or best (ours: decimation
 *   and least-squares values, without I*, which with them measured no gain); see dcv::Mode.
 * - DomainSigma (default 1.0, in voxels) and RangeSigma (default 0: 8% of the PSNR peak, i.e. 20.4
 *   for 8-bit data; else in intensity units) of the bilateral filter that makes I* (mode dec+com).
 * - Alpha (default 0.9, > 0): positions are chosen on I* until PSNR(L) >= Alpha * PSNR(I*), then on I
 *   (mode dec+com).
 * - QuantizationStep (default 0: none): vertex values are then min(I) + k * QuantizationStep, and the
 *   refinement works with these values (what a .dcv file stores). GetQuantizationOrigin() gives min(I).
 * - BitsPerVoxel (default 0: off): when positive, the point count is chosen instead of NumberOfPoints
 *   so that the .dcv file of the output (without metadata) has at most floor(BitsPerVoxel * voxels / 8)
 *   bytes and at least 97% of that, and, when QuantizationStep is 0, the step too: the best of 1, 2 and
 *   4 times 1/64 of the peak (dcv::ApproximateToBudget). GetChosenQuantizationStep() gives the step.
 * - Scale (default 0, 0, 0: from the spacing): the Delaunay tetrahedralization is built for the points
 *   (sx x, sy y, sz z), so that with thick slices cells across slices are thin (dcv::AutomaticScale:
 *   integers in the ratios of the spacings). GetChosenScale() gives the one used.
 * - PSNR (default 0: off; not with BitsPerVoxel): when positive, the fewest points whose decoded image
 *   (rounded to the input's pixel type) reaches this PSNR in dB (dcv::ApproximateToQuality); values
 *   are quantized with QuantizationStep, or when it is 0 with 1/64 of the peak, less where the target
 *   needs it.
 *
 * Results after Update(): GetSquaredError() (sum over voxels of the squared difference between the
 * input and the unrounded spline) and GetMeanSquaredError().
 *
 * The input is any 3D scalar image; each axis needs 2 to 65535 voxels. Pixel values are handled as
 * float. Progress events are sent during the refinement and AbortGenerateData() is honoured.
 * The work is dcv::Approximate (itkDCVEncoder.h), the encoder's own path, so a mesh made here and a
 * .dcv file written by ImageFileWriter with the same options hold the same points and values.
 *
 * \sa TetrahedralMeshToImageFilter
 * \ingroup DelaunayCompression
 */
template <typename TInputImage, typename TOutputMesh>
class ITK_TEMPLATE_EXPORT DelaunayApproximationImageToMeshFilter : public ImageToMeshFilter<TInputImage, TOutputMesh>
{
public:
  ITK_DISALLOW_COPY_AND_MOVE(DelaunayApproximationImageToMeshFilter);

  using Self = DelaunayApproximationImageToMeshFilter;
  using Superclass = ImageToMeshFilter<TInputImage, TOutputMesh>;
  using Pointer = SmartPointer<Self>;
  using ConstPointer = SmartPointer<const Self>;

  itkNewMacro(Self);
  itkTypeMacro(DelaunayApproximationImageToMeshFilter, ImageToMeshFilter);

  using InputImageType = TInputImage;
  using InputPixelType = typename InputImageType::PixelType;
  using OutputMeshType = TOutputMesh;
  using OutputPixelType = typename OutputMeshType::PixelType;
  using CellType = typename OutputMeshType::CellType;
  using TetrahedronCellType = TetrahedronCell<CellType>;

  static constexpr unsigned int ImageDimension = InputImageType::ImageDimension;
  static_assert(ImageDimension == 3, "DelaunayApproximationImageToMeshFilter needs a 3D image");
  static_assert(OutputMeshType::PointDimension == 3, "DelaunayApproximationImageToMeshFilter needs a 3D mesh");

  /** Number of significant points (default 10000, at least 8: the corners). */
  itkSetClampMacro(NumberOfPoints, SizeValueType, 8, NumericTraits<SizeValueType>::max());
  itkGetConstMacro(NumberOfPoints, SizeValueType);

  /** Which variant of the method runs (default dcv::Mode::Best). */
  itkSetMacro(Mode, dcv::Mode);
  itkGetConstMacro(Mode, dcv::Mode);

  /** Bilateral filter of I*: spatial sigma in voxels (default 1.0) and intensity sigma (default 0:
   * 8% of the PSNR peak, so that it scales with the data's range). */
  itkSetMacro(DomainSigma, double);
  itkGetConstMacro(DomainSigma, double);
  itkSetMacro(RangeSigma, double);
  itkGetConstMacro(RangeSigma, double);

  /** Switch of the selection image from I* to I at PSNR(L) >= Alpha * PSNR(I*) (default 0.9). */
  itkSetMacro(Alpha, double);
  itkGetConstMacro(Alpha, double);

  /** Step of the vertex values (default 0: not quantized); the origin is the input's minimum. */
  itkSetMacro(QuantizationStep, double);
  itkGetConstMacro(QuantizationStep, double);
  itkGetConstMacro(QuantizationOrigin, double);
  /** Step of the output's values after Update(): QuantizationStep, or the one rate control chose. */
  itkGetConstMacro(ChosenQuantizationStep, double);

  /** Size of the output's .dcv file in bits per voxel (default 0: off, NumberOfPoints decides). */
  itkSetMacro(BitsPerVoxel, double);
  itkGetConstMacro(BitsPerVoxel, double);

  /** Per-axis scale of the space the tetrahedralization is Delaunay in (default 0, 0, 0: from the
   * input's spacing, dcv::AutomaticScale; else 1 to 16 per axis). */
  // Not itkSetMacro: its debug message would print a std::array, which has no operator<<.
  virtual void
  SetScale(const dcv::GridScale & scale)
  {
    if (m_Scale != scale)
    {
      m_Scale = scale;
      this->Modified();
    }
  }
  itkGetConstReferenceMacro(Scale, dcv::GridScale);
  /** The scale the last Update() used. */
  itkGetConstReferenceMacro(ChosenScale, dcv::GridScale);

  /** Quality target in dB (default 0: off): the fewest points whose decoded PSNR reaches it. */
  itkSetMacro(PSNR, double);
  itkGetConstMacro(PSNR, double);

  /** Sum of squared errors of the approximation, after Update(). */
  itkGetConstMacro(SquaredError, double);
  /** Mean squared error of the approximation, after Update(). */
  itkGetConstMacro(MeanSquaredError, double);
  /** PSNR of I* against I, after Update() (0 when the mode does not smooth). */
  itkGetConstMacro(SmoothedPSNR, double);

  /** Seconds of each phase of the last Update() (smoothing, refinement, decimation, least squares). */
  using Timings = dcv::EncoderResult::Timings;
  const Timings &
  GetTimings() const
  {
    return m_Timings;
  }

protected:
  DelaunayApproximationImageToMeshFilter();
  ~DelaunayApproximationImageToMeshFilter() override = default;

  void
  PrintSelf(std::ostream & os, Indent indent) const override;

  void
  GenerateInputRequestedRegion() override;

  /** Nothing to do: the mesh's extent is only known once the data are generated. */
  void
  GenerateOutputInformation() override
  {}

  void
  GenerateData() override;

private:
  SizeValueType  m_NumberOfPoints{ 10000 };
  dcv::Mode      m_Mode{ dcv::Mode::Best };
  double         m_DomainSigma{ 1.0 };
  double         m_RangeSigma{ 0.0 };
  double         m_Alpha{ 0.9 };
  double         m_QuantizationStep{ 0.0 };
  double         m_QuantizationOrigin{ 0.0 };
  double         m_BitsPerVoxel{ 0.0 };
  double         m_PSNR{ 0.0 };
  dcv::GridScale m_Scale{ { 0, 0, 0 } };
  dcv::GridScale m_ChosenScale{ { 1, 1, 1 } };
  double         m_ChosenQuantizationStep{ 0.0 };
  double         m_SquaredError{ 0.0 };
  double         m_MeanSquaredError{ 0.0 };
  double         m_SmoothedPSNR{ 0.0 };
  Timings        m_Timings;
};

} // namespace itk

#ifndef ITK_MANUAL_INSTANTIATION
#  include "itkDelaunayApproximationImageToMeshFilter.hxx"
#endif

#endif
