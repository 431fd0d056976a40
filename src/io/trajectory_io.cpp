#include "roe/io/trajectory_io.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <set>

#include "roe/core/error.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/input.hpp"
#include "roe/io/output.hpp"

namespace roe::io {

std::string to_string(TrajectoryFormat f) {
  switch (f) {
    case TrajectoryFormat::kAuto:
      return "auto";
    case TrajectoryFormat::kTum:
      return "tum";
    case TrajectoryFormat::kEuroc:
      return "euroc";
    case TrajectoryFormat::kCsv:
      return "csv";
    case TrajectoryFormat::kCsvNs:
      return "csv-ns";
    case TrajectoryFormat::kKitti:
      return "kitti";
  }
  return "auto";
}

TrajectoryFormat parse_trajectory_format(const std::string& name) {
  if (name == "auto") return TrajectoryFormat::kAuto;
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "euroc" || name == "asl") return TrajectoryFormat::kEuroc;
  if (name == "csv" || name == "cnspy") return TrajectoryFormat::kCsv;
  if (name == "csv-ns" || name == "roe") return TrajectoryFormat::kCsvNs;
  if (name == "kitti") return TrajectoryFormat::kKitti;
  throw InputError(fmt::format("unknown trajectory format '{}' (expected auto, tum, euroc, csv (= cnspy), "
                               "csv-ns (= roe) or kitti)",
                               name),
                   {"", 0, 0, "format"});
}

std::size_t Trajectory::count_duplicate_stamps() const {
  std::size_t n = 0;
  for (std::size_t i = 1; i < t_ns.size(); ++i) n += (t_ns[i] == t_ns[i - 1]);
  return n;
}

// -------------------------------------------------------------------------------------------------
// Detection
// -------------------------------------------------------------------------------------------------

namespace {

std::string_view trim_cr(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::vector<std::string> split_names(std::string_view line, char delim) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t d = line.find(delim, start);
    out.emplace_back(
        trim_cr(line.substr(start, d == std::string_view::npos ? std::string_view::npos : d - start)));
    if (d == std::string_view::npos) break;
    start = d + 1;
  }
  return out;
}

// Name without a unit suffix: "p_RS_R_x [m]" -> "p_RS_R_x".
std::string base_name(const std::string& n) {
  const std::size_t b = n.find(" [");
  return std::string(
      trim_cr(b == std::string::npos ? std::string_view(n) : std::string_view(n).substr(0, b)));
}

bool looks_numeric(std::string_view f) {
  f = trim_cr(f);
  if (f.empty()) return false;
  const char c = f.front();
  return (c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.';
}

/// EuRoC's names, or OpenVINS's spelling of the same columns (vicon2gt / ov_eval ground truth:
/// `#time(ns),px,py,pz,qw,qx,qy,qz[,vx,...]`).
bool is_euroc_header(const std::vector<std::string>& names) {
  static const std::array<const char*, 8> euroc = {"timestamp", "p_RS_R_x", "p_RS_R_y", "p_RS_R_z",
                                                   "q_RS_w",    "q_RS_x",   "q_RS_y",   "q_RS_z"};
  static const std::array<const char*, 8> openvins = {"time(ns)", "px", "py", "pz", "qw", "qx", "qy", "qz"};
  if (names.size() < 8) return false;
  for (const auto* want : {&euroc, &openvins}) {
    bool all = true;
    for (std::size_t k = 0; k < 8; ++k) all = all && base_name(names[k]) == (*want)[k];
    if (all) return true;
  }
  return false;
}

const std::vector<std::string> kPoseCols = {"tx", "ty", "tz", "qx", "qy", "qz", "qw"};
const std::vector<std::string> kPosOrientCov = {"pxx", "pxy", "pxz", "pyy", "pyz", "pzz",
                                                "qrr", "qrp", "qry", "qpp", "qpy", "qyy"};
const std::vector<std::string> kPoseCov = {"Txx", "Txy", "Txz", "Txa", "Txb", "Txc", "Tyy",
                                           "Tyz", "Tya", "Tyb", "Tyc", "Tzz", "Tza", "Tzb",
                                           "Tzc", "Taa", "Tab", "Tac", "Tbb", "Tbc", "Tcc"};

}  // namespace

namespace {

/// The format from the first decisive line of `text`; nullopt when no line decides (only blank and
/// comment lines). InputError for a bag or a line that fits no format.
std::optional<TrajectoryFormat> detect_format_in(std::string_view text, const std::string& source) {
  if (text.substr(0, 8) == "#ROSBAG " || text.substr(0, 5) == "\x89MCAP")
    throw InputError(fmt::format("this is a ROS bag ({}), not a trajectory file: name the pose topic "
                                 "(BAG:TOPIC, a geometry_msgs PoseStamped/Odometry topic) or export it first "
                                 "(e.g. `evo_traj bag BAG TOPIC --save_as_tum`)",
                                 text[0] == '#' ? "rosbag v2" : "MCAP"),
                     {source});
  std::size_t pos = utf8_bom_length(text);
  std::int64_t line_no = 0;
  while (pos < text.size()) {
    const std::size_t nl = text.find('\n', pos);
    std::string_view line =
        trim_cr(text.substr(pos, nl == std::string_view::npos ? std::string_view::npos : nl - pos));
    pos = nl == std::string_view::npos ? text.size() : nl + 1;
    ++line_no;
    if (line.empty()) continue;
    const bool comment = line.front() == '#';
    std::string_view body = comment ? trim_cr(line.substr(1)) : line;
    if (body.find(',') != std::string_view::npos) {
      if (looks_numeric(body)) {
        throw InputError(
            "comma-separated rows without a header line: cannot tell the columns apart; add a header "
            "(e.g. t,tx,ty,tz,qx,qy,qz,qw) or pass the format (--est-format/--gt-format euroc)",
            {source, line_no, 1});
      }
      const auto names = split_names(body, ',');
      if (is_euroc_header(names)) return TrajectoryFormat::kEuroc;
      if (std::find(names.begin(), names.end(), "timestamp_ns") != names.end())
        return TrajectoryFormat::kCsvNs;
      if (std::find(names.begin(), names.end(), "t") != names.end()) return TrajectoryFormat::kCsv;
      throw InputError(fmt::format("unrecognised trajectory header '{}' (expected a TUM file, an EuRoC csv "
                                   "with p_RS_R_x..q_RS_z, or a CSV with columns t,tx,ty,tz,qx,qy,qz,qw)",
                                   std::string(line.substr(0, 120))),
                       {source, line_no, 1});
    }
    if (comment) continue;  // a TUM comment (e.g. "# timestamp tx ty tz qx qy qz qw")
    if (looks_numeric(body)) {
      // KITTI: 12 numbers (the 3×4 [R|t] row-major), no stamp; TUM: 8.
      std::size_t fields = 0;
      for (std::size_t i = 0; i < body.size(); ++i)
        fields += body[i] != ' ' && body[i] != '\t' && (i == 0 || body[i - 1] == ' ' || body[i - 1] == '\t');
      return fields == 12 ? TrajectoryFormat::kKitti : TrajectoryFormat::kTum;
    }
    throw InputError(fmt::format("unrecognised trajectory line '{}' (expected a TUM row 't tx ty tz qx qy qz "
                                 "qw' or a CSV header)",
                                 std::string(line.substr(0, 120))),
                     {source, line_no, 1});
  }
  return std::nullopt;
}

}  // namespace

TrajectoryFormat detect_trajectory_format(std::string_view text, const std::string& source) {
  if (const auto f = detect_format_in(text, source)) return *f;
  throw InputError("the trajectory file has no data rows", {source});
}

// -------------------------------------------------------------------------------------------------
// Reading
// -------------------------------------------------------------------------------------------------

namespace {

Timestamp read_seconds(const CsvReader& r, std::size_t col) {
  const std::string_view f = r.field(col);
  const std::optional<Timestamp> parsed = parse_seconds_ns(f);
  if (!parsed) {
    bool digits_only =
        !f.empty() && std::all_of(f.begin(), f.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (digits_only && f.size() >= 15) {
      throw r.error(col, fmt::format("time stamp '{}' is too large for seconds: it looks like nanoseconds "
                                     "(this format stores seconds; use the EuRoC or csv-ns format)",
                                     std::string(f)));
    }
    throw r.error(col,
                  fmt::format("expected a time stamp in seconds, got '{}'", std::string(f.substr(0, 40))));
  }
  return *parsed;
}

Pose read_pose(const CsvReader& r, const std::array<std::size_t, 3>& p,
               const std::array<std::size_t, 4>& q_xyzw) {
  const Eigen::Vector3d pos(r.get_double(p[0]), r.get_double(p[1]), r.get_double(p[2]));
  // Beyond a million km no trajectory is meant (ECEF and UTM stay below 1e7 m); squares of such
  // values overflow the alignment, which would blame the geometry instead of the cell.
  for (int k = 0; k < 3; ++k)
    if (std::abs(pos(k)) > 1e9)
      throw r.error(p[k], fmt::format("position {} m is beyond any trajectory's range (|p| <= 1e9 m)", pos(k)));
  const Eigen::Quaterniond q(r.get_double(q_xyzw[3]), r.get_double(q_xyzw[0]), r.get_double(q_xyzw[1]),
                             r.get_double(q_xyzw[2]));
  const double n = q.norm();
  if (!(std::abs(n - 1.0) <= 0.05)) {
    throw r.error(q_xyzw[3],
                  fmt::format("quaternion norm {:.6g} is not 1 (expected a unit quaternion; is the "
                              "column order right?)",
                              n));
  }
  return Pose(q, pos);  // normalises
}

void append(Trajectory& tr, const CsvReader& r, std::size_t t_col, Timestamp t, Pose pose) {
  if (!tr.t_ns.empty() && t < tr.t_ns.back()) {
    throw r.error(
        t_col, fmt::format("time stamps must not decrease: {} s follows {} s (line {})", format_seconds_ns(t),
                           format_seconds_ns(tr.t_ns.back()), tr.lines.back()));
  }
  tr.t_ns.push_back(t);
  tr.poses.push_back(std::move(pose));
  tr.lines.push_back(r.line());
}

void read_tum(CsvReader& r, Trajectory& tr) {
  while (r.next()) {
    const Timestamp t = read_seconds(r, 0);
    append(tr, r, 0, t, read_pose(r, {1, 2, 3}, {4, 5, 6, 7}));
  }
}

/// KITTI odometry poses (evo's kitti format): T = [R|t] row-major per line, no stamp. The stamps are the
/// row index in seconds (association by index) until a times file replaces them (read_kitti_times).
void read_kitti(CsvReader& r, Trajectory& tr) {
  Timestamp index = 0;
  while (r.next()) {
    Eigen::Matrix3d R;
    Eigen::Vector3d p;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) R(i, j) = r.get_double(static_cast<std::size_t>(4 * i + j));
      p(i) = r.get_double(static_cast<std::size_t>(4 * i + 3));
    }
    const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (!(err <= 1e-3) || !(R.determinant() > 0.0))
      throw r.error(0, fmt::format("the 3×3 block is not a rotation (|RᵀR − I| = {:.3g}, det {:.3g}): is this a "
                                   "KITTI pose file (r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz)?",
                                   err, R.determinant()));
    append(tr, r, 0, index, Pose(Eigen::Quaterniond(R), p));  // normalises
    index += 1'000'000'000;
  }
}

void read_euroc(CsvReader& r, Trajectory& tr) {
  if (!is_euroc_header(r.header())) {
    throw InputError(
        "not an EuRoC trajectory header: expected #timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],"
        "p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z [](,...) or OpenVINS's #time(ns),px,py,pz,qw,qx,qy,qz(,...)",
        {r.source(), r.header_line(), 1});
  }
  while (r.next()) {
    const Timestamp t = r.get_int64(0);
    append(tr, r, 0, t, read_pose(r, {1, 2, 3}, {5, 6, 7, 4}));
  }
}

void read_csv(CsvReader& r, Trajectory& tr, bool ns) {
  const auto& header = r.header();
  const std::string t_name = ns ? "timestamp_ns" : "t";
  std::set<std::string> names;
  names.insert(header.begin(), header.end());  // CsvReader already refuses duplicate names
  // The set must be the base columns plus one of the known optional groups (cnspy CSVSpatialFormatType).
  std::set<std::string> base{t_name};
  base.insert(kPoseCols.begin(), kPoseCols.end());
  for (const auto& b : base) {
    if (!names.count(b)) {
      throw InputError(
          fmt::format("the header has no column '{}' (a {} trajectory needs {},tx,ty,tz,qx,qy,qz,qw in "
                      "any order)",
                      b, ns ? "csv-ns" : "CSV", t_name),
          {r.source(), r.header_line(), 0, b});
    }
  }
  std::set<std::string> extra;
  for (const auto& n : names)
    if (!base.count(n)) extra.insert(n);
  const auto has_all = [&](const std::vector<std::string>& g) {
    return std::all_of(g.begin(), g.end(), [&](const std::string& c) { return extra.count(c) > 0; });
  };
  const auto remove = [&](const std::vector<std::string>& g) {
    for (const auto& c : g) extra.erase(c);
  };
  int cov_kind = 0;  // 0 none, 1 PosOrientWithCov, 2 PoseWithCov
  if (has_all(kPosOrientCov)) {
    cov_kind = 1;
    remove(kPosOrientCov);
  } else if (has_all(kPoseCov)) {
    cov_kind = 2;
    remove(kPoseCov);
  }
  bool typed = false, scaled = false;
  if (cov_kind != 0 && extra.count("est_err_type") && extra.count("err_representation")) {
    typed = true;
    remove({"est_err_type", "err_representation"});
  } else if (cov_kind == 0 && extra.count("scale") && extra.count("est_err_type")) {
    scaled = true;  // cnspy PoseTypedStamped
    remove({"scale", "est_err_type"});
  }
  if (!extra.empty()) {
    throw InputError(
        fmt::format("unexpected column '{}' (known CSV layouts: t,tx,ty,tz,qx,qy,qz,qw optionally "
                    "with the cnspy covariance columns pxx..qyy or Txx..Tcc [+ est_err_type, "
                    "err_representation], or + scale, est_err_type)",
                    *extra.begin()),
        {r.source(), r.header_line(), 0, *extra.begin()});
  }
  (void)scaled;
  const std::size_t ct = r.column(t_name);
  const std::array<std::size_t, 3> cp{r.column("tx"), r.column("ty"), r.column("tz")};
  const std::array<std::size_t, 4> cq{r.column("qx"), r.column("qy"), r.column("qz"), r.column("qw")};
  std::vector<std::size_t> ccov;
  for (const auto& c : cov_kind == 1 ? kPosOrientCov : cov_kind == 2 ? kPoseCov : std::vector<std::string>{})
    ccov.push_back(r.column(c));
  const std::size_t c_type = typed ? r.column("est_err_type") : 0;
  bool first = true;
  while (r.next()) {
    const Timestamp t = ns ? r.get_int64(ct) : read_seconds(r, ct);
    append(tr, r, ct, t, read_pose(r, cp, cq));
    if (cov_kind == 0) continue;
    Eigen::Matrix<double, 6, 6> C = Eigen::Matrix<double, 6, 6>::Zero();
    if (cov_kind == 1) {
      // position block (0..5) and orientation block (6..11), upper triangles row-major
      const int idx[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
      for (int k = 0; k < 6; ++k) {
        C(idx[k][0], idx[k][1]) = C(idx[k][1], idx[k][0]) = r.get_double(ccov[k]);
        C(3 + idx[k][0], 3 + idx[k][1]) = C(3 + idx[k][1], 3 + idx[k][0]) = r.get_double(ccov[6 + k]);
      }
    } else {
      int k = 0;
      for (int a = 0; a < 6; ++a)
        for (int b = a; b < 6; ++b, ++k) C(a, b) = C(b, a) = r.get_double(ccov[k]);
    }
    tr.cov.push_back(C);
    if (typed && first) tr.cov_position_local = (r.field(c_type) == "type1");
    first = false;
  }
}

}  // namespace

namespace {

CsvOptions csv_options(TrajectoryFormat format) {
  CsvOptions o;
  o.comment_prefix = "#";
  const bool spaces = format == TrajectoryFormat::kTum || format == TrajectoryFormat::kKitti;
  o.whitespace_delimited = spaces;
  o.header = spaces ? CsvHeader::kNone : CsvHeader::kFirstLine;
  o.columns = format == TrajectoryFormat::kTum ? 8 : format == TrajectoryFormat::kKitti ? 12 : 0;
  return o;
}

/// The rows of `r` (a reader made with csv_options(format)); `rows` reserves room for that many poses.
Trajectory read_rows(CsvReader& r, TrajectoryFormat format, std::size_t rows) {
  Trajectory tr;
  tr.format = format;
  tr.source = r.source();
  tr.t_ns.reserve(rows);
  tr.poses.reserve(rows);
  tr.lines.reserve(rows);
  switch (format) {
    case TrajectoryFormat::kTum:
      read_tum(r, tr);
      break;
    case TrajectoryFormat::kEuroc:
      read_euroc(r, tr);
      break;
    case TrajectoryFormat::kKitti:
      read_kitti(r, tr);
      break;
    case TrajectoryFormat::kCsv:
    case TrajectoryFormat::kCsvNs:
      read_csv(r, tr, format == TrajectoryFormat::kCsvNs);
      break;
    case TrajectoryFormat::kAuto:
      break;
  }
  if (tr.empty()) throw InputError("the trajectory file has no poses", {tr.source});
  return tr;
}

/// Bytes of a file's head that format detection and the row estimate look at.
constexpr std::size_t kHeadBytes = 64 * 1024;

}  // namespace

Trajectory parse_trajectory(std::string text, const std::string& source, TrajectoryFormat format) {
  if (format == TrajectoryFormat::kAuto) format = detect_trajectory_format(text, source);
  const std::size_t lines = static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')) + 1;
  CsvReader r = CsvReader::from_text(std::move(text), source, csv_options(format));
  return read_rows(r, format, lines);
}

Trajectory read_trajectory(const fs::path& file, TrajectoryFormat format) {
  // The file is parsed as it is read (CsvReader's chunks): its text is never held whole. The format is
  // detected from its head, and from the whole file only when the head holds no decisive line.
  const std::string source = file.string();
  const std::string head = read_file_head(file, kHeadBytes);
  const bool whole = head.size() < kHeadBytes;
  const std::string_view complete_lines(head.data(), whole ? head.size() : head.rfind('\n') + 1);
  if (format == TrajectoryFormat::kAuto) {
    const auto f = detect_format_in(complete_lines, source);
    format = f ? *f : detect_trajectory_format(read_file(file), source);
  }
  // Room for the rows: exact for a small file, else from the head's line length (+5 %).
  const std::size_t head_lines = static_cast<std::size_t>(std::count(head.begin(), head.end(), '\n')) + 1;
  const std::size_t rows =
      whole ? head_lines
            : static_cast<std::size_t>(1.05 * static_cast<double>(require_regular_file(file)) /
                                       static_cast<double>(head.size()) * static_cast<double>(head_lines));
  CsvReader r(file, csv_options(format));
  return read_rows(r, format, rows);
}

void apply_kitti_times(Trajectory& tr, const fs::path& times_file) {
  if (tr.format != TrajectoryFormat::kKitti)
    throw InputError(fmt::format("a times file is for a KITTI pose file (without stamps), not a {} trajectory",
                                 to_string(tr.format)),
                     {times_file.string()});
  CsvOptions o;
  o.whitespace_delimited = true;
  o.header = CsvHeader::kNone;
  o.columns = 1;
  o.comment_prefix = "#";
  CsvReader r = CsvReader::from_text(read_file(times_file), times_file.string(), o);
  std::size_t i = 0;
  while (r.next()) {
    if (i == tr.size())
      throw r.error(0, fmt::format("more stamps than poses: {} has {}", tr.source, tr.size()));
    const double t = r.get_double(0);  // KITTI's times.txt: seconds, often as 1.036e-01
    if (!(t >= 0.0 && t < 1e10)) throw r.error(0, fmt::format("time {} s is out of range", t));
    const Timestamp ns = from_seconds(t);
    if (i > 0 && ns < tr.t_ns[i - 1]) throw r.error(0, "time stamps must not decrease");
    tr.t_ns[i++] = ns;
  }
  if (i != tr.size())
    throw InputError(fmt::format("{} stamps for {} poses of {} (one stamp per pose line)", i, tr.size(), tr.source),
                     {times_file.string()});
}

// -------------------------------------------------------------------------------------------------
// Writing
// -------------------------------------------------------------------------------------------------

namespace {

/// The delimiter and header line of a trajectory file in `format` (not kAuto); KITTI has no header.
CsvWriter trajectory_writer(TrajectoryFormat format) {
  const char delim = format == TrajectoryFormat::kTum || format == TrajectoryFormat::kKitti ? ' ' : ',';
  CsvWriter w(delim);
  switch (format) {
    case TrajectoryFormat::kKitti:  // no header, no stamps
      break;
    case TrajectoryFormat::kTum:
      w.header({"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"}, "# ");
      break;
    case TrajectoryFormat::kEuroc:
      w.header({"timestamp [ns]", "p_RS_R_x [m]", "p_RS_R_y [m]", "p_RS_R_z [m]", "q_RS_w []", "q_RS_x []",
                "q_RS_y []", "q_RS_z []"},
               "#");
      break;
    case TrajectoryFormat::kCsvNs:
      w.header({"timestamp_ns", "tx", "ty", "tz", "qx", "qy", "qz", "qw"});
      break;
    default:
      w.header({"t", "tx", "ty", "tz", "qx", "qy", "qz", "qw"});
      break;
  }
  return w;
}

/// One pose's row of a trajectory file in `format` (not kAuto).
void trajectory_row(CsvWriter& w, const StampedPose& sp, TrajectoryFormat format) {
  const Pose& T = sp.T;
  if (format == TrajectoryFormat::kKitti) {
    const Eigen::Matrix3d R = T.R();
    for (int i = 0; i < 3; ++i) w.add(R(i, 0)).add(R(i, 1)).add(R(i, 2)).add(T.p(i));
  } else {
    if (format == TrajectoryFormat::kEuroc || format == TrajectoryFormat::kCsvNs) {
      w.add(static_cast<std::int64_t>(sp.t_ns));
    } else {
      w.add_seconds(sp.t_ns);
    }
    w.add(T.p.x()).add(T.p.y()).add(T.p.z());
    if (format == TrajectoryFormat::kEuroc) {
      w.add(T.q.w()).add(T.q.x()).add(T.q.y()).add(T.q.z());
    } else {
      w.add(T.q.x()).add(T.q.y()).add(T.q.z()).add(T.q.w());
    }
  }
  w.end_row();
}

/// The text of a trajectory file of n poses, at(i) the i-th; with a `sink`, streamed into it in pieces as it
/// grows (the writer returned then holds nothing).
CsvWriter fill_trajectory(std::size_t n, const std::function<StampedPose(std::size_t)>& at, TrajectoryFormat format,
                          AtomicFile* sink) {
  if (format == TrajectoryFormat::kAuto) format = TrajectoryFormat::kCsv;
  CsvWriter w = trajectory_writer(format);
  for (std::size_t i = 0; i < n; ++i) {
    trajectory_row(w, at(i), format);
    if (sink != nullptr) w.flush_to(*sink, CsvWriter::kFlushBytes);
  }
  if (sink != nullptr) w.flush_to(*sink);
  return w;
}

std::function<StampedPose(std::size_t)> pose_at(const std::vector<Timestamp>& t_ns, const std::vector<Pose>& poses) {
  ROE_CHECK(t_ns.size() == poses.size(), "one stamp per pose");
  return [&t_ns, &poses](std::size_t i) { return StampedPose{t_ns[i], poses[i]}; };
}

}  // namespace

std::string format_trajectory(std::size_t n, const std::function<StampedPose(std::size_t)>& at,
                              TrajectoryFormat format) {
  return fill_trajectory(n, at, format, nullptr).str();
}

std::string format_trajectory(const std::vector<Timestamp>& t_ns, const std::vector<Pose>& poses,
                              TrajectoryFormat format) {
  return format_trajectory(poses.size(), pose_at(t_ns, poses), format);
}

void write_trajectory(const fs::path& file, std::size_t n, const std::function<StampedPose(std::size_t)>& at,
                      TrajectoryFormat format) {
  AtomicFile f(file);
  fill_trajectory(n, at, format, &f);
  f.commit();
}

void write_trajectory(const fs::path& file, const std::vector<Timestamp>& t_ns,
                      const std::vector<Pose>& poses, TrajectoryFormat format) {
  write_trajectory(file, poses.size(), pose_at(t_ns, poses), format);
}

void write_trajectory(const fs::path& file, const std::vector<StampedPose>& poses, TrajectoryFormat format) {
  std::vector<Timestamp> t;
  std::vector<Pose> p;
  t.reserve(poses.size());
  p.reserve(poses.size());
  for (const auto& sp : poses) {
    t.push_back(sp.t_ns);
    p.push_back(sp.T);
  }
  write_trajectory(file, t, p, format);
}

struct TrajectoryWriter::Impl {
  Impl(const fs::path& file, TrajectoryFormat f) : format(f), file(file), w(trajectory_writer(f)) {}
  TrajectoryFormat format;
  AtomicFile file;
  CsvWriter w;
};

TrajectoryWriter::TrajectoryWriter(const fs::path& file, TrajectoryFormat format)
    : impl_(std::make_unique<Impl>(file, format == TrajectoryFormat::kAuto ? TrajectoryFormat::kCsv : format)) {}
TrajectoryWriter::~TrajectoryWriter() = default;

void TrajectoryWriter::add(const StampedPose& pose) {
  trajectory_row(impl_->w, pose, impl_->format);
  impl_->w.flush_to(impl_->file, CsvWriter::kFlushBytes);
}

void TrajectoryWriter::commit() {
  impl_->w.flush_to(impl_->file);
  impl_->file.commit();
}

}  // namespace roe::io
