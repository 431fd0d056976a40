#include "roe/core/types.hpp"

#include <algorithm>

namespace roe {

double median_rate_hz(const std::vector<Timestamp>& stamps) {
  if (stamps.size() < 2) return 0.0;
  std::vector<Timestamp> d;
  d.reserve(stamps.size() - 1);
  for (std::size_t i = 1; i < stamps.size(); ++i) d.push_back(stamps[i] - stamps[i - 1]);
  const auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  return *mid > 0 ? 1e9 / static_cast<double>(*mid) : 0.0;
}

}  // namespace roe
