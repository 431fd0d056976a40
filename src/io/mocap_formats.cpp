// Motion-capture exports: Motive CSV, Vicon CSV (pose topics of ROS bags: io/ros/bag_poses.cpp).
#include "roe/io/mocap_formats.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <set>

#include <fmt/format.h>

#include "roe/core/error.hpp"
#include "roe/io/csv.hpp"
#include "roe/math/so3.hpp"

namespace roe::io {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool valid_utf8(const std::string& s) {
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    const std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (n == 0 || i + n > s.size()) return false;
    for (std::size_t k = 1; k < n; ++k)
      if ((static_cast<unsigned char>(s[i + k]) >> 6) != 0x2) return false;
    i += n;
  }
  return true;
}

/// The cells of the current row. Motive and Vicon run on Windows and may write names in the
/// Windows code page (cp1252, Latin-1 for letters such as ö): a cell that is not UTF-8 is read as
/// Latin-1, so that `--body "Körper 1"` typed in a UTF-8 terminal finds it, and counted.
std::vector<std::string> row_strings(const CsvReader& r, std::size_t* transcoded = nullptr) {
  std::vector<std::string> v;
  for (std::size_t i = 0; i < r.size(); ++i) {
    std::string cell(r.field(i));
    if (!valid_utf8(cell)) {
      std::string u;
      for (const char ch : cell) {
        const auto c = static_cast<unsigned char>(ch);
        if (c < 0x80) {
          u += ch;
        } else {
          u += static_cast<char>(0xC0 | (c >> 6));
          u += static_cast<char>(0x80 | (c & 0x3F));
        }
      }
      cell = std::move(u);
      if (transcoded) ++*transcoded;
    }
    v.push_back(std::move(cell));
  }
  return v;
}

bool cell_empty(const CsvReader& r, std::size_t i) { return i >= r.size() || r.field(i).empty(); }

/// Checks and normalises a quaternion read at the current row; `col` is the first of its columns.
Eigen::Quaterniond checked_unit(const CsvReader& r, const Eigen::Quaterniond& q, std::size_t col) {
  const double n = q.norm();
  if (!(std::abs(n - 1.0) <= kMocapUnitQuatTolerance))
    throw r.error(col, fmt::format("quaternion is not unit norm (|q| = {:.6g}, tolerance {})", n,
                                   kMocapUnitQuatTolerance));
  return q.normalized();
}

Eigen::Matrix3d axis_rotation(char axis, double angle) {
  const Eigen::Vector3d a = axis == 'X' ? Eigen::Vector3d::UnitX()
                            : axis == 'Y' ? Eigen::Vector3d::UnitY()
                                          : Eigen::Vector3d::UnitZ();
  return Eigen::AngleAxisd(angle, a).toRotationMatrix();
}

double length_scale(const std::string& unit, const std::string& file, std::int64_t line,
                    std::vector<std::string>& warnings) {
  const std::string u = lower(unit);
  if (u.empty()) {
    warnings.push_back("no length unit in the file: assuming metres");
    return 1.0;
  }
  if (u == "meters" || u == "metres" || u == "m") return 1.0;
  if (u == "centimeters" || u == "centimetres" || u == "cm") return 0.01;
  if (u == "millimeters" || u == "millimetres" || u == "mm") return 0.001;
  throw InputError("unknown length unit \"" + unit + "\" (Meters, Centimeters, Millimeters, m, cm, mm)", {file, line});
}

void check_time(const CsvReader& r, std::size_t col, Timestamp t, bool have_prev, Timestamp prev) {
  // Motive's Time and Vicon's frame counter start at 0: a negative time is a damaged cell.
  if (t < 0) throw r.error(col, fmt::format("negative time ({} ns): mocap times start at 0", t));
  if (have_prev && t <= prev)
    throw r.error(col, fmt::format("time does not increase ({} ns after {} ns)", t, prev));
}

}  // namespace

namespace {

/// Motive and Vicon exports: several header rows roe reads itself, rows of any length, no comment lines.
CsvOptions export_csv_options() {
  CsvOptions o;
  o.header = CsvHeader::kNone;
  o.ragged = true;
  o.comment_prefix = "";
  return o;
}

/// " \"a\" \"b\"": the bodies an error offers.
std::string quoted_list(const std::vector<std::string>& names) {
  std::string list;
  for (const auto& b : names) list += " \"" + b + "\"";
  return list;
}

/// Several bodies and no --body, or a --body the file lacks: the error names the file's bodies.
/// (`noun`/`nouns`: "rigid body"/"rigid bodies" in Motive, "object"/"objects" in Vicon.)
[[noreturn]] void refuse_body(const std::string& requested, const std::vector<std::string>& bodies, const char* noun,
                              const char* nouns, const std::string& src) {
  if (requested.empty())
    throw InputError(fmt::format("several {} in the file; choose one with --body:{}", nouns, quoted_list(bodies)),
                     {src});
  throw InputError(fmt::format("{} \"{}\" is not in the file; it has:{}", noun, requested, quoted_list(bodies)), {src});
}

/// A Motive export's header: line 1's key/value pairs and the Type/Name/ID/property/axis rows.
struct MotiveHeader {
  std::map<std::string, std::string> info;
  std::vector<std::vector<std::string>> rows;  ///< up to and including the axis row ("Frame", ...)
  std::int64_t axis_line = 0;
  std::size_t time_col = 1;
  const std::vector<std::string>& axis() const { return rows[rows.size() - 1]; }
  const std::vector<std::string>& prop() const { return rows[rows.size() - 2]; }
  const std::vector<std::string>& name() const { return rows[rows.size() - 4]; }
  const std::vector<std::string>& type() const { return rows[rows.size() - 5]; }
  std::string info_or(const std::string& key, const std::string& fallback) const {
    const auto it = info.find(key);
    return it == info.end() ? fallback : it->second;
  }
};

std::string cell_of(const std::vector<std::string>& row, std::size_t i) { return i < row.size() ? row[i] : std::string(); }

MotiveHeader read_motive_header(CsvReader& r, const std::string& src, std::vector<std::string>& warnings) {
  MotiveHeader h;
  if (!r.next()) throw InputError("empty file", {src});
  for (std::size_t i = 0; i + 1 < r.size(); i += 2) h.info[std::string(r.field(i))] = std::string(r.field(i + 1));
  if (!h.info.count("Format Version"))
    throw InputError("not a Motive CSV export: line 1 has no \"Format Version\"", {src, r.line()});
  // Exports of Motive 2.x and 3.x write 1.2x (1.21, 1.22, 1.23, 1.24); an older or newer layout may
  // differ, so say so (the columns are still found by their header rows).
  const std::string& v = h.info["Format Version"];
  if (v.rfind("1.2", 0) != 0)
    warnings.push_back("Motive CSV Format Version " + v +
                       " has not been checked (roe knows 1.2x, the exports of Motive 2.x and 3.x)");
  std::size_t transcoded = 0;
  while (r.next()) {  // header rows up to the axis row ("Frame", ...)
    h.rows.push_back(row_strings(r, &transcoded));
    if (!h.rows.back().empty() && h.rows.back()[0] == "Frame") {
      h.axis_line = r.line();
      break;
    }
    if (h.rows.size() > 12) break;
  }
  if (!h.axis_line || h.rows.size() < 5)
    throw InputError("Motive header rows not found (expected Type/Name/ID/property rows and a row starting "
                     "with \"Frame\")",
                     {src, r.line()});
  const auto& axis = h.axis();
  for (std::size_t i = 1; i < axis.size(); ++i)
    if (axis[i].rfind("Time", 0) == 0 && axis[i] != "TimeCode") {
      h.time_col = i;
      break;
    }
  if (transcoded)
    warnings.push_back(fmt::format("{} header cell(s) are not UTF-8: read as Latin-1 (the Windows code page)",
                                   transcoded));
  return h;
}

/// Where the chosen body's rotation and position are, and how to read them.
struct MotiveColumns {
  std::map<std::string, std::size_t> rot, pos;  ///< axis letter → column
  bool quat = true;
  std::string euler_order;  ///< for Euler angles: the order of the rotations (e.g. "XYZ")
  double scale = 1.0;       ///< length unit → metres
};

/// The file's rigid bodies into `out.bodies`, the chosen one into `out.body`.
void choose_motive_body(const MotiveHeader& h, const std::string& body, const std::string& src, MocapData& out) {
  std::set<std::string> seen;
  const auto &type = h.type(), &name = h.name();
  for (std::size_t i = 0; i < type.size(); ++i)
    if (type[i] == "Rigid Body" && !cell_of(name, i).empty() && seen.insert(name[i]).second) out.bodies.push_back(name[i]);
  if (out.bodies.empty()) throw InputError("the Motive file has no rigid body (only markers?)", {src, h.axis_line - 4});
  if (body.empty() && out.bodies.size() > 1) refuse_body(body, out.bodies, "rigid body", "rigid bodies", src);
  if (!body.empty() && !seen.count(body)) refuse_body(body, out.bodies, "rigid body", "rigid bodies", src);
  out.body = body.empty() ? out.bodies.front() : body;
}

MotiveColumns motive_columns(const MotiveHeader& h, const std::string& src, MocapData& out) {
  MotiveColumns c;
  out.rotation_type = h.info_or("Rotation Type", "Quaternion");
  c.quat = lower(out.rotation_type) == "quaternion";
  if (!c.quat) {
    c.euler_order = out.rotation_type;
    for (auto& ch : c.euler_order) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
    std::string sorted = c.euler_order;
    std::sort(sorted.begin(), sorted.end());
    if (sorted != "XYZ")
      throw InputError("unknown Rotation Type \"" + out.rotation_type + "\" (Quaternion or an Euler order such as XYZ)",
                       {src, 1});
  }
  const auto &type = h.type(), &name = h.name(), &prop = h.prop(), &axis = h.axis();
  for (std::size_t i = 0; i < type.size(); ++i) {
    if (type[i] != "Rigid Body" || cell_of(name, i) != out.body) continue;
    if (cell_of(prop, i) == "Rotation") c.rot[cell_of(axis, i)] = i;
    if (cell_of(prop, i) == "Position") c.pos[cell_of(axis, i)] = i;
  }
  const std::vector<std::string> rot_axes = c.quat ? std::vector<std::string>{"X", "Y", "Z", "W"}
                                                   : std::vector<std::string>{"X", "Y", "Z"};
  for (const auto& a : rot_axes)
    if (!c.rot.count(a))
      throw InputError("rigid body \"" + out.body + "\" has no Rotation " + a + " column", {src, h.axis_line});
  for (const auto& a : {"X", "Y", "Z"})
    if (!c.pos.count(a))
      throw InputError("rigid body \"" + out.body + "\" has no Position " + std::string(a) + " column", {src, h.axis_line});
  out.length_unit = h.info_or("Length Units", "");
  c.scale = length_scale(out.length_unit, src, 1, out.warnings);  // "Length Units" is on line 1
  const std::string rate_key = h.info.count("Export Frame Rate") ? "Export Frame Rate" : "Capture Frame Rate";
  if (h.info.count("Capture Start Time")) out.capture_start_time = h.info.at("Capture Start Time");
  if (h.info.count(rate_key)) {
    const auto v = parse_seconds_ns(h.info.at(rate_key));  // a decimal number; reuse the exact parser
    if (v) out.rate_hz = static_cast<double>(*v) * 1e-9;
  }
  return c;
}

/// The body's pose in one data row.
Pose motive_pose(const CsvReader& r, const MotiveColumns& c) {
  Eigen::Quaterniond q;
  if (c.quat) {
    q = checked_unit(r,
                     Eigen::Quaterniond(r.get_double(c.rot.at("W")), r.get_double(c.rot.at("X")),
                                        r.get_double(c.rot.at("Y")), r.get_double(c.rot.at("Z"))),
                     c.rot.at("X"));
  } else {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    for (char a : c.euler_order) R = R * axis_rotation(a, r.get_double(c.rot.at(std::string(1, a))) * kDeg);
    q = Eigen::Quaterniond(R);
  }
  const Eigen::Vector3d p(r.get_double(c.pos.at("X")), r.get_double(c.pos.at("Y")), r.get_double(c.pos.at("Z")));
  return Pose(q, p * c.scale);
}

/// The data rows. Motive may end a row early when its last cells are empty (occluded markers), so a
/// short row is read as occlusion; only a short last line without its line end says that the file
/// itself was cut (an export or copy interrupted): that row is dropped, since its last cell may be a
/// number cut short ("0.0764" → "0.").
void read_motive_rows(CsvReader& r, const MotiveHeader& h, const MotiveColumns& c, const std::string& src,
                      MocapData& out) {
  bool have_prev = false;
  Timestamp prev = 0;
  std::size_t last_cells = 0;
  std::int64_t last_line = 0;
  bool last_occluded = false;
  bool last_unterminated = false;
  const std::size_t time_col = h.time_col;
  while (r.next()) {
    if (r.size() == 0) continue;
    last_cells = r.size();
    last_unterminated = r.row_unterminated();
    last_line = r.line();
    last_occluded = false;
    ++out.rows;
    (void)r.get_int64(0);  // the frame number must be an integer
    if (cell_empty(r, time_col)) throw r.error(time_col, "empty time cell");
    const auto t = parse_seconds_ns(r.field(time_col));
    if (!t) throw r.error(time_col, "time is not a number: \"" + std::string(r.field(time_col)) + "\"");
    check_time(r, time_col, *t, have_prev, prev);
    have_prev = true;
    prev = *t;
    bool missing = false;
    for (const auto& [a, col] : c.rot) missing = missing || cell_empty(r, col);
    for (const auto& [a, col] : c.pos) missing = missing || cell_empty(r, col);
    if (missing) {
      ++out.occluded;
      last_occluded = true;
      continue;
    }
    out.poses.push_back({*t, motive_pose(r, c)});
  }
  if (out.rows > 0 && last_cells < h.axis().size() && last_unterminated) {
    if (last_occluded)
      --out.occluded;
    else
      out.poses.pop_back();
    --out.rows;
    out.warnings.push_back(fmt::format("{}:{}: the last row has {} of {} cells and no line end: the file looks "
                                       "truncated; that row was dropped",
                                       src, last_line, last_cells, h.axis().size()));
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Motive
// ---------------------------------------------------------------------------------------------
MocapData read_motive_csv(const fs::path& file, const std::string& body) {
  MocapData out;
  out.format = "motive";
  out.y_up = true;
  CsvReader r(file, export_csv_options());
  const std::string src = file.string();
  const MotiveHeader h = read_motive_header(r, src, out.warnings);
  choose_motive_body(h, body, src, out);
  const MotiveColumns c = motive_columns(h, src, out);
  read_motive_rows(r, h, c, src, out);
  if (out.rows == 0) throw InputError("the Motive file has no data rows", {src});
  return out;
}

// ---------------------------------------------------------------------------------------------
// Vicon
// ---------------------------------------------------------------------------------------------
namespace {

constexpr const char* kViconSections[] = {"Objects", "Segments", "Trajectories", "Devices", "Joints", "Model Outputs"};

/// The head of a Vicon export's Objects (Tracker) or Segments (Nexus) section: rate, names, columns, units.
struct ViconSection {
  std::vector<std::string> names, cols, units;
  std::int64_t cols_line = 0, units_line = 0;
};

ViconSection read_vicon_section(CsvReader& r, const std::string& src, MocapData& out) {
  bool found = false;  // the first Objects/Segments section
  while (r.next()) {
    if (r.size() >= 1 && (r.field(0) == "Objects" || r.field(0) == "Segments")) {
      found = true;
      break;
    }
  }
  if (!found)
    throw InputError("no \"Objects\" (Tracker) or \"Segments\" (Nexus) section with rigid-body poses", {src});
  if (!r.next()) throw InputError("truncated Vicon section (no rate row)", {src, r.line()});
  out.rate_hz = r.get_double(0);
  if (!(out.rate_hz > 0)) throw r.error(0, "frame rate must be > 0");
  if (!r.next()) throw InputError("truncated Vicon section (no names row)", {src, r.line()});
  ViconSection v;
  std::size_t transcoded = 0;
  v.names = row_strings(r, &transcoded);
  if (transcoded)
    out.warnings.push_back(fmt::format("{} name cell(s) are not UTF-8: read as Latin-1 (the Windows code page)",
                                       transcoded));
  if (!r.next()) throw InputError("truncated Vicon section (no column row)", {src, r.line()});
  v.cols = row_strings(r);
  v.cols_line = r.line();
  if (v.cols.empty() || v.cols[0] != "Frame") throw r.error(0, "expected the column row \"Frame,Sub Frame,RX,...\"");
  if (!r.next()) throw InputError("truncated Vicon section (no units row)", {src, r.line()});
  v.units = row_strings(r);
  v.units_line = r.line();
  return v;
}

/// One body's RX RY RZ TX TY TZ columns, from `c0`.
struct ViconGroup {
  std::string name;
  std::size_t c0;
};

/// The section's bodies into `out.bodies`; the chosen one (--body by its exact name, else a
/// "Subject:Segment" by its segment, which must then be unique: Nexus subjects built on one model share
/// segment names) into `out.body`.
ViconGroup choose_vicon_group(const ViconSection& v, const std::string& body, const std::string& src, MocapData& out) {
  std::vector<ViconGroup> groups;
  const auto& cols = v.cols;
  for (std::size_t i = 0; i + 5 < cols.size(); ++i)
    if (cols[i] == "RX" && cols[i + 1] == "RY" && cols[i + 2] == "RZ" && cols[i + 3] == "TX" && cols[i + 4] == "TY" &&
        cols[i + 5] == "TZ") {
      std::string n = i < v.names.size() ? v.names[i] : "";
      // "Global Angle obj:obj" (Tracker) or "Subject:Segment" (Nexus): keep the part after ':' when
      // both halves are equal, else the whole label without the "Global Angle " prefix.
      if (n.rfind("Global Angle ", 0) == 0) n = n.substr(13);
      const std::size_t colon = n.find(':');
      if (colon != std::string::npos && n.substr(0, colon) == n.substr(colon + 1)) n = n.substr(0, colon);
      groups.push_back({n, i});
      out.bodies.push_back(n);
    }
  if (groups.empty()) throw InputError("no RX,RY,RZ,TX,TY,TZ column group in the Vicon section", {src, v.cols_line});
  const ViconGroup* g = nullptr;
  if (body.empty()) {
    if (groups.size() > 1) refuse_body(body, out.bodies, "object", "objects", src);
    g = &groups.front();
  } else {
    std::vector<const ViconGroup*> by_segment;
    for (const auto& gr : groups) {
      if (gr.name == body) g = &gr;
      if (gr.name.size() > body.size() &&
          gr.name.compare(gr.name.size() - body.size() - 1, std::string::npos, ":" + body) == 0)
        by_segment.push_back(&gr);
    }
    if (!g && by_segment.size() > 1) {
      std::vector<std::string> names;
      for (const ViconGroup* gr : by_segment) names.push_back(gr->name);
      throw InputError("object \"" + body + "\" matches several objects; choose one with --body:" + quoted_list(names),
                       {src});
    }
    if (!g && !by_segment.empty()) g = by_segment.front();
    if (!g) refuse_body(body, out.bodies, "object", "objects", src);
  }
  out.body = g->name;
  return *g;
}

/// The data rows up to the next section; frame numbers become time from the first frame at the
/// section's rate.
void read_vicon_rows(CsvReader& r, const ViconSection& v, const ViconGroup& g, double rot_scale, double len_scale,
                     const std::string& src, MocapData& out) {
  bool have_first = false, have_prev = false;
  std::int64_t first_frame = 0;
  Timestamp prev = 0;
  while (r.next()) {
    if (r.size() == 0) continue;
    const std::string first(r.field(0));
    if (std::any_of(std::begin(kViconSections), std::end(kViconSections),
                    [&](const char* k) { return first == k; }))
      break;  // next section
    if (r.row_unterminated() && r.size() < v.cols.size()) {  // as Motive's: the file was cut in this row
      out.warnings.push_back(fmt::format("{}:{}: the last row has {} of {} cells and no line end: the file looks "
                                         "truncated; that row was dropped",
                                         src, r.line(), r.size(), v.cols.size()));
      break;
    }
    ++out.rows;
    const std::int64_t frame = r.get_int64(0);
    // A frame counter, not a stamp: 10^12 frames are 300 years at 100 Hz; beyond that the difference
    // to the first frame could overflow.
    if (frame < 0 || frame > 1'000'000'000'000) throw r.error(0, "frame number out of range (0 to 10^12)");
    if (!have_first) {
      first_frame = frame;
      have_first = true;
    }
    const Timestamp t = from_seconds(static_cast<double>(frame - first_frame) / out.rate_hz);
    check_time(r, 0, t, have_prev, prev);
    have_prev = true;
    prev = t;
    bool missing = false;
    for (std::size_t k = 0; k < 6; ++k) missing = missing || cell_empty(r, g.c0 + k);
    if (missing) {
      ++out.occluded;
      continue;
    }
    const Eigen::Vector3d rv(r.get_double(g.c0), r.get_double(g.c0 + 1), r.get_double(g.c0 + 2));
    const Eigen::Vector3d p(r.get_double(g.c0 + 3), r.get_double(g.c0 + 4), r.get_double(g.c0 + 5));
    out.poses.push_back({t, Pose(math::exp_quat(rv * rot_scale), p * len_scale)});
  }
}

}  // namespace

MocapData read_vicon_csv(const fs::path& file, const std::string& body) {
  MocapData out;
  out.format = "vicon";
  out.rotation_type = "helical";
  CsvReader r(file, export_csv_options());
  const std::string src = file.string();
  const ViconSection v = read_vicon_section(r, src, out);
  const ViconGroup g = choose_vicon_group(v, body, src, out);
  auto unit_at = [&](std::size_t i) { return i < v.units.size() ? lower(v.units[i]) : std::string(); };
  const std::string ru = unit_at(g.c0);
  const double rot_scale = ru == "rad" ? 1.0 : ru == "deg" || ru.empty() ? kDeg : -1.0;
  if (rot_scale < 0) throw InputError("unknown rotation unit \"" + ru + "\" (deg or rad)", {src, v.units_line});
  if (ru.empty()) out.warnings.push_back("no rotation unit: assuming degrees");
  out.length_unit = unit_at(g.c0 + 3).empty() ? "mm" : unit_at(g.c0 + 3);
  const double len_scale = length_scale(out.length_unit, src, v.units_line, out.warnings);
  read_vicon_rows(r, v, g, rot_scale, len_scale, src, out);
  if (out.rows == 0) throw InputError("the Vicon section has no data rows", {src});
  return out;
}

}  // namespace roe::io
