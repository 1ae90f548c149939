# ==========================================================================
#
#   Copyright NumFOCUS
#
#   Licensed under the Apache License, Version 2.0 (the "License");
#   you may not use this file except in compliance with the License.
#   You may obtain a copy of the License at
#
#          http://www.apache.org/licenses/LICENSE-2.0.txt
#
#   Unless required by applicable law or agreed to in writing, software
#   distributed under the License is distributed on an "AS IS" BASIS,
#   WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
#   See the License for the specific language governing permissions and
#   limitations under the License.
#
# ==========================================================================*/
"""Encode a small synthetic volume with DelaunayApproximationImageToMeshFilter, decode it with
TetrahedralMeshToImageFilter and check the decoded volume against the filter's reported error."""

import sys

import itk
import numpy as np

number_of_points = int(sys.argv[1]) if len(sys.argv) > 1 else 300

Dimension = 3
ImageType = itk.Image[itk.F, Dimension]
MeshType = itk.Mesh[itk.F, Dimension]

# A linear ramp (which a linear spline reproduces exactly) plus a ball (which it cannot).
z, y, x = np.mgrid[0:12, 0:14, 0:16]
ball = ((x - 8.0) ** 2 + (y - 7.0) ** 2 + (z - 6.0) ** 2) < 16.0
volume = (x + 2.0 * y + 3.0 * z + 100.0 * ball).astype(np.float32)
image = itk.image_from_array(volume)
image.SetSpacing([0.5, 1.0, 2.0])
image.SetOrigin([-4.0, 2.0, 10.0])

approximate = itk.DelaunayApproximationImageToMeshFilter[ImageType, MeshType].New()
approximate.SetInput(image)
approximate.SetNumberOfPoints(number_of_points)
approximate.Update()
mesh = approximate.GetOutput()
print(
    f"points: {mesh.GetNumberOfPoints()}  cells: {mesh.GetNumberOfCells()}  "
    f"MSE: {approximate.GetMeanSquaredError()}"
)
assert approximate.GetNumberOfPoints() == number_of_points
assert 8 <= mesh.GetNumberOfPoints() <= number_of_points
assert mesh.GetNumberOfCells() > 0

rasterize = itk.TetrahedralMeshToImageFilter[MeshType, ImageType].New()
rasterize.SetInput(mesh)
rasterize.SetReferenceImage(image)
rasterize.Update()
decoded_image = rasterize.GetOutput()
assert tuple(decoded_image.GetLargestPossibleRegion().GetSize()) == tuple(image.GetLargestPossibleRegion().GetSize())
assert tuple(decoded_image.GetSpacing()) == tuple(image.GetSpacing())

# Float output keeps the spline's values unrounded, so its error is the one the filter reports.
decoded = itk.array_from_image(decoded_image)
assert decoded.shape == volume.shape
mse = float(np.mean((decoded.astype(np.float64) - volume) ** 2))
reported = approximate.GetMeanSquaredError()
print(f"decoded MSE: {mse}")
assert abs(mse - reported) <= 1e-4 * max(1.0, reported), (mse, reported)
assert mse < float(np.var(volume))
