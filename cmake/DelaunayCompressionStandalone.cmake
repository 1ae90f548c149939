# Standalone build: the module's targets with plain CMake against an installed ITK.
include(GNUInstallDirs)
include(GenerateExportHeader)
include(CMakePackageConfigHelpers)

if(NOT CMAKE_BUILD_TYPE AND NOT CMAKE_CONFIGURATION_TYPES)
  set(CMAKE_BUILD_TYPE Release CACHE STRING "Build type" FORCE)
endif()
set(CMAKE_CXX_STANDARD 17)
set(CMAKE_CXX_STANDARD_REQUIRED ON)
option(BUILD_SHARED_LIBS "Build the module library shared" ON)
option(BUILD_TESTING "Build the tests" ON)
option(DelaunayCompression_BUILD_BENCHMARKS "Build the benchmark programs" ON)

# What the library needs (as itk-module.cmake's DEPENDS), and the IO modules with which the CLI
# and the tests read NRRD, NIfTI, MetaImage and DICOM.
set(DelaunayCompression_ITK_COMPONENTS ITKCommon ITKMesh ITKIOImageBase ITKIOMeshBase ITKImageFeature)
set(DelaunayCompression_ITK_IO_COMPONENTS ITKIONRRD ITKIONIFTI ITKIOMeta ITKIOGDCM ITKIOMeshVTK)
find_package(ITK 5.2 REQUIRED COMPONENTS ${DelaunayCompression_ITK_COMPONENTS} ${DelaunayCompression_ITK_IO_COMPONENTS}
  ITKTestKernel)
# GDCM is not linked into the programs nor registered at their start: they load it when they meet DICOM
# (tools/common/dcvGDCM.h). The tests, which call it directly, link all of ITK_LIBRARIES; the programs
# neither ITKIOGDCM nor ITKTestKernel, which links it (and which a linker without --as-needed keeps).
list(REMOVE_ITEM ITK_ImageIO GDCM)
include(${ITK_USE_FILE})
set(DelaunayCompression_PROGRAM_LIBRARIES ${ITK_LIBRARIES})
list(REMOVE_ITEM DelaunayCompression_PROGRAM_LIBRARIES ITKIOGDCM ITKTestKernel)

# Installed programs find the module's library relative to themselves, whatever the prefix.
file(RELATIVE_PATH _dcv_bin_to_lib "/${CMAKE_INSTALL_BINDIR}" "/${CMAKE_INSTALL_LIBDIR}")
set(CMAKE_INSTALL_RPATH "$ORIGIN/${_dcv_bin_to_lib}")
set(CMAKE_INSTALL_RPATH_USE_LINK_PATH ON)

add_subdirectory(src)
add_subdirectory(tools)
add_subdirectory(slicer) # the 3D Slicer CLI modules
if(BUILD_TESTING)
  enable_testing()
  add_subdirectory(test)
endif()
if(DelaunayCompression_BUILD_BENCHMARKS)
  add_subdirectory(benchmark)
endif()

# A CMake package, so that other projects can find_package(DelaunayCompression).
install(DIRECTORY include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/DelaunayCompression PATTERN "*.in" EXCLUDE)
install(FILES ${PROJECT_BINARY_DIR}/include/DelaunayCompressionExport.h ${PROJECT_BINARY_DIR}/include/dcvVersion.h
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/DelaunayCompression)
install(EXPORT DelaunayCompressionTargets NAMESPACE DelaunayCompression::
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/DelaunayCompression)
configure_package_config_file(cmake/DelaunayCompressionConfig.cmake.in
  ${PROJECT_BINARY_DIR}/DelaunayCompressionConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/DelaunayCompression)
# find_package(DelaunayCompression 0.2) accepts any 0.2.x: before 1.0 a minor version may change the API.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/DelaunayCompressionConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/DelaunayCompressionConfig.cmake
              ${PROJECT_BINARY_DIR}/DelaunayCompressionConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/DelaunayCompression)
