# Tests of the optional libraries (cmake/features.cmake; issue 38). The test build has OpenCV and Ceres, so
# two stand-ins for a build without them:
#  - roe-without-optional: roe, but with the two CLI files that read roe/features.hpp compiled with
#    ROE_HAVE_OPENCV/CERES/TORCH_BACKEND = 0 (the other CLI objects are roe's own: compiled once).
#    tests/cli/test_features.cpp runs it for the refusals (exit 2, the Debian package, the CMake option)
#    and the "no" lines of --version.
#  - cli/configure-without-opencv-ceres: configures the source with -DROE_WITH_OPENCV=OFF
#    -DROE_WITH_CERES=OFF into a scratch folder (nothing is built) and checks the configure report and
#    that no helper or refine target exists (cmake/check-configure-without.cmake).
# scripts/time-fresh-demo.sh builds the real thing (a bookworm without those packages) and runs the
# refusal checks on it.
if(ROE_TESTS_ON)
  add_executable(roe-without-optional ${ROE_CLI_FEATURE_SRC})
  target_link_libraries(roe-without-optional PRIVATE roe_cli_base roe_cli_commands)
  target_compile_definitions(roe-without-optional PRIVATE ROE_HAVE_OPENCV=0 ROE_HAVE_CERES=0 ROE_HAVE_TORCH_BACKEND=0)
  if(TARGET test_cli)
    add_dependencies(test_cli roe-without-optional)
    # On the one file that uses them, so the other CLI tests' objects do not change with them.
    set_source_files_properties(${CMAKE_SOURCE_DIR}/tests/cli/test_features.cpp PROPERTIES COMPILE_DEFINITIONS
      "ROE_BINARY_WITHOUT_OPTIONAL=\"$<TARGET_FILE:roe-without-optional>\";ROE_BUILT_OPENCV=${ROE_HAVE_OPENCV};ROE_BUILT_CERES=${ROE_HAVE_CERES};ROE_BUILT_TORCH=${ROE_HAVE_TORCH_BACKEND}")
  endif()
  add_test(NAME cli/configure-without-opencv-ceres
           COMMAND ${CMAKE_COMMAND} -DSOURCE=${CMAKE_SOURCE_DIR} -DSCRATCH=${CMAKE_BINARY_DIR}/test-tmp/configure-without
                   -P ${CMAKE_SOURCE_DIR}/cmake/check-configure-without.cmake)
  set_tests_properties(cli/configure-without-opencv-ceres PROPERTIES LABELS cli TIMEOUT 300)
endif()
