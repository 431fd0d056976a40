#include "roe/io/models_info.hpp"

#include <fmt/format.h>

#include "roe/io/output.hpp"

#include <cmath>
#include <vector>

namespace roe::io {

namespace {

/// A JSON array of n finite numbers at `path`.
std::vector<double> numbers(const json& v, std::size_t n, const std::string& source, const std::string& path) {
  if (!v.is_array() || v.size() != n)
    throw ConfigError(fmt::format("expected an array of {} numbers", n), {source, 0, 0, path});
  std::vector<double> out;
  for (std::size_t i = 0; i < n; ++i) {
    if (!v[i].is_number() || !std::isfinite(v[i].get<double>()))
      throw ConfigError("expected a finite number", {source, 0, 0, fmt::format("{}[{}]", path, i)});
    out.push_back(v[i].get<double>());
  }
  return out;
}

Pose discrete_transform(const json& v, const std::string& source, const std::string& path) {
  const std::vector<double> a = numbers(v, 16, source, path);
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = a[4 * r + c];
  if (a[12] != 0.0 || a[13] != 0.0 || a[14] != 0.0 || a[15] != 1.0)
    throw ConfigError("the last row of a 4x4 transform must be 0 0 0 1", {source, 0, 0, path});
  const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (err > 1e-4 || R.determinant() < 0.0)
    throw ConfigError(fmt::format("not a rotation (|RᵀR − I| = {:.2g}, det {:.4g})", err, R.determinant()),
                      {source, 0, 0, path});
  // mm → m; the rotation re-orthonormalised through its quaternion (Pose normalises it).
  return Pose(Eigen::Quaterniond(R), Eigen::Vector3d(a[3], a[7], a[11]) * 1e-3);
}

ObjectSymmetry object_entry(const json& e, const std::string& source, const std::string& path) {
  JsonObject o(e, source, path);
  double ignored = 0.0;
  for (const char* k : {"diameter", "min_x", "min_y", "min_z", "size_x", "size_y", "size_z"}) o.get(k, ignored);
  ObjectSymmetry s;
  if (const json* d = o.raw("symmetries_discrete"); d && !d->is_null()) {
    if (!d->is_array()) throw ConfigError("expected an array", {source, 0, 0, o.key_path("symmetries_discrete")});
    for (std::size_t i = 0; i < d->size(); ++i)
      s.discrete.push_back(
          discrete_transform((*d)[i], source, fmt::format("{}[{}]", o.key_path("symmetries_discrete"), i)));
  }
  if (const json* c = o.raw("symmetries_continuous"); c && !c->is_null()) {
    const std::string cp = o.key_path("symmetries_continuous");
    if (!c->is_array()) throw ConfigError("expected an array", {source, 0, 0, cp});
    if (c->size() > 1)
      throw ConfigError("more than one continuous symmetry (a sphere-like object) is not supported",
                        {source, 0, 0, cp + "[1]"});
    if (c->size() == 1) {
      const std::string ep = cp + "[0]";
      JsonObject co((*c)[0], source, ep);
      const json* axis = co.raw("axis");
      const json* offset = co.raw("offset");
      if (!axis) throw ConfigError("missing required key", {source, 0, 0, ep + ".axis"});
      if (!offset) throw ConfigError("missing required key", {source, 0, 0, ep + ".offset"});
      const std::vector<double> a = numbers(*axis, 3, source, ep + ".axis");
      const std::vector<double> off = numbers(*offset, 3, source, ep + ".offset");
      co.finish();
      ContinuousSymmetry cs;
      cs.axis = Eigen::Vector3d(a[0], a[1], a[2]);
      if (!(cs.axis.norm() > 1e-9)) throw ConfigError("the axis must not be zero", {source, 0, 0, ep + ".axis"});
      cs.axis.normalize();
      cs.offset = Eigen::Vector3d(off[0], off[1], off[2]) * 1e-3;
      s.continuous = cs;
    }
  }
  o.finish();
  return s;
}

}  // namespace

std::map<int, ObjectSymmetry> models_info_from_json(const json& j, const std::string& source) {
  if (!j.is_object()) throw ConfigError("expected a JSON object keyed by object id", {source, 1, 1, ""});
  std::map<int, ObjectSymmetry> out;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& key = it.key();
    int id = -1;
    const bool digits = !key.empty() && key.size() <= 9 && key.find_first_not_of("0123456789") == std::string::npos;
    if (digits) id = std::stoi(key);
    if (!digits) throw ConfigError("object ids must be non-negative decimal integers", {source, 0, 0, key});
    if (!it.value().is_object()) throw ConfigError("expected an object", {source, 0, 0, key});
    out[id] = object_entry(it.value(), source, key);
  }
  return out;
}

std::map<int, ObjectSymmetry> read_models_info(const std::filesystem::path& file) {
  return read_json_file(file, models_info_from_json);
}

json models_info_to_json(const std::map<int, ObjectSymmetry>& symmetries) {
  json out = json::object();
  const auto mm = [](const Eigen::Vector3d& v) { return json::array({v.x() * 1e3, v.y() * 1e3, v.z() * 1e3}); };
  for (const auto& [id, s] : symmetries) {
    json e = json::object();
    json disc = json::array();
    for (const Pose& S : s.discrete) {
      const Eigen::Matrix3d R = S.R();
      json row = json::array();
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) row.push_back(R(r, c));
        row.push_back(S.p(r) * 1e3);
      }
      for (double v : {0.0, 0.0, 0.0, 1.0}) row.push_back(v);
      disc.push_back(row);
    }
    if (!disc.empty()) e["symmetries_discrete"] = disc;
    if (s.continuous) e["symmetries_continuous"] = json::array({{{"axis", {s.continuous->axis.x(), s.continuous->axis.y(), s.continuous->axis.z()}},
                                                                  {"offset", mm(s.continuous->offset)}}});
    out[std::to_string(id)] = e;
  }
  return out;
}

void write_models_info(const std::filesystem::path& file, const std::map<int, ObjectSymmetry>& symmetries) {
  write_file_atomic(file, dump_json(models_info_to_json(symmetries), 2) + "\n");
}

}  // namespace roe::io
