# Warnings and sanitizers per target, never as global flags.
function(cairn_target_options target)
  # -Wno-missing-field-initializers: GCC 12 warns on designated initializers that rely on member
  # defaults ({.res_voxel = 0.05}), which is the style of our config structs.
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                                           -Wno-missing-field-initializers)
  # float-cast-overflow (not part of `undefined`): a NaN or out-of-range double cast to an integer
  # (a voxel index of a NaN point) is undefined behaviour; the kernels must never do it.
  if(CAIRN_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined,float-cast-overflow
                                             -fno-omit-frame-pointer -fno-sanitize-recover=all)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined,float-cast-overflow)
  endif()
endfunction()

# The precompiled headers (CAIRN_PCH): what nearly every file includes. Parsing them was about a
# fifth of a unity batch's compile time. Built once with cairn_core's flags, reused by the other
# C++20 targets (not by the C++17 ROS nodes, nor by the PCL / Open3D peer tests, whose own headers
# come first).
set(CAIRN_PCH_HEADERS <algorithm> <array> <cmath> <cstdint> <filesystem> <fstream> <functional> <limits>
    <map> <memory> <numbers> <optional> <random> <set> <span> <string> <vector> <Eigen/Core>
    <Eigen/Geometry> <Eigen/Eigenvalues> <Eigen/SVD> <nlohmann/json.hpp> <spdlog/spdlog.h>
    <tbb/blocked_range.h> <tbb/parallel_for.h>)
function(cairn_use_pch target)
  if(NOT CAIRN_PCH)
    return()
  endif()
  if(target STREQUAL "cairn_core")
    target_precompile_headers(cairn_core PRIVATE ${CAIRN_PCH_HEADERS})
  else()
    target_precompile_headers(${target} REUSE_FROM cairn_core)
  endif()
endfunction()

# cairn_add_library(name SOURCES ... DEPS ...): one static library per stage folder.
function(cairn_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR}/src)
  target_link_libraries(${name} PUBLIC ${ARG_DEPS})
  cairn_target_options(${name})
  cairn_use_pch(${name})
  if(CAIRN_SANITIZE)
    target_link_options(${name} INTERFACE -fsanitize=address,undefined,float-cast-overflow)
  endif()
endfunction()

# In CI (environment CI set and not "false", as .ci/run runs) a missing optional part (a peer, ROS)
# fails the configuration; on a developer's machine it is a warning. Sets VAR to the message mode.
function(cairn_missing_level var)
  if(DEFINED ENV{CI} AND NOT "$ENV{CI}" STREQUAL "" AND NOT "$ENV{CI}" STREQUAL "false")
    set(${var} FATAL_ERROR PARENT_SCOPE)
  else()
    set(${var} WARNING PARENT_SCOPE)
  endif()
endfunction()
