#pragma once
/// @file
/// Where the tests find the checkout, its roe binary and ../shared/data. Force-included into every test
/// object (CMakeLists.txt, roe_test_main), with ROE_SOURCE_DIR, ROE_SHARED_DATA_DIR and ROE_BINARY defined as
/// calls of these functions; only tests/support/test_paths.cpp holds the paths themselves. So every other test
/// object is the same in every checkout and ccache shares it between them (issue 53: with the paths as
/// string macros each checkout compiled all ~125 test files again).

namespace roe::test::paths {
const char* source_dir();       ///< the checkout (CMAKE_SOURCE_DIR)
const char* shared_data_dir();  ///< ../shared/data beside it (may be absent: tests skip)
const char* roe_binary();       ///< the build's roe executable
}  // namespace roe::test::paths
