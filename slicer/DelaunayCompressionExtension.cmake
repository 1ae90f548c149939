# The 3D Slicer extension's description: what the Slicer Extensions Index asks of an extension (in a
# Slicer extension build these EXTENSION_* variables precede find_package(Slicer)), and what the module
# descriptions (<category>, <contributor>, <documentation-url>, <license>) take from it. The index entry
# itself is DelaunayCompression.json beside this file.
set(EXTENSION_NAME DelaunayCompression)
set(DelaunayCompression_HOMEPAGE "https://github.com/InsightSoftwareConsortium/ITKDelaunayCompression" CACHE STRING
  "Home page of the project (the Slicer extension's EXTENSION_HOMEPAGE; the raw file URLs derive from it)")
set(DelaunayCompression_RAW_URL "https://raw.githubusercontent.com/InsightSoftwareConsortium/ITKDelaunayCompression/main"
  CACHE STRING "Base URL of the project's files as served raw (the extension's icon and screenshot)")
set(EXTENSION_HOMEPAGE "${DelaunayCompression_HOMEPAGE}#for-3d-slicer-users")
set(EXTENSION_CATEGORY "Converters")
set(EXTENSION_CONTRIBUTORS "DelaunayCompression contributors (NumFOCUS / ITK remote module)")
set(EXTENSION_DESCRIPTION "Lossy compression of 3D volumes into .dcv files: significant grid points and a linear spline over their adaptive Delaunay tetrahedralization (Jovanovic and Lorentz), optionally with a JPEG 2000 residual layer, at a bit rate or a PSNR target. Modules: DCV Compress, DCV Decompress, and DCV Approximate, which shows the decoded volume and its absolute error before a rate is chosen.")
set(EXTENSION_ICONURL "${DelaunayCompression_RAW_URL}/slicer/Resources/DelaunayCompression.png")
set(EXTENSION_SCREENSHOTURLS "${DelaunayCompression_RAW_URL}/slicer/Resources/Screenshot-DCVApproximate.png")
set(EXTENSION_LICENSE "Apache-2.0 (sources); binaries link CGAL, GPL-3.0-or-later (see NOTICE)")
set(EXTENSION_DEPENDS "NA") # no other extension
set(EXTENSION_BUILD_SUBDIRECTORY ".")

# What the module descriptions show.
set(DCV_SLICER_CATEGORY "Converters.Compression")
set(DCV_SLICER_CONTRIBUTOR "${EXTENSION_CONTRIBUTORS}; method: R. Jovanovic and R. A. Lorentz")
set(DCV_SLICER_LICENSE "${EXTENSION_LICENSE}")
set(DCV_SLICER_DOCUMENTATION_URL "${EXTENSION_HOMEPAGE}")
