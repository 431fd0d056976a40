# roe import extras (owner: import helper).
#
# 1. fuzz_rosbag: a libFuzzer target for the ROS bag reader and message decoders, built only when the
#    compiler is clang and accepts -fsanitize=fuzzer. Configure a separate clang build to get it:
#      CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DROE_WITH_TORCH=OFF
#      cmake --build build-fuzz --target fuzz_rosbag
#      build-fuzz/fuzz_rosbag -max_total_time=600 -jobs=1 build-fuzz/fuzz_corpus tests/data/bags
#    (docs/import.md, "Fuzzing").
# 2. gen_d435i_bag: the committed fixture generator as a command-line tool (tests/fixtures).
include(CheckCXXSourceCompiles)

if(CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  set(CMAKE_REQUIRED_FLAGS "-fsanitize=fuzzer")
  check_cxx_source_compiles(
    "#include <cstdint>\n#include <cstddef>\nextern \"C\" int LLVMFuzzerTestOneInput(const uint8_t*, size_t) { return 0; }"
    ROE_HAVE_LIBFUZZER)
  unset(CMAKE_REQUIRED_FLAGS)
  if(ROE_HAVE_LIBFUZZER)
    add_executable(fuzz_rosbag
      ${CMAKE_SOURCE_DIR}/tests/fuzz/fuzz_rosbag.cpp
      ${CMAKE_SOURCE_DIR}/src/io/rosbag.cpp
      ${CMAKE_SOURCE_DIR}/src/io/ros_msgs.cpp
      ${CMAKE_SOURCE_DIR}/src/core/error.cpp
      ${CMAKE_SOURCE_DIR}/src/core/log.cpp)
    target_include_directories(fuzz_rosbag PRIVATE ${CMAKE_SOURCE_DIR}/include ${CMAKE_BINARY_DIR}/generated)
    target_compile_options(fuzz_rosbag PRIVATE -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined)
    target_link_options(fuzz_rosbag PRIVATE -fsanitize=fuzzer,address,undefined)
    target_link_libraries(fuzz_rosbag PRIVATE Eigen3::Eigen fmt::fmt PkgConfig::LZ4 BZip2::BZip2)
    message(STATUS "roe: libFuzzer target fuzz_rosbag enabled")
  endif()
endif()

add_executable(gen_d435i_bag EXCLUDE_FROM_ALL ${CMAKE_SOURCE_DIR}/tests/fixtures/gen_d435i_bag.cpp)
target_include_directories(gen_d435i_bag PRIVATE ${CMAKE_SOURCE_DIR}/tests)
target_link_libraries(gen_d435i_bag PRIVATE roe_io)
