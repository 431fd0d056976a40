#pragma once
/// @file
/// Detector post-processing with PoET's rules (notes/poet.md §1; Scaled-YOLOv4's NMS, which PoET's
/// YOLO backbone uses):
///  1. candidates: objectness > conf_thresh;
///  2. class confidence = objectness × class probability; multi-label: every class whose confidence
///     > conf_thresh gives a candidate (else only the best class, if > conf_thresh);
///  3. class-aware NMS: greedy by descending score, a box is removed when its IoU with a kept box of
///     the same class exceeds iou_thresh (agnostic NMS compares across classes);
///  4. at most max_detections, sorted by score (ties keep the candidate order);
///  5. class ids shifted by class_offset (PoET: +1, 0 = background).
/// Unlike PoET, which drops the score after the cut, roe keeps it for detections.csv.

#include <cstddef>
#include <vector>

namespace roe::infer {

/// An axis-aligned box in pixels (x1, y1) top-left, (x2, y2) bottom-right.
struct BoxDetection {
  double x1 = 0, y1 = 0, x2 = 0, y2 = 0;
  double score = 0;   ///< objectness × class probability
  int class_id = 0;   ///< after class_offset
};

struct NmsOptions {
  double conf_thresh = 0.4;
  double iou_thresh = 0.5;
  std::size_t max_detections = 300;
  bool multi_label = true;
  bool class_aware = true;
  int class_offset = 1;
};

/// IoU of two boxes (0 when either has no area).
double box_iou(const BoxDetection& a, const BoxDetection& b);

/// One YOLO row as OpenCV's Darknet region layer writes it: cx, cy, w, h (normalised to the network
/// input), objectness, then per class objectness × class probability.
/// Steps 1-2 on `rows` (n x (5 + classes), row-major float) → candidates in pixels of a
/// width x height image, in row order.
std::vector<BoxDetection> yolo_candidates(const float* rows, std::size_t n, std::size_t cols, int width, int height,
                                          const NmsOptions& opt);

/// Steps 3-5 on candidates (class_id still 0-based): the kept boxes, best first.
std::vector<BoxDetection> nms(std::vector<BoxDetection> candidates, const NmsOptions& opt);

}  // namespace roe::infer
