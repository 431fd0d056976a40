#pragma once
// The filter with FilterOptions' plain defaults, causal, for tests about the filter's mechanics and
// consistency (not about roe run's recommended defaults).
#include "roe/app/run.hpp"

namespace roe::test {

/// FilterOptions' plain defaults (the dataset's IMU noise, isotropic σ, the anchor rule), causal (no
/// smoother): what the consistency and mechanics tests are about. `roe run`'s built-in defaults
/// (app::recommended_filter_options, the RTS smoother) are deliberately conservative for robustness
/// (IMU noise × 4; docs/filter.md §12), so their NEES lies below the matched bounds.
inline app::RunConfig plain_config() {
  app::RunConfig c;
  c.filter = ekf::FilterOptions{};
  c.estimator = store::Estimator::kFilter;
  return c;
}

}  // namespace roe::test
