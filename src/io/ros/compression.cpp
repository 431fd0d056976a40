// zstd helpers (include/roe/io/ros/compression.hpp).
#include "roe/io/ros/compression.hpp"

#include <fmt/format.h>
#include <zstd.h>

#include <algorithm>
#include <fstream>
#include <memory>
#include <vector>

#include "roe/core/error.hpp"

namespace roe::io {
namespace {
struct DctxFree {
  void operator()(ZSTD_DCtx* c) const { ZSTD_freeDCtx(c); }
};
using Dctx = std::unique_ptr<ZSTD_DCtx, DctxFree>;

/// Streams `in` into `out`, growing it up to `cap` bytes; false on error, on more than `cap` bytes,
/// or when the input ends inside a frame.
bool stream_decompress(std::string_view in, std::size_t cap, std::string& out) {
  Dctx ctx(ZSTD_createDCtx());
  if (!ctx) return false;
  out.clear();
  out.resize(std::min<std::size_t>(std::max<std::size_t>(cap, 1), 1u << 16));
  ZSTD_inBuffer ib{in.data(), in.size(), 0};
  std::size_t produced = 0;
  std::size_t last = 1;  // ZSTD_decompressStream's hint: 0 once a frame is complete
  while (ib.pos < ib.size || last != 0) {
    if (produced == out.size()) {
      if (out.size() >= cap) {
        // Full: only acceptable if the frame is complete and no input is left.
        if (last == 0 && ib.pos == ib.size) break;
        char probe;
        ZSTD_outBuffer ob{&probe, 1, 0};
        const std::size_t r = ZSTD_decompressStream(ctx.get(), &ob, &ib);
        if (ZSTD_isError(r) || ob.pos != 0) return false;
        if (r == 0 && ib.pos == ib.size) break;
        if (ib.pos == ib.size) return false;
        last = r;
        continue;
      }
      out.resize(std::min<std::size_t>(cap, 2 * out.size()));
    }
    ZSTD_outBuffer ob{out.data() + produced, out.size() - produced, 0};
    const std::size_t before_in = ib.pos;
    const std::size_t r = ZSTD_decompressStream(ctx.get(), &ob, &ib);
    if (ZSTD_isError(r)) return false;
    produced += ob.pos;
    last = r;
    if (ob.pos == 0 && ib.pos == before_in && r != 0) return false;  // stuck: input ends inside a frame
  }
  out.resize(produced);
  return last == 0;
}
}  // namespace

bool zstd_decompress(std::string_view in, std::size_t expected_size, std::string& out) {
  return stream_decompress(in, expected_size, out) && out.size() == expected_size;
}

bool zstd_decompress_any(std::string_view in, std::size_t max_size, std::string& out) {
  return stream_decompress(in, max_size, out);
}

std::string zstd_compress(std::string_view in, int level) {
  std::string out(ZSTD_compressBound(in.size()), '\0');
  const std::size_t n = ZSTD_compress(out.data(), out.size(), in.data(), in.size(), level);
  if (ZSTD_isError(n)) throw InternalError(std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
  out.resize(n);
  return out;
}

std::uint64_t chunk_decompression_limit(std::uint64_t file_size) {
  return std::min(kMaxChunkLimit, std::max(kMinChunkLimit, file_size > kMaxChunkLimit ? kMaxChunkLimit : 4 * file_size));
}

std::uint64_t file_decompression_limit(std::uint64_t compressed_size) {
  return std::max<std::uint64_t>(kMinFileDecompressionLimit, kFileDecompressionRatio * compressed_size);
}

void zstd_decompress_file(const std::filesystem::path& in, const std::filesystem::path& out, std::uint64_t max_bytes) {
  std::ifstream f(in, std::ios::binary);
  if (!f) throw InputError("cannot open file", {in.string()});
  std::ofstream o(out, std::ios::binary | std::ios::trunc);
  if (!o) throw InputError("cannot write the decompressed copy", {out.string()});
  Dctx ctx(ZSTD_createDCtx());
  std::vector<char> ibuf(ZSTD_DStreamInSize()), obuf(ZSTD_DStreamOutSize());
  std::uint64_t offset = 0, written = 0;
  std::size_t last = 0;
  bool any = false;
  while (f) {
    f.read(ibuf.data(), static_cast<std::streamsize>(ibuf.size()));
    const auto n = static_cast<std::size_t>(f.gcount());
    if (n == 0) break;
    any = true;
    ZSTD_inBuffer ib{ibuf.data(), n, 0};
    while (ib.pos < ib.size) {
      ZSTD_outBuffer ob{obuf.data(), obuf.size(), 0};
      last = ZSTD_decompressStream(ctx.get(), &ob, &ib);
      if (ZSTD_isError(last))
        throw InputError("zstd data is corrupt near compressed byte " + std::to_string(offset + ib.pos) + " (" +
                             ZSTD_getErrorName(last) + ")",
                         {in.string()});
      written += ob.pos;
      if (written > max_bytes)
        throw InputError(fmt::format("decompresses to more than {} bytes (the limit for a zstd-compressed bag file: "
                                     "max(256 MiB, {}× its size); stopped near compressed byte {})",
                                     max_bytes, kFileDecompressionRatio, offset + ib.pos),
                         {in.string()});
      o.write(obuf.data(), static_cast<std::streamsize>(ob.pos));
    }
    offset += n;
  }
  if (!any) throw InputError("empty zstd file", {in.string()});
  if (last != 0)
    throw InputError("zstd data ends inside a frame at compressed byte " + std::to_string(offset) + " (truncated?)",
                     {in.string()});
  o.flush();
  if (!o) throw InputError("cannot write the decompressed copy", {out.string()});
}

}  // namespace roe::io
