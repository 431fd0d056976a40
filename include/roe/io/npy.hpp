#pragma once
/// @file
/// NumPy's .npy format (format versions 1.0 to 3.0, C order, little-endian), kept as the raw element bytes
/// with NumPy's type string, so that every reader (the PoET bundle's self-test tensors, evo's result
/// files) converts from one definition and nothing is rounded on the way.

#include <cstdint>
#include <string>
#include <vector>

namespace roe::io {

struct NpyArray {
  std::vector<std::int64_t> shape;
  std::string descr;  ///< NumPy's type string: "<f8", "<f4", "<i8", "<i4", "|i1", "|u1" or "|b1"
  std::string data;   ///< numel() elements, little-endian, C order

  std::size_t numel() const;
  /// Bytes per element of `descr` (0 for a type roe does not read).
  static std::size_t element_size(const std::string& descr);
  bool is_float() const { return descr.size() == 3 && descr[1] == 'f'; }
  /// Element k as a double (floats exactly; integers beyond 2^53 rounded).
  double as_double(std::size_t k) const;
  /// Element k of an integer array (a float array: InternalError).
  std::int64_t as_int(std::size_t k) const;

  static NpyArray float64(std::vector<std::int64_t> shape, const std::vector<double>& values);
};

/// Parses .npy bytes; InputError naming `source` (and what is wrong) for anything else, a dtype roe does
/// not read, Fortran order, a shape whose size overflows or data shorter than the shape.
NpyArray parse_npy(const std::string& bytes, const std::string& source);
/// The .npy bytes (format 1.0, header padded to 64 bytes as NumPy writes it).
std::string encode_npy(const NpyArray& a);

}  // namespace roe::io
