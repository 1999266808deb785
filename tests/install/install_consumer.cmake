# ctest case install_consumer: installs the build tree into a fresh prefix, configures and builds
# tests/install/consumer against it with find_package(voxshadow CONFIG REQUIRED) (same generator, compiler
# and launcher as the build), checks that the consumer compiled with voxshadow::exact_fp's flags, and runs
# the consumer and the installed CLI.
# Variables: BUILD_DIR, SOURCE_DIR (tests/install/consumer), WORK_DIR, GENERATOR, CXX, CXX_LAUNCHER,
# BUILD_TYPE.
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE status)
  if(NOT status EQUAL 0)
    string(REPLACE ";" " " command "${ARGN}")
    message(FATAL_ERROR "install_consumer: failed (${status}): ${command}")
  endif()
endfunction()

set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(file bin/voxshadow include/voxshadow/compute/shared/traverse.h include/voxshadow/lighting/scene.h
             lib/cmake/voxshadow/voxshadowConfig.cmake lib/cmake/voxshadow/voxshadowConfigVersion.cmake)
  if(NOT EXISTS ${prefix}/${file})
    message(FATAL_ERROR "install_consumer: ${prefix}/${file} was not installed")
  endif()
endforeach()

run(${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build -G ${GENERATOR}
  -DCMAKE_BUILD_TYPE=${BUILD_TYPE}
  -DCMAKE_CXX_COMPILER=${CXX}
  -DCMAKE_CXX_COMPILER_LAUNCHER=${CXX_LAUNCHER}
  -DCMAKE_EXPORT_COMPILE_COMMANDS=ON
  -DCMAKE_PREFIX_PATH=${prefix})
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)

# The installed package hands its consumers the exact-arithmetic flags of the shared trace core.
file(READ ${WORK_DIR}/build/compile_commands.json commands)
foreach(flag -ffp-contract=off -fno-fast-math)
  string(FIND "${commands}" "${flag}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "install_consumer: the consumer compiled without ${flag}")
  endif()
endforeach()

run(${WORK_DIR}/build/consumer ${WORK_DIR})
run(${prefix}/bin/voxshadow --version)
