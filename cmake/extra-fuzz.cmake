# Fuzzing (docs/TESTING.md, "Fuzzing"): one libFuzzer target per reader, every tests/fuzz/fuzz_*.cpp
# (a new file is picked up by the glob, no edit here). Built only in a separate clang configuration
# with ROE_FUZZ=ON, where every library is compiled with ASan + UBSan and libFuzzer's coverage:
#   make fuzz                  (= scripts/fuzz.sh build: build-fuzz/, clang, RelWithDebInfo)
#   scripts/fuzz.sh run 600    (each target 600 s on its seed corpus)
# In the ordinary build, CTest's fuzz/smoke runs scripts/fuzz.sh smoke (each target a few seconds);
# it is skipped when clang or libFuzzer is missing.
option(ROE_FUZZ "Build the libFuzzer targets (clang only; instruments every library)" OFF)

if(ROE_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "ROE_FUZZ needs clang (CXX=clang++): libFuzzer is clang's")
  endif()
  # The readers and what they stand on, instrumented: coverage for libFuzzer, ASan, UBSan (any UB aborts).
  set(_san -fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer)
  foreach(_lib roe_core roe_math roe_io roe_io_ros roe_store roe_app)
    target_compile_options(${_lib} PRIVATE -fsanitize=fuzzer-no-link ${_san})
  endforeach()
  file(GLOB ROE_FUZZ_SOURCES CONFIGURE_DEPENDS ${CMAKE_SOURCE_DIR}/tests/fuzz/fuzz_*.cpp)
  add_custom_target(fuzz_all)
  foreach(_f ${ROE_FUZZ_SOURCES})
    get_filename_component(_n ${_f} NAME_WE)
    add_executable(${_n} ${_f})
    target_include_directories(${_n} PRIVATE ${CMAKE_SOURCE_DIR}/tests/fuzz)
    # The sweep's files are read by the app layer (plan_sweep, read_sweep): that target links it.
    if(_n MATCHES "^fuzz_sweep")
      target_link_libraries(${_n} PRIVATE roe_app)
    else()
      target_link_libraries(${_n} PRIVATE roe_io roe_io_ros roe_store)
    endif()
    target_compile_options(${_n} PRIVATE -fsanitize=fuzzer ${_san})
    target_link_options(${_n} PRIVATE -fsanitize=fuzzer ${_san})
    add_dependencies(fuzz_all ${_n})
  endforeach()
  message(STATUS "roe: libFuzzer targets enabled (fuzz_all)")
elseif(ROE_TESTS_ON)
  add_test(NAME fuzz/smoke COMMAND ${CMAKE_SOURCE_DIR}/scripts/fuzz.sh smoke)
  set_tests_properties(fuzz/smoke PROPERTIES SKIP_RETURN_CODE 77 LABELS fuzz TIMEOUT 1500 RUN_SERIAL TRUE)
endif()
