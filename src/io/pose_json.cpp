// The JSON forms of a Pose (io/pose_json.hpp).
#include "roe/io/pose_json.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <vector>

namespace roe::io {

Eigen::Quaterniond unit_quaternion(const Eigen::Quaterniond& q) {
  if (std::abs(q.squaredNorm() - 1.0) <= 4.0 * std::numeric_limits<double>::epsilon()) return q;
  return q.normalized();
}

json pose_to_json(const Pose& T) {
  return json{{"p", {T.p.x(), T.p.y(), T.p.z()}}, {"q", {T.q.x(), T.q.y(), T.q.z(), T.q.w()}}};
}

namespace {

// A fixed-length array of numbers at `key` of `o`; empty when absent and not `required`.
std::vector<double> number_array(JsonObject& o, const char* key, std::size_t n, bool required) {
  const json* v = o.raw(key);
  const std::string path = o.key_path(key);
  if (!v || v->is_null()) {
    if (required) throw ConfigError("missing required key", {o.source(), 0, 0, path});
    return {};
  }
  if (!v->is_array() || v->size() != n)
    throw ConfigError(fmt::format("expected an array of {} numbers", n), {o.source(), 0, 0, path});
  std::vector<double> out;
  for (std::size_t i = 0; i < n; ++i) {
    if (!(*v)[i].is_number())
      throw ConfigError("expected a number", {o.source(), 0, 0, fmt::format("{}[{}]", path, i)});
    out.push_back((*v)[i].get<double>());
  }
  return out;
}

}  // namespace

Pose pose_from_json(const json& j, const std::string& source, const std::string& key_path, const PoseJsonRead& read) {
  JsonObject o(j, source, key_path);
  const bool required = read.base == nullptr;
  const auto p = number_array(o, "p", 3, required);
  const auto qv = number_array(o, "q", 4, required);
  o.finish();
  Pose T = read.base ? *read.base : Pose();
  if (!p.empty()) T.p = Eigen::Vector3d(p[0], p[1], p[2]);
  if (!qv.empty()) {
    const Eigen::Quaterniond q(qv[3], qv[0], qv[1], qv[2]);
    const double n = q.norm();
    if (!(std::abs(n - 1.0) <= read.quat_tol))
      throw ConfigError(fmt::format("quaternion [qx, qy, qz, qw] is not unit norm (|q| = {:.12g}, tolerance {:g})",
                                    n, read.quat_tol),
                        {source, 0, 0, o.key_path("q")});
    T.q = unit_quaternion(q);
  }
  return T;
}

}  // namespace roe::io
