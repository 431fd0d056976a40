#include "roe/io/evo_result.hpp"

#include <fmt/format.h>

#include <cmath>
#include <map>

#include "roe/core/error.hpp"
#include "roe/eval/align.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/io/zip.hpp"

namespace roe::io {
namespace fs = std::filesystem;
namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

nlohmann::json object_member(const ZipMember& m, const std::string& source) {
  const std::string where = source + ":" + m.name;
  nlohmann::json j = parse_json_text(m.data, where);
  if (!j.is_object()) throw InputError("is not a JSON object", {where});
  return j;
}

}  // namespace

const NpyArray* EvoResult::array(const std::string& name) const {
  for (const auto& [n, a] : arrays)
    if (n == name) return &a;
  return nullptr;
}

bool looks_like_zip(const fs::path& file) {
  // A local file header, or the end-of-central-directory record that alone makes an empty archive.
  const std::string head = read_file_head(file, 4);
  return head == std::string("PK\x03\x04", 4) || head == std::string("PK\x05\x06", 4);
}

EvoResult read_evo_result(const fs::path& zip) {
  const std::string source = zip.string();
  const std::vector<ZipMember> members = read_zip(read_file(zip), source);
  EvoResult r;
  bool info = false, stats = false;
  for (const auto& m : members) {
    if (m.name == "info.json") {
      r.info = object_member(m, source);
      info = true;
    } else if (m.name == "stats.json") {
      r.stats = object_member(m, source);
      for (const auto& [k, v] : r.stats.items())
        if (!v.is_number()) throw InputError("statistic is not a number", {source + ":stats.json", 0, 0, k});
      stats = true;
    } else if (ends_with(m.name, ".npy") || ends_with(m.name, ".npz")) {
      r.arrays.emplace_back(m.name.substr(0, m.name.size() - 4), parse_npy(m.data, source + ":" + m.name));
    } else if (ends_with(m.name, ".tum") || ends_with(m.name, ".kitti")) {
      r.trajectories.emplace_back(m.name, m.data);
    }
  }
  if (!info || !stats)
    throw InputError(std::string("not an evo result file: it has no ") + (info ? "stats.json" : "info.json") +
                         " (evo_ape/evo_rpe --save_results write both)",
                     {source});
  return r;
}

namespace {

/// evo's title for the alignment of the report (main_ape.py, main_rpe.py): `t` and the alignment.
std::string evo_title(const eval::Report& rep, std::string t = "APE w.r.t. translation part (m)") {
  const std::string a = eval::to_string(rep.align_type());
  if (a == "se3") t += "\n(with SE(3) Umeyama alignment)";
  else if (a == "sim3") t += "\n(with Sim(3) Umeyama alignment)";
  else if (a == "origin") t += "\n(with origin alignment)";
  else if (a == "none") t += "\n(not aligned)";
  else t += "\n(with " + a + " alignment)";
  if (rep.params.n_align > 0 && (a == "se3" || a == "sim3"))
    t += " (aligned poses: " + std::to_string(rep.params.n_align) + ")";
  return t;
}

/// Cumulative path length along the poses, from 0.
std::vector<double> distances(std::size_t n, const std::function<Eigen::Vector3d(std::size_t)>& p) {
  std::vector<double> d(n, 0.0);
  for (std::size_t k = 1; k < n; ++k) d[k] = d[k - 1] + (p(k) - p(k - 1)).norm();
  return d;
}

/// Python's str() of a float as evo prints the delta: 10.0, 0.5.
std::string python_float(double v) {
  return v == std::floor(v) && std::abs(v) < 1e16 ? fmt::format("{:.1f}", v) : fmt::format("{}", v);
}

/// evo's stats.json of the values (evo.core.metrics: population std).
nlohmann::json stats_json(const eval::Stats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std},
          {"min", s.min},   {"max", s.max},   {"sse", s.sse}};
}

/// evo's alignment_transformation_sim3 ([sR t; 0 1]), absent when nothing was aligned.
void add_alignment(const eval::Report& rep, EvoResult& r) {
  if (rep.alignment.type == eval::AlignType::kNone) return;
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = rep.alignment.s * rep.alignment.R;
  T.topRightCorner<3, 1>() = rep.alignment.t;
  std::vector<double> m(16);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) m[static_cast<std::size_t>(4 * i + j)] = T(i, j);
  r.arrays.emplace_back("alignment_transformation_sim3", NpyArray::float64({4, 4}, m));
}

}  // namespace

EvoResult evo_rpe_result(const eval::Report& rep, std::size_t block, bool stamped, const std::string& ref_name,
                         const std::string& est_name) {
  const eval::RpeResult& e = rep.rpe.at(block);
  const eval::RpeOptions& o = e.options;
  static const std::map<eval::DeltaUnit, const char*> kUnit = {{eval::DeltaUnit::kMeters, "m"},
                                                                {eval::DeltaUnit::kFrames, "frames"},
                                                                {eval::DeltaUnit::kDegrees, "deg"},
                                                                {eval::DeltaUnit::kRadians, "rad"},
                                                                {eval::DeltaUnit::kSeconds, "s"}};
  EvoResult r;
  r.info = {{"title", evo_title(rep, fmt::format("RPE w.r.t. translation part (m)\nfor delta = {} ({}) using {} pairs",
                                                 python_float(o.delta), kUnit.at(o.unit),
                                                 o.all_pairs ? "all" : "consecutive"))},
            {"ref_name", ref_name},
            {"est_name", est_name},
            {"label", "RPE (m)"}};
  r.stats = stats_json(e.trans_m);
  const std::size_t n = e.pairs.size();
  const auto N = static_cast<std::int64_t>(n);
  std::vector<double> err(n);
  for (std::size_t k = 0; k < n; ++k) err[k] = e.pairs[k].trans_m;
  r.arrays.emplace_back("error_array", NpyArray::float64({N}, err));
  if (stamped && n > 0) {
    // evo reduces both trajectories to [0] + every pair's j and takes the values at the j's.
    std::vector<std::size_t> ids{0};
    for (const eval::RpePair& p : e.pairs) ids.push_back(p.j);
    std::vector<double> t0(n), t(n);
    for (std::size_t k = 0; k < n; ++k) t[k] = to_seconds(rep.t_est(ids[k + 1])), t0[k] = t[k] - to_seconds(rep.t_est(0));
    const auto along = [&](bool est) {
      std::vector<double> d = distances(ids.size(), [&](std::size_t k) {
        return est ? rep.est_aligned(ids[k]).p : rep.gt(ids[k]).p;
      });
      return std::vector<double>(d.begin() + 1, d.end());
    };
    r.arrays.emplace_back("seconds_from_start", NpyArray::float64({N}, t0));
    r.arrays.emplace_back("timestamps", NpyArray::float64({N}, t));
    r.arrays.emplace_back("distances_from_start", NpyArray::float64({N}, along(false)));
    r.arrays.emplace_back("distances", NpyArray::float64({N}, along(true)));
  }
  add_alignment(rep, r);
  return r;
}

EvoResult evo_ape_result(const eval::Report& rep, const std::string& ref_name, const std::string& est_name) {
  const std::size_t n = rep.n_pairs();
  const auto N = static_cast<std::int64_t>(n);
  EvoResult r;
  r.info = {{"title", evo_title(rep)}, {"ref_name", ref_name}, {"est_name", est_name}, {"label", "APE (m)"}};
  r.stats = stats_json(rep.ape.trans_m);
  std::vector<double> err(n), t(n), t0(n);
  for (std::size_t k = 0; k < n; ++k) {
    err[k] = rep.error(k).dp.norm();
    t[k] = to_seconds(rep.t_est(k));
    t0[k] = t[k] - t[0];
  }
  r.arrays.emplace_back("error_array", NpyArray::float64({N}, err));
  r.arrays.emplace_back("seconds_from_start", NpyArray::float64({N}, t0));
  r.arrays.emplace_back("timestamps", NpyArray::float64({N}, t));
  r.arrays.emplace_back("distances_from_start",
                        NpyArray::float64({N}, distances(n, [&](std::size_t k) { return rep.gt(k).p; })));
  r.arrays.emplace_back("distances",
                        NpyArray::float64({N}, distances(n, [&](std::size_t k) { return rep.est_aligned(k).p; })));
  add_alignment(rep, r);
  const auto tum = [&](bool est) {
    return format_trajectory(n, [&](std::size_t k) {
      return StampedPose{est ? rep.t_est(k) : rep.t_gt(k), est ? rep.est_aligned(k) : rep.gt(k)};
    }, TrajectoryFormat::kTum);
  };
  // evo names the members after the paths as given (info.json keeps them so); a ZIP member name is relative
  // and stays inside the archive (APPNOTE 4.4.17), so an absolute path or one with ".." gives its file name.
  const auto member = [](const std::string& path) {
    const fs::path p(path);
    bool dotdot = false;
    for (const auto& part : p) dotdot = dotdot || part == "..";
    return (p.is_absolute() || dotdot ? p.filename().string() : path) + ".tum";
  };
  r.trajectories.emplace_back(member(ref_name), tum(false));
  r.trajectories.emplace_back(member(est_name), tum(true));
  return r;
}

void write_evo_result(const fs::path& zip, const EvoResult& r) {
  std::vector<ZipMember> members;
  members.push_back({"info.json", dump_json(r.info)});
  members.push_back({"stats.json", dump_json(r.stats)});
  for (const auto& [name, a] : r.arrays) members.push_back({name + ".npy", encode_npy(a)});
  for (const auto& [name, text] : r.trajectories) members.push_back({name, text});
  write_file_atomic(zip, write_zip(members));
}

}  // namespace roe::io
