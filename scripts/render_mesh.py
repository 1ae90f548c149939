#!/usr/bin/python3
"""Renders a mesh written by `dcv mesh` (a .vtu or .vtk file) into a PNG, headless.

    /usr/bin/python3 scripts/render_mesh.py MESH.vtu OUT.png [--axis x|y|z] [--size 900x600]

The tetrahedra whose four values are all at least --threshold of the value range (the object, not the
background around it) and that lie on one side of the volume's middle plane (across --axis, x by default, kept whole:
ParaView's Threshold, then Clip with "Crinkle clip") are drawn, their faces colored by the point data
"value" (gray scale over its range) with the cell edges on top: the spline the points define, and the
cells it lives on. Needs Debian's python3-vtk9 (and numpy). Debian's VTK renders
through X; without a display the script runs itself again under xvfb-run (Debian's xvfb).
"""
import argparse
import os
import shutil
import sys

VALUE = "value"  # the point data's name, as dcv mesh writes it


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mesh", help="a .vtu or .vtk file written by dcv mesh")
    p.add_argument("png", help="the picture to write")
    p.add_argument("--axis", choices="xyz", default="x", help="the clip plane is across this physical axis")
    p.add_argument("--keep", choices=["below", "above"], default="below", help="which side of the plane is kept")
    p.add_argument("--threshold", type=float, default=0.1, help="fraction of the value range the cells' values reach")
    p.add_argument("--size", default="840x560", help="WIDTHxHEIGHT in pixels")
    p.add_argument("--azimuth", type=float, default=30.0, help="camera azimuth from the cut's normal, degrees")
    p.add_argument("--elevation", type=float, default=15.0, help="camera elevation, degrees")
    p.add_argument("--zoom", type=float, default=1.3, help="camera zoom")
    return p.parse_args(argv)


def main(argv):
    args = parse_args(argv)
    if not os.environ.get("DISPLAY") and not os.environ.get("DCV_RENDER_UNDER_XVFB"):
        xvfb = shutil.which("xvfb-run")
        if not xvfb:
            sys.exit("render_mesh.py: no display, and no xvfb-run to make one (apt-get install xvfb xauth)")
        os.environ["DCV_RENDER_UNDER_XVFB"] = "1"
        os.execv(xvfb, [xvfb, "-a", "-s", "-screen 0 1280x1024x24", sys.executable, os.path.abspath(__file__)] + argv)

    from vtkmodules.vtkCommonDataModel import vtkPlane
    from vtkmodules.vtkFiltersCore import vtkThreshold
    from vtkmodules.vtkFiltersExtraction import vtkExtractGeometry
    from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter
    from vtkmodules.vtkIOImage import vtkPNGWriter
    from vtkmodules.vtkIOLegacy import vtkUnstructuredGridReader
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
    from vtkmodules.vtkRenderingCore import (
        vtkActor,
        vtkColorTransferFunction,
        vtkDataSetMapper,
        vtkRenderer,
        vtkRenderWindow,
        vtkWindowToImageFilter,
    )
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
    import vtkmodules.vtkRenderingFreeType  # noqa: F401 (text of the scalar bar)
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401 (the render window's implementation)

    reader = vtkXMLUnstructuredGridReader() if args.mesh.endswith(".vtu") else vtkUnstructuredGridReader()
    reader.SetFileName(args.mesh)
    reader.Update()
    grid = reader.GetOutput()
    values = grid.GetPointData().GetArray(VALUE)
    if grid.GetNumberOfCells() == 0 or values is None:
        sys.exit("render_mesh.py: %s holds no cells with point data '%s'" % (args.mesh, VALUE))
    low, high = values.GetRange()
    bounds = grid.GetBounds()
    axis = "xyz".index(args.axis)

    # The object: cells whose four values reach the threshold.
    threshold = vtkThreshold()
    threshold.SetInputData(grid)
    threshold.SetInputArrayToProcess(0, 0, 0, 0, VALUE)  # point data
    threshold.SetLowerThreshold(low + args.threshold * (high - low))
    threshold.SetUpperThreshold(high)
    threshold.SetThresholdFunction(vtkThreshold.THRESHOLD_BETWEEN)
    threshold.AllScalarsOn()

    # Whole cells on one side of the middle plane.
    plane = vtkPlane()
    plane.SetOrigin([(bounds[2 * d] + bounds[2 * d + 1]) / 2 for d in range(3)])
    normal = [0.0, 0.0, 0.0]
    normal[axis] = 1.0 if args.keep == "below" else -1.0
    plane.SetNormal(normal)
    clip = vtkExtractGeometry()
    clip.SetInputConnection(threshold.GetOutputPort())
    clip.SetImplicitFunction(plane)
    clip.ExtractInsideOn()  # where the plane's function is negative
    clip.ExtractBoundaryCellsOn()
    surface = vtkDataSetSurfaceFilter()
    surface.SetInputConnection(clip.GetOutputPort())
    surface.Update()
    kept = clip.GetOutput().GetNumberOfCells()

    colors = vtkColorTransferFunction()
    colors.AddRGBPoint(low, 0.0, 0.0, 0.0)
    colors.AddRGBPoint(high, 1.0, 1.0, 1.0)

    faces = vtkDataSetMapper()
    faces.SetInputConnection(surface.GetOutputPort())
    faces.SetScalarModeToUsePointFieldData()
    faces.SelectColorArray(VALUE)
    faces.SetLookupTable(colors)
    faces.SetScalarRange(low, high)
    faces.SetResolveCoincidentTopologyToPolygonOffset()
    face_actor = vtkActor()
    face_actor.SetMapper(faces)
    face_actor.GetProperty().SetInterpolationToFlat()
    face_actor.GetProperty().SetAmbient(0.6)  # the colour is the value; light only shows the shape
    face_actor.GetProperty().SetDiffuse(0.4)

    edges = vtkDataSetMapper()
    edges.SetInputConnection(surface.GetOutputPort())
    edges.ScalarVisibilityOff()
    edge_actor = vtkActor()
    edge_actor.SetMapper(edges)
    edge_actor.GetProperty().SetRepresentationToWireframe()
    edge_actor.GetProperty().SetColor(0.85, 0.35, 0.1)
    edge_actor.GetProperty().SetOpacity(0.35)
    edge_actor.GetProperty().SetLineWidth(1.0)
    edge_actor.GetProperty().LightingOff()

    bar = vtkScalarBarActor()
    bar.SetLookupTable(colors)
    bar.SetTitle(VALUE)
    bar.SetNumberOfLabels(3)
    bar.SetWidth(0.08)
    bar.SetHeight(0.5)
    bar.SetPosition(0.9, 0.25)

    renderer = vtkRenderer()
    renderer.SetBackground(0.12, 0.14, 0.18)
    renderer.AddActor(face_actor)
    renderer.AddActor(edge_actor)
    renderer.AddActor2D(bar)
    # Facing the cut (the plane's normal points out of the kept side), turned by azimuth and elevation.
    camera = renderer.GetActiveCamera()
    center = plane.GetOrigin()
    camera.SetFocalPoint(center)
    camera.SetPosition([center[d] + normal[d] for d in range(3)])
    camera.SetViewUp([0.0, 0.0, 1.0] if axis != 2 else [0.0, 1.0, 0.0])
    camera.Azimuth(args.azimuth)
    camera.Elevation(args.elevation)
    camera.OrthogonalizeViewUp()
    renderer.ResetCamera()
    camera.Zoom(args.zoom)

    width, height = (int(v) for v in args.size.split("x"))
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(width, height)
    window.AddRenderer(renderer)
    window.Render()
    capture = vtkWindowToImageFilter()
    capture.SetInput(window)
    capture.Update()
    png = vtkPNGWriter()
    png.SetFileName(args.png)
    png.SetInputConnection(capture.GetOutputPort())
    png.Write()
    print("points: %d" % grid.GetNumberOfPoints())
    print("tetrahedra: %d (%d drawn)" % (grid.GetNumberOfCells(), kept))
    print("value range: %g %g" % (low, high))
    print("wrote %s" % args.png)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
