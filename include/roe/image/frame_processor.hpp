#pragma once
/// @file
/// The image half of importing (OpenCV kept out of this header): raw ROS images in memory →
/// undistorted, centre-cropped, optionally resized → PNG.
///
/// Geometry (paper §IV: "after undistorting the images, they were cropped to 640x480"): the output
/// pixel (u, v) looks up the undistorted full-resolution image (same fx, fy, cx, cy as the source,
/// no distortion) at u_full = x0 + (u + 0.5) s_x − 0.5, with the centred crop origin
/// x0 = (W − crop_w) / 2 (integer) and s_x = crop_w / out_w (likewise for v). That undistorted point
/// is distorted with the source model to find the source pixel (CameraModel::distort), and the
/// source is sampled bilinearly (one cv::remap). The resulting pinhole intrinsics are
/// fx' = fx / s_x, cx' = (cx − x0 + 0.5) / s_x − 0.5 (likewise y), distortion none.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "roe/image/camera_model.hpp"

namespace roe::image {

namespace fs = std::filesystem;

/// A raw image in memory with a ROS encoding ("rgb8", "bgr8", "rgba8", "bgra8", "mono8", "8UC1",
/// "mono16", "16UC1", "yuv422"/"uyvy", "yuv422_yuy2"/"yuyv") or a librealsense format name as
/// recorder bags write it for formats without a ROS equivalent (rs2_format_to_string: "YUYV", "UYVY",
/// "RGB8", "BGR8", "RGBA8", "BGRA8", "Y8", "RAW8", "Y16", "Z16"); see canonical_encoding.
/// `step` is the row stride in bytes.
struct RawImage {
  int width = 0, height = 0;
  std::string encoding;
  std::size_t step = 0;
  std::string_view data;
};

/// An image decoded from a file (tests, tools): 8-bit or 16-bit, 1 or 3 channels (BGR order).
struct DecodedImage {
  int width = 0, height = 0, channels = 0, depth_bytes = 1;
  std::vector<std::uint8_t> data;  ///< row-major, tightly packed
  /// Channel c of pixel (u, v) (8-bit images).
  int at(int u, int v, int c = 0) const { return data[(static_cast<std::size_t>(v) * width + u) * channels + c]; }
};

struct ProcessOptions {
  int crop_width = 640, crop_height = 480;  ///< centred crop of the undistorted image (0 = full size)
  int out_width = 0, out_height = 0;        ///< 0 = the crop size (no resize)
  bool undistort = true;                    ///< false: crop/resize only (the model must then be kept)
  int png_compression = 3;                  ///< 0..9 (cv::IMWRITE_PNG_COMPRESSION)
};

/// Builds the undistort+crop+resize map once for a source camera; processes many frames.
class FrameProcessor {
 public:
  /// InputError when the crop is larger than the source or sizes are not positive.
  FrameProcessor(const CameraModel& source, const ProcessOptions& options);
  ~FrameProcessor();
  FrameProcessor(FrameProcessor&&) noexcept;
  FrameProcessor& operator=(FrameProcessor&&) noexcept;

  const CameraModel& source() const { return source_; }
  /// The camera of the processed images (distortion none unless options.undistort is false).
  const CameraModel& output() const { return output_; }
  int crop_x0() const { return x0_; }
  int crop_y0() const { return y0_; }

  /// Processes a raw frame and writes it as PNG. InputError when the frame does not match the
  /// source size or has an unsupported encoding (`where` names it).
  void process_to_png(const RawImage& frame, const fs::path& png, const std::string& where) const;
  /// The same for an encoded frame (CompressedImage: PNG/JPEG bytes, decoded with cv::imdecode).
  void process_encoded_to_png(std::string_view encoded, const fs::path& png, const std::string& where) const;

 private:
  struct Impl;
  CameraModel source_, output_;
  int x0_ = 0, y0_ = 0;
  ProcessOptions options_;
  std::unique_ptr<Impl> impl_;
};

/// The ROS name of an image encoding: librealsense format names map to the ROS encoding with the same
/// memory layout ("YUYV" → "yuyv", "UYVY" → "uyvy", "RGB8" → "rgb8", "BGR8" → "bgr8", "RGBA8" →
/// "rgba8", "BGRA8" → "bgra8", "Y8"/"RAW8" → "mono8", "Y16"/"Z16" → "mono16"); any other name is
/// returned unchanged (whether it is supported is decided when a frame is converted).
std::string canonical_encoding(const std::string& encoding);

/// Writes a raw image unchanged as PNG (colour converted to OpenCV's BGR order).
void write_png(const RawImage& frame, const fs::path& png, const std::string& where);
/// PNG bytes of a raw image.
std::string encode_png(const RawImage& frame, const std::string& where);
/// Reads a PNG (or any format OpenCV reads) without conversion. InputError when unreadable.
DecodedImage read_image(const fs::path& file);

}  // namespace roe::image
