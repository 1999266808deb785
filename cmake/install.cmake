# cmake --install: the CLI (bin/voxshadow) and the library as a CMake package,
#   find_package(voxshadow CONFIG REQUIRED)  ->  voxshadow::voxshadow
# with the module libraries (voxshadow::voxel, ::bvh, ::compute, ::lighting, each static, the SPIR-V of the
# shaders embedded in voxshadow::compute), their headers under include/voxshadow/ (sources include them as
# "voxel/...", "compute/shared/..."), and the interface targets voxshadow::options and voxshadow::exact_fp.
include(CMakePackageConfigHelpers)

set(VOXSHADOW_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/voxshadow)

install(TARGETS voxshadow_options voxshadow_exact_fp
                voxshadow_voxel voxshadow_bvh voxshadow_compute voxshadow_lighting voxshadow_library
  EXPORT voxshadowTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/voxshadow)
install(TARGETS voxshadow RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

# The public headers keep their paths relative to the source root. The generated SPIR-V headers are
# included by .cpp files only (compute/vulkan/*.cpp), so they are part of libvoxshadow_compute.a, not of
# the headers.
foreach(module voxel bvh compute lighting)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${module}/
    DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/voxshadow/${module}
    FILES_MATCHING PATTERN "*.h" PATTERN "*.glsl"
    PATTERN "shaders" EXCLUDE)
endforeach()

install(EXPORT voxshadowTargets
  NAMESPACE voxshadow::
  DESTINATION ${VOXSHADOW_CMAKE_DIR})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/voxshadowConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/voxshadowConfig.cmake
  INSTALL_DESTINATION ${VOXSHADOW_CMAKE_DIR})
# 0.x: a minor version may change the API.
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/voxshadowConfigVersion.cmake
  VERSION ${PROJECT_VERSION}
  COMPATIBILITY SameMinorVersion)
install(FILES
  ${CMAKE_CURRENT_BINARY_DIR}/voxshadowConfig.cmake
  ${CMAKE_CURRENT_BINARY_DIR}/voxshadowConfigVersion.cmake
  DESTINATION ${VOXSHADOW_CMAKE_DIR})
