# The description is the first paragraph of the README.
get_filename_component(MY_CURRENT_DIR "${CMAKE_CURRENT_LIST_FILE}" PATH)
file(READ "${MY_CURRENT_DIR}/README.md" DOCUMENTATION)
string(REGEX MATCH "\n\n[^#\n][^\n]*" DOCUMENTATION "${DOCUMENTATION}")
string(STRIP "${DOCUMENTATION}" DOCUMENTATION)

itk_module(DelaunayCompression
  ENABLE_SHARED
  DEPENDS
    ITKCommon
    ITKMesh
    ITKIOImageBase
    ITKImageFeature
    ITKIOMeshBase
  TEST_DEPENDS
    ITKTestKernel
    ITKGoogleTest
    ITKIONRRD
    ITKIONIFTI
    ITKIOMeta
    ITKIOGDCM
    ITKIOMeshVTK
  FACTORY_NAMES
    ImageIO::DCV
    MeshIO::DCV
  EXCLUDE_FROM_DEFAULT
  DESCRIPTION
    "${DOCUMENTATION}"
)
