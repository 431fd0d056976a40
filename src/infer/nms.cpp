#include "roe/infer/nms.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace roe::infer {

double box_iou(const BoxDetection& a, const BoxDetection& b) {
  const double aw = a.x2 - a.x1, ah = a.y2 - a.y1, bw = b.x2 - b.x1, bh = b.y2 - b.y1;
  if (!(aw > 0 && ah > 0 && bw > 0 && bh > 0)) return 0.0;
  const double iw = std::min(a.x2, b.x2) - std::max(a.x1, b.x1);
  const double ih = std::min(a.y2, b.y2) - std::max(a.y1, b.y1);
  if (iw <= 0 || ih <= 0) return 0.0;
  const double inter = iw * ih;
  return inter / (aw * ah + bw * bh - inter);
}

std::vector<float> decode_yolo_head(const float* raw, const YoloHead& head, int ny, int nx, float stride) {
  const std::size_t A = head.anchors.size();
  const std::size_t no = 5 + static_cast<std::size_t>(std::max(head.classes, 0));
  std::vector<float> rows;
  if (A == 0 || ny <= 0 || nx <= 0 || head.classes <= 0) return rows;
  const std::size_t plane = static_cast<std::size_t>(ny) * static_cast<std::size_t>(nx);
  rows.resize(A * plane * no);
  const auto sigmoid = [](float v) { return 1.0f / (1.0f + std::exp(-v)); };
  std::size_t r = 0;
  for (std::size_t a = 0; a < A; ++a) {
    // PyTorch: anchor_wh = anchors / stride, then w = (2σ)² · anchor_wh · stride.
    const float aw = head.anchors[a][0] / stride, ah = head.anchors[a][1] / stride;
    const float* base = raw + a * no * plane;
    for (int y = 0; y < ny; ++y) {
      for (int x = 0; x < nx; ++x, ++r) {
        const std::size_t at = static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(x);
        float* row = rows.data() + r * no;
        for (std::size_t c = 0; c < no; ++c) row[c] = sigmoid(base[c * plane + at]);
        row[0] = (row[0] * 2.0f - 0.5f + static_cast<float>(x)) * stride;
        row[1] = (row[1] * 2.0f - 0.5f + static_cast<float>(y)) * stride;
        const float tw = row[2] * 2.0f, th = row[3] * 2.0f;
        row[2] = tw * tw * aw * stride;
        row[3] = th * th * ah * stride;
        for (std::size_t c = 5; c < no; ++c) row[c] *= row[4];
      }
    }
  }
  return rows;
}

std::vector<BoxDetection> yolo_candidates(const float* rows, std::size_t n, std::size_t cols, int width, int height,
                                          const NmsOptions& opt) {
  std::vector<BoxDetection> out;
  if (cols < 6) return out;
  const std::size_t classes = cols - 5;
  // Compared in float32, as PyTorch compares a float32 tensor with a Python float threshold.
  const float conf = static_cast<float>(opt.conf_thresh);
  for (std::size_t r = 0; r < n; ++r) {
    const float* row = rows + r * cols;
    if (!(row[4] > conf)) continue;  // objectness (NaN never passes)
    BoxDetection b;
    const double cx = row[0] * width, cy = row[1] * height, w = row[2] * width, h = row[3] * height;
    b.x1 = cx - w / 2;
    b.y1 = cy - h / 2;
    b.x2 = cx + w / 2;
    b.y2 = cy + h / 2;
    if (opt.multi_label) {
      for (std::size_t c = 0; c < classes; ++c) {
        if (row[5 + c] > conf) {
          b.score = row[5 + c];
          b.class_id = static_cast<int>(c);
          out.push_back(b);
        }
      }
    } else {
      std::size_t best = 0;
      for (std::size_t c = 1; c < classes; ++c)
        if (row[5 + c] > row[5 + best]) best = c;
      if (row[5 + best] > conf) {
        b.score = row[5 + best];
        b.class_id = static_cast<int>(best);
        out.push_back(b);
      }
    }
  }
  return out;
}

std::vector<BoxDetection> nms(std::vector<BoxDetection> candidates, const NmsOptions& opt) {
  std::vector<std::size_t> order(candidates.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return candidates[a].score > candidates[b].score; });
  std::vector<BoxDetection> kept;
  for (std::size_t idx : order) {
    const BoxDetection& c = candidates[idx];
    bool suppressed = false;
    for (const auto& k : kept) {
      if (opt.class_aware && k.class_id != c.class_id) continue;
      if (box_iou(k, c) > opt.iou_thresh) {
        suppressed = true;
        break;
      }
    }
    if (suppressed) continue;
    kept.push_back(c);
    if (kept.size() >= opt.max_detections) break;
  }
  for (auto& k : kept) k.class_id += opt.class_offset;
  return kept;
}

}  // namespace roe::infer
