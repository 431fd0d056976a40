#include "roe/image/frame_processor.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "roe/core/error.hpp"
#include "roe/io/output.hpp"

namespace roe::image {

std::string canonical_encoding(const std::string& e) {
  // rs2_format_to_string names (librealsense src/types.cpp), written by the recorder when its
  // rs2 format → ROS encoding table has no entry (YUYV on current SDKs) or by older SDKs.
  static const std::pair<const char*, const char*> kRs2[] = {
      {"YUYV", "yuyv"},   {"UYVY", "uyvy"},   {"RGB8", "rgb8"}, {"BGR8", "bgr8"}, {"RGBA8", "rgba8"},
      {"BGRA8", "bgra8"}, {"Y8", "mono8"},    {"RAW8", "mono8"}, {"Y16", "mono16"}, {"Z16", "mono16"}};
  for (const auto& [rs, ros] : kRs2)
    if (e == rs) return ros;
  return e;
}

namespace {

/// Wraps a raw frame as a cv::Mat (no copy) and converts it to what PNG stores (BGR / gray / 16-bit).
cv::Mat to_png_layout(const RawImage& f, const std::string& where) {
  if (f.width <= 0 || f.height <= 0) throw InputError(where + ": image has no pixels");
  int type = 0, bytes_pp = 0;
  const std::string e = canonical_encoding(f.encoding);
  if (e == "rgb8" || e == "bgr8") type = CV_8UC3, bytes_pp = 3;
  else if (e == "rgba8" || e == "bgra8") type = CV_8UC4, bytes_pp = 4;
  else if (e == "mono8" || e == "8UC1") type = CV_8UC1, bytes_pp = 1;
  else if (e == "mono16" || e == "16UC1") type = CV_16UC1, bytes_pp = 2;
  else if (e == "yuv422" || e == "uyvy" || e == "yuv422_yuy2" || e == "yuyv") type = CV_8UC2, bytes_pp = 2;
  else
    throw InputError(where + ": unsupported image encoding \"" + f.encoding +
                     "\" (supported: rgb8 bgr8 rgba8 bgra8 mono8 8UC1 mono16 16UC1 yuv422/uyvy yuyv, and the "
                     "librealsense names YUYV UYVY RGB8 BGR8 RGBA8 BGRA8 Y8 RAW8 Y16 Z16)");
  const std::size_t row = static_cast<std::size_t>(f.width) * bytes_pp;
  if (f.step < row || f.data.size() < f.step * static_cast<std::size_t>(f.height - 1) + row)
    throw InputError(where + ": image data too short for " + std::to_string(f.width) + "x" +
                     std::to_string(f.height) + " " + f.encoding);
  cv::Mat m(f.height, f.width, type, const_cast<char*>(f.data.data()), f.step);
  cv::Mat out;
  if (e == "rgb8") cv::cvtColor(m, out, cv::COLOR_RGB2BGR);
  else if (e == "rgba8") cv::cvtColor(m, out, cv::COLOR_RGBA2BGR);
  else if (e == "bgra8") cv::cvtColor(m, out, cv::COLOR_BGRA2BGR);
  else if (e == "yuv422" || e == "uyvy") cv::cvtColor(m, out, cv::COLOR_YUV2BGR_UYVY);
  else if (e == "yuv422_yuy2" || e == "yuyv") cv::cvtColor(m, out, cv::COLOR_YUV2BGR_YUY2);
  else out = m.clone();
  return out;
}

void write_mat_png(const cv::Mat& m, const fs::path& png, int compression) {
  std::vector<uchar> buf;
  if (!cv::imencode(".png", m, buf, {cv::IMWRITE_PNG_COMPRESSION, compression}))
    throw InputError("PNG encoding failed", {png.string()});
  io::write_file_atomic(png, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()));
}

}  // namespace

struct FrameProcessor::Impl {
  cv::Mat map_x, map_y;  // CV_32FC1; empty when the frame is only cropped (no remap needed)
  bool identity_crop = false;
};

FrameProcessor::FrameProcessor(const CameraModel& source, const ProcessOptions& options)
    : source_(source), options_(options), impl_(std::make_unique<Impl>()) {
  if (source.width <= 0 || source.height <= 0 || !(source.fx > 0) || !(source.fy > 0))
    throw InputError("camera model needs a positive size and focal lengths");
  const int cw = options.crop_width > 0 ? options.crop_width : source.width;
  const int ch = options.crop_height > 0 ? options.crop_height : source.height;
  if (cw > source.width || ch > source.height)
    throw InputError("crop " + std::to_string(cw) + "x" + std::to_string(ch) + " is larger than the image " +
                     std::to_string(source.width) + "x" + std::to_string(source.height));
  const int ow = options.out_width > 0 ? options.out_width : cw;
  const int oh = options.out_height > 0 ? options.out_height : ch;
  x0_ = (source.width - cw) / 2;
  y0_ = (source.height - ch) / 2;
  const double sx = static_cast<double>(cw) / ow, sy = static_cast<double>(ch) / oh;
  output_ = source;
  output_.width = ow;
  output_.height = oh;
  output_.fx = source.fx / sx;
  output_.fy = source.fy / sy;
  output_.cx = (source.cx - x0_ + 0.5) / sx - 0.5;
  output_.cy = (source.cy - y0_ + 0.5) / sy - 0.5;
  const bool undistort = options.undistort && source.model != Distortion::kNone;
  if (options.undistort) {
    output_.model = Distortion::kNone;
    output_.coeffs = {};
  }
  // Without undistortion the coefficients stay valid after cropping/resizing: they act on
  // normalised coordinates, which only K (updated above) maps to pixels.
  if (!undistort && ow == cw && oh == ch) {
    impl_->identity_crop = true;
    return;
  }
  impl_->map_x.create(oh, ow, CV_32FC1);
  impl_->map_y.create(oh, ow, CV_32FC1);
  for (int v = 0; v < oh; ++v) {
    float* mx = impl_->map_x.ptr<float>(v);
    float* my = impl_->map_y.ptr<float>(v);
    for (int u = 0; u < ow; ++u) {
      const double uf = x0_ + (u + 0.5) * sx - 0.5;
      const double vf = y0_ + (v + 0.5) * sy - 0.5;
      if (undistort) {
        const Eigen::Vector2d xy((uf - source.cx) / source.fx, (vf - source.cy) / source.fy);
        const Eigen::Vector2d d = source.distort(xy);
        mx[u] = static_cast<float>(source.fx * d.x() + source.cx);
        my[u] = static_cast<float>(source.fy * d.y() + source.cy);
      } else {
        mx[u] = static_cast<float>(uf);
        my[u] = static_cast<float>(vf);
      }
    }
  }
}

FrameProcessor::~FrameProcessor() = default;
FrameProcessor::FrameProcessor(FrameProcessor&&) noexcept = default;
FrameProcessor& FrameProcessor::operator=(FrameProcessor&&) noexcept = default;

namespace {
cv::Mat apply(const cv::Mat& src, const CameraModel& s, int x0, int y0, const CameraModel& o, bool identity_crop,
              const cv::Mat& mx, const cv::Mat& my, const std::string& where) {
  if (src.cols != s.width || src.rows != s.height)
    throw InputError(where + ": frame is " + std::to_string(src.cols) + "x" + std::to_string(src.rows) +
                     ", the camera info says " + std::to_string(s.width) + "x" + std::to_string(s.height));
  if (identity_crop) return src(cv::Rect(x0, y0, o.width, o.height)).clone();
  cv::Mat out;
  cv::remap(src, out, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return out;
}
}  // namespace

void FrameProcessor::process_to_png(const RawImage& frame, const fs::path& png, const std::string& where) const {
  const cv::Mat src = to_png_layout(frame, where);
  write_mat_png(apply(src, source_, x0_, y0_, output_, impl_->identity_crop, impl_->map_x, impl_->map_y, where), png,
                options_.png_compression);
}

void FrameProcessor::process_encoded_to_png(std::string_view encoded, const fs::path& png,
                                             const std::string& where) const {
  const cv::Mat buf(1, static_cast<int>(encoded.size()), CV_8UC1, const_cast<char*>(encoded.data()));
  cv::Mat src = cv::imdecode(buf, cv::IMREAD_UNCHANGED);
  if (src.empty()) throw InputError(where + ": compressed image cannot be decoded");
  if (src.channels() == 4) cv::cvtColor(src, src, cv::COLOR_BGRA2BGR);
  write_mat_png(apply(src, source_, x0_, y0_, output_, impl_->identity_crop, impl_->map_x, impl_->map_y, where), png,
                options_.png_compression);
}

void write_png(const RawImage& frame, const fs::path& png, const std::string& where) {
  write_mat_png(to_png_layout(frame, where), png, 3);
}

std::string encode_png(const RawImage& frame, const std::string& where) {
  std::vector<uchar> buf;
  if (!cv::imencode(".png", to_png_layout(frame, where), buf)) throw InputError(where + ": PNG encoding failed");
  return std::string(buf.begin(), buf.end());
}

DecodedImage read_image(const fs::path& file) {
  const cv::Mat m = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
  if (m.empty()) throw InputError("cannot read image", {file.string()});
  DecodedImage d;
  d.width = m.cols;
  d.height = m.rows;
  d.channels = m.channels();
  d.depth_bytes = static_cast<int>(m.elemSize1());
  const cv::Mat c = m.isContinuous() ? m : m.clone();
  d.data.assign(c.data, c.data + c.total() * c.elemSize());
  return d;
}

}  // namespace roe::image
