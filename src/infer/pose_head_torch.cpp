// The only translation unit of roe that includes LibTorch (its headers compile slowly).
#include "roe/infer/pose_head.hpp"

#include "roe/core/error.hpp"

#ifdef ROE_HAVE_TORCH
#include <algorithm>
#include <thread>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <ATen/Parallel.h>
#include <torch/cuda.h>
#include <torch/script.h>
#include <torch/version.h>
#endif

namespace roe::infer {

#ifdef ROE_HAVE_TORCH

struct PoseHead::Impl {
  torch::jit::script::Module module;
  torch::Device device = torch::kCPU;
  bool optimized = false;
};

namespace {
void keep_freed_memory() {
#ifdef __GLIBC__
  // Large tensors are otherwise mmap'ed and unmapped at every layer: page faults and zeroing in the
  // kernel on each run. Fixed thresholds keep them in the heap for reuse.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest allowed value on 64-bit
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

void set_threads(int wanted) {
  const int n = wanted > 0 ? wanted : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (at::get_num_threads() != n) at::set_num_threads(n);
}
}  // namespace

PoseHead::PoseHead(const std::filesystem::path& file, const std::string& device, const PoseHeadTuning& tuning)
    : impl_(std::make_unique<Impl>()) {
  if (device == "cuda" || (device == "auto" && torch::cuda::is_available())) {
    if (!torch::cuda::is_available())
      throw InputError("--device cuda: this LibTorch has no CUDA device (Debian's libtorch is CPU-only; build roe "
                       "with a CUDA LibTorch via -DTorch_DIR=...)");
    impl_->device = torch::Device(torch::kCUDA, 0);
  } else if (device != "cpu" && device != "auto") {
    throw InputError("unknown device \"" + device + "\" (expected auto, cpu or cuda)");
  }
  try {
    impl_->module = torch::jit::load(file.string(), impl_->device);
    impl_->module.eval();
  } catch (const c10::Error& e) {
    std::string msg = e.what_without_backtrace();
    // A file that is not a readable zip archive is damaged (or not TorchScript at all); anything else
    // that fails to load is most often TorchScript from a newer torch.
    const bool not_archive = msg.find("PytorchStreamReader") != std::string::npos ||
                             msg.find("zip archive") != std::string::npos ||
                             msg.find("file not found") != std::string::npos;
    throw InputError(std::string("cannot load the TorchScript pose head (") +
                         (not_archive ? "not a readable TorchScript archive: damaged, truncated or another kind of file?"
                                      : "exported with a newer torch than LibTorch " + runtime_version() + "?") +
                         "): " + msg.substr(0, 400),
                     {file.string()});
  }
  if (impl_->device.is_cpu()) {
    set_threads(tuning.threads);
    if (tuning.reuse_memory) keep_freed_memory();
    if (tuning.optimize) {
      try {  // freezes (weights become constants) and runs the inference passes
        impl_->module = torch::jit::optimize_for_inference(impl_->module);
        impl_->optimized = true;
      } catch (const c10::Error&) {
        impl_->optimized = false;  // a module the passes cannot handle runs as it is
      }
    }
  }
}

PoseHead::~PoseHead() = default;

std::vector<HostTensor> PoseHead::forward(const std::vector<HostTensor>& inputs) {
  c10::InferenceMode guard;
  std::vector<torch::jit::IValue> args;
  args.reserve(inputs.size());
  for (const auto& t : inputs) {
    // from_blob does not copy; the data outlives the call. const_cast: the module does not write.
    auto tensor = t.is_int ? torch::from_blob(const_cast<std::int64_t*>(t.i.data()), t.shape, torch::kInt64)
                           : torch::from_blob(const_cast<float*>(t.f.data()), t.shape, torch::kFloat32);
    args.emplace_back(impl_->device.is_cpu() ? tensor : tensor.to(impl_->device));
  }
  torch::jit::IValue out;
  try {
    out = impl_->module.forward(args);
  } catch (const c10::Error& e) {
    std::string msg = e.what_without_backtrace();
    throw DataError("the pose head failed: " + msg.substr(0, 600));
  }
  std::vector<torch::Tensor> tensors;
  if (out.isTuple()) {
    for (const auto& v : out.toTuple()->elements()) {
      if (!v.isTensor()) throw DataError("the pose head returned a tuple element that is not a tensor");
      tensors.push_back(v.toTensor());
    }
  } else if (out.isTensorList()) {
    for (const auto& v : out.toTensorList()) tensors.push_back(v);
  } else if (out.isTensor()) {
    tensors.push_back(out.toTensor());
  } else {
    throw DataError("the pose head returned neither a tensor nor a tuple of tensors");
  }
  std::vector<HostTensor> result;
  for (auto& t : tensors) {
    auto c = t.to(torch::kCPU, torch::kFloat32).contiguous();
    HostTensor h;
    h.shape.assign(c.sizes().begin(), c.sizes().end());
    h.f.assign(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
    result.push_back(std::move(h));
  }
  return result;
}

std::string PoseHead::device() const { return impl_->device.str(); }
bool PoseHead::optimized() const { return impl_->optimized; }
int PoseHead::threads() { return at::get_num_threads(); }
bool PoseHead::available() { return true; }
std::string PoseHead::runtime_version() { return TORCH_VERSION; }

#else  // no LibTorch

struct PoseHead::Impl {};

PoseHead::PoseHead(const std::filesystem::path& file, const std::string&, const PoseHeadTuning&) {
  throw InputError("this roe was built without LibTorch, so it cannot run PoET pose heads; rebuild with "
                   "libtorch-dev installed (cmake -DROE_WITH_TORCH=ON), or run PoET's own inference and use "
                   "`roe import poet`",
                   {file.string()});
}
PoseHead::~PoseHead() = default;
std::vector<HostTensor> PoseHead::forward(const std::vector<HostTensor>&) {
  throw InternalError("PoseHead without LibTorch");
}
std::string PoseHead::device() const { return "none"; }
bool PoseHead::optimized() const { return false; }
int PoseHead::threads() { return 0; }
bool PoseHead::available() { return false; }
std::string PoseHead::runtime_version() { return ""; }

#endif

}  // namespace roe::infer
