// The one test object compiled with the checkout's paths (tests/support/test_paths.hpp).
#include "support/test_paths.hpp"

namespace roe::test::paths {
const char* source_dir() { return ROE_PATH_SOURCE_DIR; }
const char* shared_data_dir() { return ROE_PATH_SHARED_DATA_DIR; }
const char* roe_binary() { return ROE_PATH_BINARY; }
}  // namespace roe::test::paths
