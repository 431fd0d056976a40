#pragma once
/// @file
/// A loaded PoET model (bundle + OpenCV Darknet detector + LibTorch pose head) and the per-frame
/// pipeline of `roe infer`:
///   decode image → optional virtual-camera warp to the training intrinsics → detector → NMS with
///   PoET's rules (score kept) → top num_queries boxes → pose head → T_C_O per detection.
///
/// Virtual-camera warp: PoET learns its training camera's intrinsics (aau-cns/poet issue #8), so a
/// frame from another pinhole camera is resampled with the homography H = K_train · K_cam⁻¹ into the
/// training image size. H changes only the intrinsics (same optical centre and axes), so the
/// predicted T_C_O is valid in the real camera frame. Pixels outside the source image are black.
/// This is roe's own, documented approximation; it does not recreate lens effects or the blur of
/// a different sensor.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "roe/core/types.hpp"
#include "roe/infer/bundle.hpp"
#include "roe/infer/pose_head.hpp"
#include "roe/infer/nms.hpp"
#include "roe/infer/tensor.hpp"

namespace roe::infer {

struct ModelOptions {
  std::string warp = "auto";   ///< auto (warp when the camera differs), on, off
  std::string device = "auto"; ///< LibTorch device: auto, cpu, cuda
  bool selftest = true;        ///< check the bundle's self-test vectors on load
  PoseHeadTuning tuning;       ///< CPU inference passes and threads of the pose head
};

/// One detection of a frame: PoET class, pose, detector score and box (dataset image pixels).
struct PoseDetection {
  int class_id = 0;
  Pose T_C_O;
  double score = std::numeric_limits<double>::quiet_NaN();
  std::array<double, 4> box{0, 0, 0, 0};  ///< x1, y1, x2, y2 in the dataset image
  std::optional<Vector6d> sigma;          ///< from aleatoric heads: tx,ty,tz (m), rx,ry,rz (rad)
};

struct FrameTimings {
  double decode_ms = 0, warp_ms = 0, detector_ms = 0, pose_ms = 0, total_ms = 0;
};

struct FrameResult {
  std::vector<PoseDetection> detections;  ///< in detector-score order
  std::size_t boxes_after_nms = 0;        ///< before the cut to num_queries
  std::size_t dropped_invalid = 0;        ///< degenerate rotation or non-finite t
  FrameTimings timings;
};

/// Self-test results against the bundle's reference outputs.
struct SelfTestReport {
  /// Per checked detector layer: max |out − ref| / max(1, max |ref|) (feature maps reach 1e4).
  std::vector<std::pair<std::string, double>> detector;
  /// Per pose-head output: max |out − ref| (metres, rotation values).
  std::vector<std::pair<std::string, double>> pose;
  double detector_atol = 0, pose_atol = 0;
  nlohmann::json to_json() const;
};

class PoetModel {
 public:
  /// Loads the detector and the pose head; runs the self-test unless disabled (roe::InputError when
  /// a reference output is not reproduced within its tolerance).
  PoetModel(PoetBundle bundle, ModelOptions options = {});
  ~PoetModel();
  PoetModel(const PoetModel&) = delete;
  PoetModel& operator=(const PoetModel&) = delete;

  const PoetBundle& bundle() const;
  const SelfTestReport& selftest_report() const;
  /// Runs the self-test again and returns its report (no tolerance check).
  SelfTestReport run_selftest();

  /// Sets the dataset camera (the processed image's size and intrinsics, when known) and decides
  /// the warp. roe::InputError when the image size differs from the bundle's and no warp is
  /// possible (warp off or unknown intrinsics).
  void set_camera(int width, int height, const std::optional<Intrinsics>& K);
  bool warping() const;
  /// The pose head's LibTorch device ("cpu", "cuda:0").
  std::string device() const;
  /// Whether the pose head runs with TorchScript's inference passes (PoseHeadTuning::optimize).
  bool pose_head_optimized() const;
  /// The warp decision and homography, for meta.json and the config hash.
  nlohmann::json camera_json() const;

  /// One frame from the encoded image bytes (PNG/JPEG). `external_boxes` (dataset image pixels,
  /// 1-based classes, best first) replace the detector when given. roe::InputError when the image
  /// cannot be decoded or has the wrong size.
  FrameResult infer(const std::string& encoded_image, const std::vector<BoxDetection>* external_boxes = nullptr,
                    const std::string& source = "");

  /// The pose head on explicit inputs (tests, benchmark).
  std::vector<HostTensor> run_pose_head(const std::vector<HostTensor>& inputs);
  /// The detector on a normalised NCHW blob: NMS'd boxes (network pixels) and the tapped features.
  std::pair<std::vector<BoxDetection>, std::vector<HostTensor>> run_detector(const HostTensor& blob);
  /// The normalised NCHW network input of an encoded image already at the training size.
  HostTensor preprocess(const std::string& encoded_image, const std::string& source = "");
  /// Pose-head outputs → detections (boxes in network pixels, best first; first n valid rows).
  std::vector<PoseDetection> decode_outputs(const std::vector<HostTensor>& outputs, const std::vector<BoxDetection>& boxes,
                                            std::size_t* dropped = nullptr) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Number of float32 parameters a Darknet weights file holds for `cfg_text`, counted the way
/// OpenCV's Darknet importer reads them: per [convolutional] layer biases (+ BN scales, means,
/// variances when batch_normalize=1) and filters x in_channels/groups x size², per [connected]
/// layer the same with inputs x outputs. Channels are followed through [route], [reorg], ... as
/// OpenCV does. std::nullopt when the cfg holds something OpenCV's importer would refuse (OpenCV
/// then gives its own error).
std::optional<std::uint64_t> darknet_parameter_count(const std::string& cfg_text);

/// The [yolo] heads of a Darknet cfg, in cfg order (= the order of OpenCV's Region layers):
/// anchors picked by `mask`, classes. roe::InputError naming `source` on a malformed section.
std::vector<YoloHead> darknet_yolo_heads(const std::string& cfg_text, const std::string& source);

/// roe::InputError naming `weights` when its size differs from the header (16 or 20 bytes, by the
/// file's version numbers) + 4 bytes per parameter of `cfg` (see darknet_parameter_count): OpenCV
/// reads a truncated file without complaint (leaving weights undefined) and ignores extra bytes.
void check_darknet_weights(const fs::path& cfg, const fs::path& weights);

/// The pose head's query inputs for boxes in network pixels (best first): a [Q, 4] float tensor of
/// normalised cx, cy, w, h and a [Q] int tensor of class ids; rows beyond the boxes are −1 (PoET's
/// padding), boxes beyond Q are dropped.
std::vector<HostTensor> pose_queries(const std::vector<BoxDetection>& boxes, std::size_t num_queries, int width,
                                     int height);

}  // namespace roe::infer
