# ctest case example_host_engine: installs the build tree into a fresh prefix, builds the example host engine
# (tools/examples) against it as a separate project would, and runs it: its own instance and device, voxshadow's
# frames on them, its own shader over voxshadow's shadows through the installed GLSL include. The program exits
# non-zero unless its image equals the library's own bit for bit with the validation layer on and silent; the PNG
# must exist.
# Variables: BUILD_DIR, SOURCE_DIR (tools/examples), WORK_DIR, GENERATOR, CXX, CXX_LAUNCHER, BUILD_TYPE.
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE status)
  if(NOT status EQUAL 0)
    string(REPLACE ";" " " command "${ARGN}")
    message(FATAL_ERROR "example_host_engine: failed (${status}): ${command}")
  endif()
endfunction()

set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
run(${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build -G ${GENERATOR}
    -DCMAKE_BUILD_TYPE=${BUILD_TYPE}
    -DCMAKE_CXX_COMPILER=${CXX}
    -DCMAKE_CXX_COMPILER_LAUNCHER=${CXX_LAUNCHER}
    -DCMAKE_PREFIX_PATH=${prefix})
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run(${WORK_DIR}/build/host_engine ${WORK_DIR}/host_engine.png --frames 3 --size 320x180 --require-validation)
if(NOT EXISTS ${WORK_DIR}/host_engine.png)
  message(FATAL_ERROR "example_host_engine: host_engine.png was not written")
endif()
