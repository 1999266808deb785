# ctest case install_consumer: installs the build tree into a fresh prefix, configures and builds
# tests/install/consumer against it with find_package(voxshadow CONFIG REQUIRED) (same generator, compiler
# and launcher as the build), and checks what the package does to a host's build: find_package prints
# nothing; a translation unit that links voxshadow::voxshadow only compiles with its own flags (no GLM
# configuration macro, no floating-point flag); one that links voxshadow::exact_fp gets the exact flags; the
# core's arithmetic headers refuse a translation unit without them; the scene and CPU tracer headers bring no
# Vulkan header; a host engine's shader (tests/shaders/host_shadows.comp) compiles against the installed GLSL
# include (lighting/shared/shadows.glsl) alone. Then it runs the consumers and the installed CLI.
# Variables: BUILD_DIR, SOURCE_DIR (tests/install/consumer), WORK_DIR, GENERATOR, CXX, CXX_LAUNCHER,
# BUILD_TYPE, GLSLANG (glslangValidator), HOST_SHADER.
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
             include/voxshadow/lighting/shared/shadows.glsl include/voxshadow/lighting/vulkan_shadows.h
             lib/cmake/voxshadow/voxshadowConfig.cmake lib/cmake/voxshadow/voxshadowConfigVersion.cmake)
  if(NOT EXISTS ${prefix}/${file})
    message(FATAL_ERROR "install_consumer: ${prefix}/${file} was not installed")
  endif()
endforeach()
# The host's shader, with the installed headers as its only include root.
run(${GLSLANG} --target-env vulkan1.1 -I${prefix}/include/voxshadow -o ${WORK_DIR}/host_shadows.spv ${HOST_SHADER})

# Configure, keeping the output: find_package(voxshadow) must print nothing when all is found.
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build -G ${GENERATOR}
    -DCMAKE_BUILD_TYPE=${BUILD_TYPE}
    -DCMAKE_CXX_COMPILER=${CXX}
    -DCMAKE_CXX_COMPILER_LAUNCHER=${CXX_LAUNCHER}
    -DCMAKE_EXPORT_COMPILE_COMMANDS=ON
    -DCMAKE_PREFIX_PATH=${prefix}
  RESULT_VARIABLE status OUTPUT_VARIABLE configured ERROR_VARIABLE configured)
message("${configured}")
if(NOT status EQUAL 0)
  message(FATAL_ERROR "install_consumer: configuring the consumer failed (${status})")
endif()
string(REGEX MATCH "voxshadow-find-begin\n(.*)-- voxshadow-find-end" between "${configured}")
set(printed "${CMAKE_MATCH_1}")
if("${between}" STREQUAL "")
  message(FATAL_ERROR "install_consumer: the markers around find_package(voxshadow) were not found")
elseif(NOT "${printed}" STREQUAL "")
  message(FATAL_ERROR "install_consumer: find_package(voxshadow) printed:\n${printed}")
endif()
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)

# Each consumer's compile command, from compile_commands.json.
file(READ ${WORK_DIR}/build/compile_commands.json commands)
string(JSON count LENGTH "${commands}")
math(EXPR last "${count} - 1")
foreach(i RANGE ${last})
  string(JSON file GET "${commands}" ${i} file)
  string(JSON command GET "${commands}" ${i} command)
  get_filename_component(name ${file} NAME)
  set(command_${name} "${command}")
endforeach()
if(NOT DEFINED command_main.cpp OR NOT DEFINED command_core_rays.cpp)
  message(FATAL_ERROR "install_consumer: compile_commands.json lacks main.cpp or core_rays.cpp")
endif()
# Linking voxshadow::voxshadow changes nothing in the consumer's own code.
foreach(flag -ffp-contract -fno-fast-math GLM_FORCE GLM_ENABLE_EXPERIMENTAL VOXSHADOW_EXACT_FP)
  string(FIND "${command_main.cpp}" "${flag}" at)
  if(NOT at EQUAL -1)
    message(FATAL_ERROR "install_consumer: linking voxshadow::voxshadow put ${flag} into the consumer's "
      "compile command: ${command_main.cpp}")
  endif()
endforeach()
# voxshadow::exact_fp hands the exact-arithmetic flags to the translation unit that compiles the core.
foreach(flag -ffp-contract=off -fno-fast-math -DVOXSHADOW_EXACT_FP)
  string(FIND "${command_core_rays.cpp}" "${flag}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "install_consumer: core_rays.cpp compiled without ${flag}: ${command_core_rays.cpp}")
  endif()
endforeach()

# The core's arithmetic refuses a translation unit compiled without those flags, naming the target to link.
set(probe ${WORK_DIR}/probe)
file(MAKE_DIRECTORY ${probe})
file(WRITE ${probe}/core_without_flags.cpp "#include \"compute/shared/camera_rays.h\"\nint main() { return 0; }\n")
execute_process(COMMAND ${CXX} -std=c++20 -I${prefix}/include/voxshadow -fsyntax-only ${probe}/core_without_flags.cpp
  RESULT_VARIABLE status OUTPUT_VARIABLE refusal ERROR_VARIABLE refusal)
string(FIND "${refusal}" "link voxshadow::exact_fp" named)
if(status EQUAL 0 OR named EQUAL -1)
  message(FATAL_ERROR "install_consumer: the core compiled without the exact flags (${status}): ${refusal}")
endif()

# Headers that need only the scene, the CPU tracer or the frame renderer bring no Vulkan header.
file(WRITE ${probe}/no_vulkan.cpp
  "#include \"lighting/scene.h\"\n#include \"compute/cpu/cpu_tracer.h\"\n#include \"lighting/renderer.h\"\n")
execute_process(COMMAND ${CXX} -std=c++20 -I${prefix}/include/voxshadow -E ${probe}/no_vulkan.cpp
  RESULT_VARIABLE status OUTPUT_VARIABLE preprocessed ERROR_VARIABLE errors)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "install_consumer: preprocessing the scene and tracer headers failed: ${errors}")
endif()
string(FIND "${preprocessed}" "vulkan/vulkan" at)
if(NOT at EQUAL -1)
  message(FATAL_ERROR "install_consumer: lighting/scene.h, compute/cpu/cpu_tracer.h or lighting/renderer.h "
    "includes a Vulkan header")
endif()

run(${WORK_DIR}/build/consumer ${WORK_DIR})
run(${WORK_DIR}/build/core_rays)
run(${prefix}/bin/voxshadow --version)
