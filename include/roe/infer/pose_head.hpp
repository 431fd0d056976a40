#pragma once
/// @file
/// The PoET pose head: a TorchScript module run through LibTorch. This header does not include
/// LibTorch (only src/infer/pose_head_torch.cpp does); without LibTorch (ROE_WITH_TORCH=OFF or not
/// found) constructing a PoseHead throws roe::InputError saying so.
///
/// Contract (docs/infer.md): forward(boxes float32 [Q,4] normalised cx,cy,w,h with padding rows −1,
/// classes int64 [Q] 1-based with padding −1, then the detector's feature maps float32 [1,C,h,w] in
/// the bundle's order, or the image float32 [1,3,H,W]) → a tuple (t [Q,3], rotation [Q,K]
/// [, logvar_t [Q,3], logvar_r [Q,3]]), or a single tensor for one output.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "roe/infer/tensor.hpp"

namespace roe::infer {

/// How the pose head runs on the CPU (docs/BENCHMARKS.md, "PoET pose head on the CPU").
struct PoseHeadTuning {
  /// Freeze the module and apply TorchScript's inference passes (torch::jit::optimize_for_inference:
  /// constants folded, conv/linear through oneDNN, which does not depend on the system BLAS). CPU only;
  /// if the passes fail the plain module is used.
  bool optimize = true;
  /// LibTorch intra-op threads (process-wide); 0 = one per hardware thread.
  int threads = 0;
  /// glibc malloc keeps freed buffers (up to 32 MB each) in the heap, not trimmed, instead of mapping and
  /// unmapping memory per tensor
  /// (process-wide; PoET-sized model: 2.1 → 0.2 s of kernel time per frame, 0.7 GB more peak RSS).
  bool reuse_memory = true;
};

class PoseHead {
 public:
  /// Loads a TorchScript file. `device`: "auto" (CUDA when LibTorch has it), "cpu" or "cuda".
  explicit PoseHead(const std::filesystem::path& file, const std::string& device = "auto", const PoseHeadTuning& tuning = {});
  ~PoseHead();
  PoseHead(const PoseHead&) = delete;
  PoseHead& operator=(const PoseHead&) = delete;

  /// Runs the module; outputs as float32 host tensors. roe::DataError when the module fails.
  std::vector<HostTensor> forward(const std::vector<HostTensor>& inputs);
  /// "cpu" or "cuda:0".
  std::string device() const;
  /// Whether the inference passes were applied (PoseHeadTuning::optimize on the CPU, and they succeeded).
  bool optimized() const;
  /// LibTorch's intra-op thread count now.
  static int threads();

  /// Whether this roe was built with LibTorch.
  static bool available();
  /// LibTorch's version ("1.13.1"), or "" without LibTorch.
  static std::string runtime_version();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace roe::infer
