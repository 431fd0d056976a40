#pragma once
/// @file
/// A plain host tensor (float32 or int64, row-major) used at the boundary of the LibTorch pose head
/// and for self-test vectors, so that no header of roe includes LibTorch. Read from NumPy .npy files.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace roe::infer {

struct HostTensor {
  std::vector<std::int64_t> shape;
  bool is_int = false;          ///< int64 data in `i`, else float32 data in `f`
  std::vector<float> f;
  std::vector<std::int64_t> i;

  std::size_t numel() const;
  /// "[1, 3, 24, 32] float32"
  std::string describe() const;
  static HostTensor floats(std::vector<std::int64_t> shape, std::vector<float> data);
  static HostTensor ints(std::vector<std::int64_t> shape, std::vector<std::int64_t> data);
};

/// Reads a NumPy .npy file (format 1.0-3.0, C order, little-endian float32/float64/int32/int64/
/// uint8/bool): floats become float32, integers int64. roe::InputError naming the file otherwise.
HostTensor read_npy(const std::filesystem::path& file);
/// Writes float32 or int64 data as .npy (format 1.0).
void write_npy(const std::filesystem::path& file, const HostTensor& t);

/// max |a − b| over all elements; +inf when the shapes or kinds differ or a value is non-finite.
double max_abs_diff(const HostTensor& a, const HostTensor& b);

}  // namespace roe::infer
