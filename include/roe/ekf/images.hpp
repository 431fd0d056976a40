#pragma once
/// @file
/// The measurement stream of a run: detections grouped per image in the IMU clock, and the one rule that
/// picks the anchor (main) object when FilterOptions::anchor_id is −1. I/O-free.

#include <cstddef>
#include <map>
#include <vector>

#include "roe/core/symmetry.hpp"
#include "roe/core/types.hpp"
#include "roe/ekf/options.hpp"

namespace roe::ekf {

/// The detections of one image (time in the IMU clock).
struct ImageDetections {
  Timestamp t_ns = 0;
  std::vector<Detection> detections;
};

/// Detections sorted by time (as the dataset readers return them) grouped per image, each stamp shifted
/// by `offset_ns` into the IMU clock (camera.time_offset_s). Throws DataError when the stamps decrease.
std::vector<ImageDetections> group_images(const std::vector<Detection>& detections, Timestamp offset_ns = 0);

/// Whether a detection can be used at all: a finite score below min_score cannot (rejected_score).
bool usable_detection(const Detection& d, const FilterOptions& options);

/// How the anchor was chosen.
struct AnchorChoice {
  int id = -1;             ///< −1: no image in the IMU span has a usable detection
  bool automatic = false;  ///< chosen by the rule (FilterOptions::anchor_id was −1)
  Timestamp t_ns = 0;      ///< the image the rule looked at (automatic only)
  std::size_t images = 0;  ///< number of images the anchor is detected in (usable detections)
};

/// The anchor rule of `anchor_id = −1`, the only one (Filter::update and run_filter both use it):
/// among the objects of the first image in [t_first_ns, t_last_ns] (the IMU span) with a usable detection,
/// a non-symmetric one when there is one (an object with an entry in `symmetries`, even an empty one =
/// symmetric with its group unknown, is symmetric: relative to a symmetric anchor the other objects' poses
/// are known only up to its symmetry), then the object detected in the most images of `images` (usable
/// detections), then the lowest id. With
/// require_anchor an image without the anchor is not used, so the object seen most often wastes the
/// fewest images (docs/filter.md §4). Given a single image (what Filter::update knows when called
/// without run_filter) every count is 1 and the rule is the lowest id. A configured anchor_id ≥ 0 is
/// returned as it is (automatic false).
AnchorChoice choose_anchor(const std::vector<ImageDetections>& images, Timestamp t_first_ns, Timestamp t_last_ns,
                           const FilterOptions& options, const std::map<int, ObjectSymmetry>& symmetries = {});

}  // namespace roe::ekf
