#include "roe/infer/tensor.hpp"

#include <cmath>
#include <cstring>
#include <limits>
#include <regex>

#include "roe/core/error.hpp"
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

namespace {
template <typename T>
T load(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}
}  // namespace

HostTensor read_npy(const std::filesystem::path& file) {
  const std::string bytes = io::read_file(file);
  const std::string src = file.string();
  if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) throw InputError("not a NumPy .npy file", {src});
  const int major = static_cast<unsigned char>(bytes[6]);
  std::size_t header_len = 0, offset = 0;
  if (major == 1) {
    header_len = static_cast<unsigned char>(bytes[8]) | (static_cast<std::size_t>(static_cast<unsigned char>(bytes[9])) << 8);
    offset = 10;
  } else if (major == 2 || major == 3) {
    if (bytes.size() < 12) throw InputError("truncated .npy header", {src});
    header_len = load<std::uint32_t>(bytes.data() + 8);
    offset = 12;
  } else {
    throw InputError("unsupported .npy format version " + std::to_string(major), {src});
  }
  if (offset + header_len > bytes.size()) throw InputError("truncated .npy header", {src});
  const std::string header = bytes.substr(offset, header_len);
  std::smatch m;
  if (!std::regex_search(header, m, std::regex("'descr'\\s*:\\s*'([^']*)'"))) throw InputError(".npy header without descr", {src});
  const std::string descr = m[1];
  if (std::regex_search(header, m, std::regex("'fortran_order'\\s*:\\s*True")))
    throw InputError(".npy in Fortran order is not supported", {src});
  if (!std::regex_search(header, m, std::regex("'shape'\\s*:\\s*\\(([^)]*)\\)"))) throw InputError(".npy header without shape", {src});
  HostTensor t;
  const std::string dims = m[1];
  static const std::regex kDigits("[0-9]+");
  std::sregex_iterator it(dims.begin(), dims.end(), kDigits), end;
  for (; it != end; ++it) t.shape.push_back(std::stoll(it->str()));
  const std::size_t n = t.numel();
  const char* data = bytes.data() + offset + header_len;
  const std::size_t avail = bytes.size() - offset - header_len;
  std::size_t elem = 0;
  if (descr == "<f4" || descr == "<i4") elem = 4;
  else if (descr == "<f8" || descr == "<i8") elem = 8;
  else if (descr == "|u1" || descr == "|b1" || descr == "|i1") elem = 1;
  else throw InputError("unsupported .npy dtype '" + descr + "' (float32/64, int8/32/64, uint8, bool)", {src});
  if (avail < n * elem) throw InputError("truncated .npy data (" + std::to_string(avail) + " bytes for " + std::to_string(n) + " elements)", {src});
  if (descr[1] == 'f') {
    t.f.resize(n);
    for (std::size_t k = 0; k < n; ++k)
      t.f[k] = elem == 4 ? load<float>(data + 4 * k) : static_cast<float>(load<double>(data + 8 * k));
  } else {
    t.is_int = true;
    t.i.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      if (elem == 8) t.i[k] = load<std::int64_t>(data + 8 * k);
      else if (elem == 4) t.i[k] = load<std::int32_t>(data + 4 * k);
      else if (descr == "|i1") t.i[k] = static_cast<signed char>(data[k]);
      else t.i[k] = static_cast<unsigned char>(data[k]);
    }
  }
  return t;
}

void write_npy(const std::filesystem::path& file, const HostTensor& t) {
  std::string shape;
  for (std::size_t k = 0; k < t.shape.size(); ++k) shape += std::to_string(t.shape[k]) + (t.shape.size() == 1 ? "," : (k + 1 < t.shape.size() ? ", " : ""));
  std::string header = std::string("{'descr': '") + (t.is_int ? "<i8" : "<f4") + "', 'fortran_order': False, 'shape': (" + shape + "), }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::string out = "\x93NUMPY";
  out += '\x01';
  out += '\x00';
  out += static_cast<char>(header.size() & 0xFF);
  out += static_cast<char>((header.size() >> 8) & 0xFF);
  out += header;
  if (t.is_int) out.append(reinterpret_cast<const char*>(t.i.data()), t.i.size() * 8);
  else out.append(reinterpret_cast<const char*>(t.f.data()), t.f.size() * 4);
  io::write_file_atomic(file, out);
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
