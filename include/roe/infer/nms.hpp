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

#include <array>
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

/// One [yolo] head of a Darknet cfg: its anchors in pixels (the cfg's `anchors` picked by `mask`,
/// in mask order) and its number of classes.
struct YoloHead {
  std::vector<std::array<float, 2>> anchors;
  int classes = 0;
};

/// Decodes the raw output of the convolution that feeds a [yolo] layer (float32 [A·(5 + C), ny, nx],
/// row-major) the way PoET's detector does: the YOLOLayer of aau-cns/yolov4 in inference (the
/// Scaled-YOLOv4 rule). Every channel goes through the logistic function σ, then
///   cx = (2σ(tx) − 0.5 + column)·stride,  cy = (2σ(ty) − 0.5 + row)·stride,
///   w = (2σ(tw))²·anchor_w,  h = (2σ(th))²·anchor_h,  objectness σ(to),
///   class confidence σ(tc)·σ(to) (Scaled-YOLOv4's non_max_suppression multiplies them),
/// whatever the cfg's scale_x_y or new_coords say (that code ignores them; OpenCV's Region layer
/// follows them, with Darknet's exp() rule, and gives other boxes). Rows come in PyTorch's order
/// (anchor, row, column), computed in float32 as PyTorch does: cx, cy, w, h in pixels, objectness,
/// then the C class confidences, the input of yolo_candidates with width = height = 1.
/// Returns an empty vector when A·(5 + C) rows do not fit (the caller checks the shape).
std::vector<float> decode_yolo_head(const float* raw, const YoloHead& head, int ny, int nx, float stride);

/// Steps 1-2 on `rows` (n x (5 + classes), row-major float: cx, cy, w, h, objectness, then per class
/// objectness × class probability) → candidates, in row order. The box columns are multiplied by
/// width and height: 1 for pixel rows (decode_yolo_head), the image size for normalised ones.
std::vector<BoxDetection> yolo_candidates(const float* rows, std::size_t n, std::size_t cols, int width, int height,
                                          const NmsOptions& opt);

/// Steps 3-5 on candidates (class_id still 0-based): the kept boxes, best first.
std::vector<BoxDetection> nms(std::vector<BoxDetection> candidates, const NmsOptions& opt);

}  // namespace roe::infer
