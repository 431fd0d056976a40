# roe import extras (owner: import helper).
#
# (The fuzz targets, fuzz_rosbag among them, are built by cmake/extra-fuzz.cmake: `make fuzz`.)
# gen_d435i_bag: the committed fixture generator as a command-line tool (tests/fixtures).
add_executable(gen_d435i_bag EXCLUDE_FROM_ALL ${CMAKE_SOURCE_DIR}/tests/fixtures/gen_d435i_bag.cpp)
target_include_directories(gen_d435i_bag PRIVATE ${CMAKE_SOURCE_DIR}/tests)
target_link_libraries(gen_d435i_bag PRIVATE roe_io_ros)
