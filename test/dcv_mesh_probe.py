#!/usr/bin/python3
"""Reads a mesh written by `dcv mesh` with VTK's own readers and probes it at the voxel centres of a grid.

    dcv_mesh_probe.py MESH OUT.raw NX NY NZ OX OY OZ SX SY SZ D00 D01 ... D22

MESH is .vtu (vtkXMLUnstructuredGridReader) or .vtk (vtkUnstructuredGridReader). The grid is the .dcv
file's: physical point = origin + direction (row major) * (spacing * index). Writes the probed values
(float64, x fastest; NaN where VTK found no cell) to OUT.raw and prints, one `key: value` a line, what
the mesh holds, for dcvMeshTest.cxx to check.
"""
import sys

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPolyData, vtkStaticCellLocator
from vtkmodules.vtkFiltersCore import vtkProbeFilter
from vtkmodules.vtkIOLegacy import vtkUnstructuredGridReader
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

VALUE = "value"  # the point data's name, as dcvMesh.cxx writes it


def main(argv):
    mesh_path, out_path = argv[1], argv[2]
    numbers = [float(a) for a in argv[3:]]
    size = [int(v) for v in numbers[0:3]]
    origin = np.array(numbers[3:6])
    spacing = np.array(numbers[6:9])
    direction = np.array(numbers[9:18]).reshape(3, 3)

    reader = vtkXMLUnstructuredGridReader() if mesh_path.endswith(".vtu") else vtkUnstructuredGridReader()
    reader.SetFileName(mesh_path)
    reader.Update()
    grid = reader.GetOutput()
    n, m = grid.GetNumberOfPoints(), grid.GetNumberOfCells()
    types = vtk_to_numpy(grid.GetCellTypesArray()) if m else np.zeros(0)
    values = grid.GetPointData().GetArray(VALUE)
    print("points: %d" % n)
    print("cells: %d" % m)
    print("all tetrahedra: %d" % int(m > 0 and bool(np.all(types == 10))))
    print("value array: %d" % int(values is not None and values.GetNumberOfTuples() == n))
    if values is None or n == 0:
        return 1
    v = vtk_to_numpy(values)
    print("value range: %.17g %.17g" % (v.min(), v.max()))
    bounds = grid.GetBounds()
    print("bounds: " + " ".join("%.17g" % b for b in bounds))

    # Voxel centres in physical space, x fastest.
    k, j, i = np.meshgrid(np.arange(size[2]), np.arange(size[1]), np.arange(size[0]), indexing="ij")
    index = np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1).astype(np.float64)
    physical = origin + (index * spacing) @ direction.T
    points = vtkPoints()
    points.SetData(numpy_to_vtk(np.ascontiguousarray(physical), deep=True))
    probe_input = vtkPolyData()
    probe_input.SetPoints(points)
    probe = vtkProbeFilter()
    probe.SetInputData(probe_input)
    probe.SetSourceData(grid)
    # A cell locator finds every point; the default search (walking from the last cell found) misses
    # some on the box's faces and beside thin cells.
    probe.SetCellLocatorPrototype(vtkStaticCellLocator())
    probe.Update()
    out = probe.GetOutput().GetPointData()
    probed = vtk_to_numpy(out.GetArray(VALUE)).astype(np.float64)
    valid = vtk_to_numpy(out.GetArray(probe.GetValidPointMaskArrayName())).astype(bool)
    probed[~valid] = np.nan
    probed.tofile(out_path)
    print("probed: %d" % int(valid.sum()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
