# What the DelaunayCompression library target needs beyond its sources, the same in the standalone
# build and in a build inside ITK (included by src/CMakeLists.txt once the target exists).
# _dcv_private: the link keyword the target's other target_link_libraries calls use.

# Interpolated values must be the same doubles in the encoder and in any decoder: no fused
# multiply-add contraction of the shared rasterizer arithmetic.
target_compile_options(DelaunayCompression PUBLIC $<$<CXX_COMPILER_ID:GNU,Clang>:-ffp-contract=off>)
find_package(CGAL REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(ZLIB REQUIRED) # crc32 of the .dcv files
find_package(Threads REQUIRED)
find_package(TBB REQUIRED) # the encoder's threads
# The residual layer's JPEG 2000 (libopenjp2-7-dev; its CMake files carry no version, pkg-config does).
find_package(PkgConfig REQUIRED)
pkg_check_modules(OpenJPEG REQUIRED IMPORTED_TARGET libopenjp2>=2.5)
# The video layer's HEVC: x265 encodes (libx265-dev, GPL-2+), libde265 decodes (libde265-dev, LGPL-3+).
pkg_check_modules(X265 REQUIRED IMPORTED_TARGET x265>=3.5)
pkg_check_modules(LIBDE265 REQUIRED IMPORTED_TARGET libde265>=1.0.11)
# ... and its AV1: libaom encodes (libaom-dev, BSD-2-Clause), dav1d decodes (libdav1d-dev, BSD-2-Clause).
pkg_check_modules(AOM REQUIRED IMPORTED_TARGET aom>=3.6)
pkg_check_modules(DAV1D REQUIRED IMPORTED_TARGET dav1d>=1.0)
target_link_libraries(DelaunayCompression ${_dcv_private} CGAL::CGAL Eigen3::Eigen ZLIB::ZLIB Threads::Threads
  TBB::tbb TBB::tbbmalloc PkgConfig::OpenJPEG PkgConfig::X265 PkgConfig::LIBDE265
  PkgConfig::AOM PkgConfig::DAV1D)
# CGAL's concurrent triangulation (the decoder's, dcvTetrahedralize.cxx) is compiled with TBB; defined for
# every source, so that CGAL's classes are the same in each.
target_compile_definitions(DelaunayCompression PRIVATE CGAL_LINKED_WITH_TBB)
# The library's private headers, by concern (src/CMakeLists.txt).
target_include_directories(DelaunayCompression PRIVATE
  ${PROJECT_SOURCE_DIR}/src/core ${PROJECT_SOURCE_DIR}/src/mesh ${PROJECT_SOURCE_DIR}/src/layer)

# The .dcv image and mesh IO as an ITK plugin: a directory holding it, in ITK_AUTOLOAD_PATH, lets any
# ITK program read and write .dcv files without linking the module.
add_library(DelaunayCompressionPlugin MODULE ${PROJECT_SOURCE_DIR}/src/itk/itkDCVPlugin.cxx)
target_link_libraries(DelaunayCompressionPlugin ${_dcv_private} DelaunayCompression)
set_target_properties(DelaunayCompressionPlugin PROPERTIES LIBRARY_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/plugin)
