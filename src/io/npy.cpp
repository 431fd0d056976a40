#include "roe/io/npy.hpp"

#include <cstring>
#include <limits>
#include <regex>

#include "roe/core/error.hpp"

namespace roe::io {
namespace {

template <typename T>
T load(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

}  // namespace

std::size_t NpyArray::numel() const {
  std::size_t n = 1;
  for (auto d : shape) n *= static_cast<std::size_t>(d);
  return n;
}

std::size_t NpyArray::element_size(const std::string& descr) {
  if (descr == "<f4" || descr == "<i4") return 4;
  if (descr == "<f8" || descr == "<i8") return 8;
  if (descr == "|u1" || descr == "|b1" || descr == "|i1") return 1;
  return 0;
}

double NpyArray::as_double(std::size_t k) const {
  if (descr == "<f8") return load<double>(data.data() + 8 * k);
  if (descr == "<f4") return load<float>(data.data() + 4 * k);
  return static_cast<double>(as_int(k));
}

std::int64_t NpyArray::as_int(std::size_t k) const {
  if (descr == "<i8") return load<std::int64_t>(data.data() + 8 * k);
  if (descr == "<i4") return load<std::int32_t>(data.data() + 4 * k);
  if (descr == "|i1") return static_cast<signed char>(data[k]);
  if (descr == "|u1" || descr == "|b1") return static_cast<unsigned char>(data[k]);
  throw InternalError("NpyArray::as_int on a " + descr + " array");
}

NpyArray NpyArray::float64(std::vector<std::int64_t> shape, const std::vector<double>& values) {
  NpyArray a;
  a.shape = std::move(shape);
  a.descr = "<f8";
  ROE_CHECK(a.numel() == values.size(), "npy: the values do not fill the shape");
  a.data.assign(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(double));
  return a;
}

NpyArray parse_npy(const std::string& bytes, const std::string& src) {
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
  if (header_len > bytes.size() - offset) throw InputError("truncated .npy header", {src});
  const std::string header = bytes.substr(offset, header_len);
  std::smatch m;
  if (!std::regex_search(header, m, std::regex("'descr'\\s*:\\s*'([^']*)'"))) throw InputError(".npy header without descr", {src});
  NpyArray a;
  a.descr = m[1];
  if (std::regex_search(header, m, std::regex("'fortran_order'\\s*:\\s*True")))
    throw InputError(".npy in Fortran order is not supported", {src});
  if (!std::regex_search(header, m, std::regex("'shape'\\s*:\\s*\\(([^)]*)\\)"))) throw InputError(".npy header without shape", {src});
  const std::string dims = m[1];
  static const std::regex kDigits("[0-9]+");
  std::size_t n = 1;
  for (std::sregex_iterator it(dims.begin(), dims.end(), kDigits), end; it != end; ++it) {
    if (it->str().size() > 15) throw InputError(".npy shape too large: (" + dims + ")", {src});
    const auto d = std::stoll(it->str());
    if (d != 0 && n > std::numeric_limits<std::size_t>::max() / 8 / static_cast<std::size_t>(d))
      throw InputError(".npy shape too large: (" + dims + ")", {src});
    n *= static_cast<std::size_t>(d);
    a.shape.push_back(d);
  }
  const std::size_t elem = NpyArray::element_size(a.descr);
  if (elem == 0) throw InputError("unsupported .npy dtype '" + a.descr + "' (float32/64, int8/32/64, uint8, bool)", {src});
  const std::size_t avail = bytes.size() - offset - header_len;
  if (avail < n * elem)
    throw InputError("truncated .npy data (" + std::to_string(avail) + " bytes for " + std::to_string(n) + " elements)", {src});
  a.data = bytes.substr(offset + header_len, n * elem);
  return a;
}

std::string encode_npy(const NpyArray& a) {
  ROE_CHECK(NpyArray::element_size(a.descr) != 0, "npy: unsupported dtype " + a.descr);
  ROE_CHECK(a.data.size() == a.numel() * NpyArray::element_size(a.descr), "npy: data size does not match the shape");
  std::string shape;
  for (std::size_t k = 0; k < a.shape.size(); ++k)
    shape += std::to_string(a.shape[k]) + (a.shape.size() == 1 ? "," : (k + 1 < a.shape.size() ? ", " : ""));
  std::string header = "{'descr': '" + a.descr + "', 'fortran_order': False, 'shape': (" + shape + "), }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::string out = "\x93NUMPY";
  out += '\x01';
  out += '\x00';
  out += static_cast<char>(header.size() & 0xFF);
  out += static_cast<char>((header.size() >> 8) & 0xFF);
  out += header;
  out += a.data;
  return out;
}

}  // namespace roe::io
