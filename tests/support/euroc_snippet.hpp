#pragma once
/// @file
/// The real EuRoC V1_02 snippet of ../shared/data (IMU and ground truth), for tests that skip when
/// ../shared is absent.

#include <filesystem>
#include <optional>
#include <vector>

#include "roe/store/dataset.hpp"

namespace roe::test {

struct EurocSnippet {
  std::filesystem::path mav0;
  std::vector<ImuSample> imu;
  std::vector<ImuState> groundtruth;
};

/// The snippet, or nothing when ../shared/data is absent (the caller WARNs and returns).
inline std::optional<EurocSnippet> load_euroc_snippet() {
  const auto mav0 = std::filesystem::path(ROE_SHARED_DATA_DIR) / "euroc_v102_snippet" / "mav0";
  if (!std::filesystem::exists(mav0 / "imu0" / "data.csv")) return std::nullopt;
  return EurocSnippet{mav0, store::read_imu_csv(mav0 / "imu0" / "data.csv"),
                      store::read_groundtruth_csv(mav0 / "state_groundtruth_estimate0" / "data.csv")};
}

}  // namespace roe::test
