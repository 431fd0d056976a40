# CTest cli/configure-without-opencv-ceres (cmake/extra-features.cmake): configures SOURCE into SCRATCH as
# `make demo` does on a machine without OpenCV and Ceres (here by -DROE_WITH_*=OFF), builds nothing, and
# checks what the configure step reports and generates. Then two refused configurations.
#   cmake -DSOURCE=DIR -DSCRATCH=DIR -P cmake/check-configure-without.cmake
if(NOT SOURCE OR NOT SCRATCH)
  message(FATAL_ERROR "usage: cmake -DSOURCE=DIR -DSCRATCH=DIR -P check-configure-without.cmake")
endif()

function(roe_configure dir out_var rc_var)
  file(REMOVE_RECURSE "${dir}")
  execute_process(COMMAND ${CMAKE_COMMAND} -S "${SOURCE}" -B "${dir}" -G "Unix Makefiles"
                          -DCMAKE_BUILD_TYPE=Release ${ARGN}
                  OUTPUT_VARIABLE _out ERROR_VARIABLE _err RESULT_VARIABLE _rc)
  set(${out_var} "${_out}${_err}" PARENT_SCOPE)
  set(${rc_var} "${_rc}" PARENT_SCOPE)
endfunction()

function(roe_expect text what)
  string(FIND "${text}" "${what}" _at)
  if(_at EQUAL -1)
    message(FATAL_ERROR "expected \"${what}\" in:\n${text}")
  endif()
endfunction()

function(roe_expect_not text what)
  string(FIND "${text}" "${what}" _at)
  if(NOT _at EQUAL -1)
    message(FATAL_ERROR "did not expect \"${what}\" in:\n${text}")
  endif()
endfunction()

# 1. Without OpenCV and Ceres: configures, says so, and has no target that needs them.
set(_dir "${SCRATCH}/off")
roe_configure("${_dir}" _out _rc -DROE_WITH_OPENCV=OFF -DROE_WITH_CERES=OFF)
if(NOT _rc EQUAL 0)
  message(FATAL_ERROR "configure without OpenCV and Ceres failed (${_rc}):\n${_out}")
endif()
roe_expect("${_out}" "roe: OpenCV (roe import realsense, roe infer): OFF (ROE_WITH_OPENCV=OFF)")
roe_expect("${_out}" "roe: Ceres (roe refine): OFF (ROE_WITH_CERES=OFF)")
roe_expect("${_out}" "roe: tests not configured: they need")
roe_expect("${_out}" "libopencv-dev libceres-dev")
roe_expect("${_out}" "roe: benchmarks not configured: they need OpenCV (libopencv-dev)")
file(READ "${_dir}/generated/roe/features.hpp" _features)
roe_expect("${_features}" "#define ROE_HAVE_OPENCV 0")
roe_expect("${_features}" "#define ROE_HAVE_CERES 0")
roe_expect("${_features}" "#define ROE_HAVE_TORCH_BACKEND 0")
execute_process(COMMAND ${CMAKE_COMMAND} --build "${_dir}" --target help OUTPUT_VARIABLE _targets RESULT_VARIABLE _rc)
if(NOT _rc EQUAL 0)
  message(FATAL_ERROR "cannot list the targets of ${_dir}")
endif()
roe_expect("${_targets}" "... roe\n")
foreach(_t roe-image roe-infer roe-refine roe_image roe_infer roe_refine roe_app_refine roe_app_all test_cli bench_filter fuzz_replay)
  roe_expect_not("${_targets}" "... ${_t}\n")
endforeach()

# 2. Refused: a value that is none of AUTO, ON, OFF; LibTorch without OpenCV.
roe_configure("${SCRATCH}/bad" _out _rc -DROE_WITH_CERES=maybe)
if(_rc EQUAL 0)
  message(FATAL_ERROR "-DROE_WITH_CERES=maybe was accepted")
endif()
roe_expect("${_out}" "ROE_WITH_CERES=maybe: expected AUTO, ON or OFF")
roe_configure("${SCRATCH}/torch" _out _rc -DROE_WITH_OPENCV=OFF -DROE_WITH_TORCH=ON)
if(_rc EQUAL 0)
  message(FATAL_ERROR "-DROE_WITH_OPENCV=OFF -DROE_WITH_TORCH=ON was accepted")
endif()
roe_expect("${_out}" "ROE_WITH_TORCH=ON needs OpenCV too")

file(REMOVE_RECURSE "${SCRATCH}")
message(STATUS "configure without OpenCV and Ceres: as expected")
