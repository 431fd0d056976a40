#include "roe/ekf/images.hpp"

#include <fmt/format.h>

#include <cmath>
#include <tuple>

#include "roe/core/error.hpp"

namespace roe::ekf {

std::vector<ImageDetections> group_images(const std::vector<Detection>& detections, Timestamp offset_ns) {
  std::vector<ImageDetections> images;
  for (std::size_t i = 0; i < detections.size(); ++i) {
    const Detection& d = detections[i];
    const Timestamp t = d.t_ns + offset_ns;
    if (!images.empty() && t < images.back().t_ns)
      throw DataError(fmt::format("detections not sorted by time: detection {} at {} ns follows one at {} ns", i,
                                  d.t_ns, images.back().t_ns - offset_ns));
    if (images.empty() || images.back().t_ns != t) images.push_back({t, {}});
    images.back().detections.push_back(d);
    images.back().detections.back().t_ns = t;
  }
  return images;
}

bool usable_detection(const Detection& d, const FilterOptions& options) {
  return !(std::isfinite(d.score) && d.score < options.min_score);
}

AnchorChoice choose_anchor(const std::vector<ImageDetections>& images, Timestamp t_first_ns, Timestamp t_last_ns,
                           const FilterOptions& options, const std::map<int, ObjectSymmetry>& symmetries) {
  AnchorChoice c;
  std::map<int, std::size_t> seen;
  for (const auto& im : images)
    for (const auto& d : im.detections)
      if (usable_detection(d, options)) ++seen[d.object_id];
  if (options.anchor_id >= 0) {
    c.id = options.anchor_id;
    c.images = seen[c.id];
    return c;
  }
  c.automatic = true;
  for (const auto& im : images) {
    if (im.t_ns < t_first_ns || im.t_ns > t_last_ns) continue;
    for (const auto& d : im.detections) {
      if (!usable_detection(d, options)) continue;
      // Ranked by (non-symmetric, images, −id).
      const auto rank = [&](int id) { return std::make_tuple(symmetries.count(id) == 0, seen[id], -id); };
      if (c.id < 0 || rank(d.object_id) > rank(c.id)) c.id = d.object_id;
    }
    if (c.id >= 0) {
      c.t_ns = im.t_ns;
      c.images = seen[c.id];
      return c;
    }
  }
  return c;
}

}  // namespace roe::ekf
