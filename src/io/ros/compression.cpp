// The decompressors of the bag readers: zstd, LZ4 frames, bzip2 (include/roe/io/ros/compression.hpp).
#include "roe/io/ros/compression.hpp"

#include <bzlib.h>
#include <fmt/format.h>
#include <lz4frame.h>
#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <limits>
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

// ---------------------------------------------------------------------------------------------
// LZ4 frames and bzip2 (ROS 1 chunks; LZ4 also MCAP chunks)
// ---------------------------------------------------------------------------------------------
bool lz4_decompress(std::string_view in, std::size_t expected_size, std::string& out) {
  // The output grows with what the decoder actually produces (doubling up to expected_size), so a
  // corrupt size field on a tiny chunk costs nothing: no up-front zero-filled allocation.
  out.clear();
  out.resize(std::min<std::size_t>(expected_size, 1u << 16));
  LZ4F_dctx* ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) return false;
  std::size_t in_pos = 0, out_pos = 0;
  bool ok = true;
  while (true) {
    if (out_pos == out.size() && out.size() < expected_size)
      out.resize(std::min<std::size_t>(expected_size, 2 * out.size()));
    std::size_t src_size = in.size() - in_pos;
    std::size_t dst_size = out.size() - out_pos;
    const std::size_t r = LZ4F_decompress(ctx, out.data() + out_pos, &dst_size, in.data() + in_pos,
                                          &src_size, nullptr);
    if (LZ4F_isError(r)) {
      ok = false;
      break;
    }
    in_pos += src_size;
    out_pos += dst_size;
    if (r == 0) break;  // frame complete
    if (src_size == 0 && dst_size == 0 && (in_pos == in.size() || out_pos == expected_size)) {
      ok = false;  // input exhausted before the end of the frame, or more output than announced
      break;
    }
  }
  LZ4F_freeDecompressionContext(ctx);
  return ok && out_pos == expected_size;
}

std::string lz4_compress(std::string_view in) {
  LZ4F_preferences_t prefs;
  std::memset(&prefs, 0, sizeof prefs);
  prefs.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
  std::string out(LZ4F_compressFrameBound(in.size(), &prefs), '\0');
  const std::size_t n = LZ4F_compressFrame(out.data(), out.size(), in.data(), in.size(), &prefs);
  if (LZ4F_isError(n)) throw InternalError(std::string("LZ4 compression failed: ") + LZ4F_getErrorName(n));
  out.resize(n);
  return out;
}

bool bz2_decompress(std::string_view in, std::size_t expected_size, std::string& out) {
  // Streaming, with the output grown as it is produced (see lz4_decompress).
  if (in.size() > std::numeric_limits<unsigned>::max()) return false;
  out.clear();
  out.resize(std::min<std::size_t>(expected_size, 1u << 16));
  bz_stream s;
  std::memset(&s, 0, sizeof s);
  if (BZ2_bzDecompressInit(&s, 0, 0) != BZ_OK) return false;
  s.next_in = const_cast<char*>(in.data());  // libbz2 takes non-const pointers but does not write
  s.avail_in = static_cast<unsigned>(in.size());
  std::size_t out_pos = 0;
  bool ok = false;
  while (true) {
    if (out_pos == out.size() && out.size() < expected_size)
      out.resize(std::min<std::size_t>(expected_size, 2 * out.size()));
    const std::size_t room = std::min<std::size_t>(out.size() - out_pos, std::numeric_limits<unsigned>::max());
    s.next_out = out.data() + out_pos;
    s.avail_out = static_cast<unsigned>(room);
    const int r = BZ2_bzDecompress(&s);
    out_pos += room - s.avail_out;
    if (r == BZ_STREAM_END) {
      ok = out_pos == expected_size;
      break;
    }
    if (r != BZ_OK) break;
    if (room - s.avail_out == 0 && (s.avail_in == 0 || out_pos == expected_size)) break;  // stuck
  }
  BZ2_bzDecompressEnd(&s);
  return ok;
}

std::string bz2_compress(std::string_view in) {
  unsigned len = static_cast<unsigned>(in.size() + in.size() / 100 + 600);
  std::string out(len, '\0');
  const int r = BZ2_bzBuffToBuffCompress(out.data(), &len, const_cast<char*>(in.data()),
                                         static_cast<unsigned>(in.size()), 9, 0, 30);
  if (r != BZ_OK) throw InternalError("bz2 compression failed");
  out.resize(len);
  return out;
}

}  // namespace roe::io
