#include "roe/infer/tensor.hpp"

#include <cmath>
#include <limits>

#include "roe/core/error.hpp"
#include "roe/io/npy.hpp"
#include "roe/io/output.hpp"

namespace roe::infer {

std::size_t HostTensor::numel() const {
  std::size_t n = 1;
  for (auto d : shape) n *= static_cast<std::size_t>(d);
  return n;
}

std::string HostTensor::describe() const {
  std::string s = "[";
  for (std::size_t k = 0; k < shape.size(); ++k) s += (k ? ", " : "") + std::to_string(shape[k]);
  return s + "] " + (is_int ? "int64" : "float32");
}

HostTensor HostTensor::floats(std::vector<std::int64_t> shape, std::vector<float> data) {
  HostTensor t;
  t.shape = std::move(shape);
  t.f = std::move(data);
  return t;
}

HostTensor HostTensor::ints(std::vector<std::int64_t> shape, std::vector<std::int64_t> data) {
  HostTensor t;
  t.shape = std::move(shape);
  t.is_int = true;
  t.i = std::move(data);
  return t;
}

HostTensor read_npy(const std::filesystem::path& file) {
  const io::NpyArray a = io::parse_npy(io::read_file(file), file.string());
  HostTensor t;
  t.shape = a.shape;
  const std::size_t n = a.numel();
  if (a.is_float()) {
    t.f.resize(n);
    for (std::size_t k = 0; k < n; ++k) t.f[k] = static_cast<float>(a.as_double(k));
  } else {
    t.is_int = true;
    t.i.resize(n);
    for (std::size_t k = 0; k < n; ++k) t.i[k] = a.as_int(k);
  }
  return t;
}

void write_npy(const std::filesystem::path& file, const HostTensor& t) {
  io::NpyArray a;
  a.shape = t.shape;
  a.descr = t.is_int ? "<i8" : "<f4";
  if (t.is_int) a.data.assign(reinterpret_cast<const char*>(t.i.data()), t.i.size() * 8);
  else a.data.assign(reinterpret_cast<const char*>(t.f.data()), t.f.size() * 4);
  io::write_file_atomic(file, io::encode_npy(a));
}

double max_abs_diff(const HostTensor& a, const HostTensor& b) {
  if (a.shape != b.shape || a.is_int != b.is_int) return std::numeric_limits<double>::infinity();
  double m = 0.0;
  const std::size_t n = a.numel();
  for (std::size_t k = 0; k < n; ++k) {
    const double d = a.is_int ? std::abs(static_cast<double>(a.i[k] - b.i[k])) : std::abs(static_cast<double>(a.f[k]) - b.f[k]);
    if (!std::isfinite(d)) return std::numeric_limits<double>::infinity();
    m = std::max(m, d);
  }
  return m;
}

}  // namespace roe::infer
