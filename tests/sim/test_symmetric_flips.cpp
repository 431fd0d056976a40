// The simulator's symmetric flips use the symmetry definitions the filter uses (core/symmetry.hpp): a
// flipped detection is exactly a symmetry-equivalent pose T_C_O · S of the truth, so the filter's nearest
// equivalent (ekf::nearest_equivalent) maps it back to the truth, and with the ordinary errors on top its
// residual is zero-mean with the configured σ.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "roe/app/simulate.hpp"
#include "roe/store/dataset.hpp"

#include "roe/ekf/symmetry.hpp"
#include "roe/math/so3.hpp"
#include "roe/sim/detection_model.hpp"
#include "detection_support.hpp"

using namespace roe;
using namespace roe::sim;
using math::exp_quat;
using roe::sim::test::gaussian_only;

namespace {

// S = (R, o − R o): a rotation about the line through o (model frame), as BOP writes them (mm → m done).
Pose about_point(const Eigen::Vector3d& rotvec, const Eigen::Vector3d& o) {
  const Eigen::Quaterniond q = exp_quat(rotvec);
  return Pose(q, o - q * o);
}

struct Case {
  const char* name;
  ObjectSymmetry sym;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  out.push_back({"YCB-V default two-fold (16)", ycbv_symmetry(16)});
  out.push_back({"YCB-V default continuous (13)", ycbv_symmetry(13)});
  // A four-fold box whose axis does not pass through the model origin: three discrete transforms.
  ObjectSymmetry box;
  const Eigen::Vector3d o(0.012, -0.02, 0.0);
  for (int k = 1; k <= 3; ++k) box.discrete.push_back(about_point(k * M_PI / 2 * Eigen::Vector3d::UnitY(), o));
  out.push_back({"four-fold about an offset axis", box});
  // A body of revolution about a tilted axis through an offset point, with its end-for-end flip.
  ObjectSymmetry cyl;
  ContinuousSymmetry c;
  c.axis = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  c.offset = Eigen::Vector3d(0.01, 0.015, -0.005);
  cyl.continuous = c;
  cyl.discrete.push_back(about_point(M_PI * c.axis.cross(Eigen::Vector3d::UnitX()).normalized(), c.offset));
  out.push_back({"continuous about a tilted offset axis, with its flip", cyl});
  return out;
}

const Pose kTruth(exp_quat(Eigen::Vector3d(0.4, -0.7, 0.25)), Eigen::Vector3d(0.12, -0.08, 1.3));

}  // namespace

TEST_CASE("flip_transform draws the members of the symmetry group uniformly", "[sim][symmetry]") {
  ObjectSymmetry box = cases()[2].sym;
  for (int j = 0; j < 3; ++j) {
    const Pose S = flip_transform(box, (j + 0.5) / 3.0, 0.0);
    CHECK(math::pose_difference(S, box.discrete[j]).norm() < 1e-15);
  }
  ObjectSymmetry cyl = cases()[3].sym;
  const ContinuousSymmetry& c = *cyl.continuous;
  // u < 1/2: the turn alone; u ≥ 1/2: the flip after the turn. Every S(ψ) fixes the points of the axis.
  const Eigen::Vector3d on_axis = c.offset + 0.07 * c.axis;
  for (double u : {0.1, 0.7}) {
    const Pose S = flip_transform(cyl, u, 1.1);
    const Pose turn = u < 0.5 ? S : cyl.discrete[0].inverse() * S;
    CHECK((turn.act(on_axis) - on_axis).norm() < 1e-15);
    CHECK(math::log_quat(turn.q).normalized().dot(c.axis) == Approx(1.0).epsilon(1e-12));
    CHECK(math::log_quat(turn.q).norm() == Approx(1.1).epsilon(1e-12));
  }
}

TEST_CASE("a simulated flip is exactly a symmetry-equivalent pose of the truth", "[sim][symmetry]") {
  DetectionNoiseConfig cfg = gaussian_only();
  cfg.symmetric_flip_prob = 1.0;  // every detection of the symmetric object flips
  cfg.lateral_sigma_m = cfg.lateral_sigma_per_depth = 0.0;
  cfg.along_ray_sigma_m = cfg.along_ray_sigma_per_depth = 0.0;
  cfg.rotation_sigma_deg = cfg.rotation_sigma_per_depth_deg = 0.0;
  for (const Case& k : cases()) {
    INFO(k.name);
    PoetErrorModel model(cfg, {{7, k.sym}});
    Rng rng(5);
    const Pose z_true = kTruth.inverse();  // the filter's measurement z = T_O_C
    double farthest = 0.0;
    for (int i = 0; i < 200; ++i) {
      DetectionLabel label;
      const Detection d = model.measure(i * 33'000'000LL, 7, kTruth, false, rng, &label);
      REQUIRE(label.flipped);
      // The filter's nearest equivalent of the detection is the truth itself.
      const Pose back = ekf::nearest_equivalent(z_true, d.T_C_O.inverse(), k.sym);
      REQUIRE(math::pose_difference(back, z_true).norm() < 1e-9);
      farthest = std::max(farthest, math::angle_between(d.T_C_O.q, kTruth.q));
    }
    CHECK(farthest > 0.5);  // and the detections were not the truth
  }
}

TEST_CASE("with the ordinary errors the nearest-equivalent residual of flipped detections is zero-mean",
          "[sim][symmetry]") {
  DetectionNoiseConfig cfg = gaussian_only();
  cfg.symmetric_flip_prob = 1.0;
  cfg.translation_frame = "camera";
  cfg.rotation_sigma_per_depth_deg = 0.0;
  const double s_rot = cfg.rotation_sigma_deg * M_PI / 180.0;
  const int n = 4000;
  for (const Case& k : cases()) {
    INFO(k.name);
    PoetErrorModel model(cfg, {{7, k.sym}});
    Rng rng(17);
    const Pose z_true = kTruth.inverse();
    Eigen::Vector3d sum_t = Eigen::Vector3d::Zero(), sum_r = Eigen::Vector3d::Zero();
    Eigen::Vector3d sq_t = Eigen::Vector3d::Zero(), sq_r = Eigen::Vector3d::Zero();
    for (int i = 0; i < n; ++i) {
      const Detection d = model.measure(i * 33'000'000LL, 7, kTruth, false, rng);
      // Residual of the detection against the truth after the filter's choice of equivalent, as T_C_O.
      const Pose back = ekf::nearest_equivalent(z_true, d.T_C_O.inverse(), k.sym).inverse();
      const Eigen::Vector3d et = back.p - kTruth.p;
      const Eigen::Vector3d er = math::log_quat(kTruth.q.conjugate() * back.q);
      sum_t += et;
      sum_r += er;
      sq_t += et.cwiseProduct(et);
      sq_r += er.cwiseProduct(er);
    }
    const Eigen::Vector3d mt = sum_t / n, mr = sum_r / n;
    const Eigen::Vector3d rms_t = (sq_t / n).cwiseSqrt(), rms_r = (sq_r / n).cwiseSqrt();
    INFO("mean t " << mt.transpose() << " rms t " << rms_t.transpose() << " mean r " << mr.transpose()
                   << " rms r " << rms_r.transpose());
    for (int a = 0; a < 3; ++a) {
      // Zero mean: within 4 standard errors (the flips add no bias).
      CHECK(std::abs(mt(a)) < 4.0 * rms_t(a) / std::sqrt(double(n)));
      CHECK(std::abs(mr(a)) < 4.0 * s_rot / std::sqrt(double(n)));
    }
    // The translation error is the configured one (camera axes); the rotation error at most σ per axis
    // (a continuous symmetry's alignment removes the part about the axis, nothing else).
    const Eigen::Vector3d s_t(cfg.lateral_sigma_m + cfg.lateral_sigma_per_depth * kTruth.p.z(),
                              cfg.lateral_sigma_m + cfg.lateral_sigma_per_depth * kTruth.p.z(),
                              cfg.along_ray_sigma_m + cfg.along_ray_sigma_per_depth * kTruth.p.z());
    for (int a = 0; a < 3; ++a) {
      CHECK(rms_t(a) == Approx(s_t(a)).epsilon(0.08));
      CHECK(rms_r(a) < 1.08 * s_rot);
    }
    if (!k.sym.continuous)
      for (int a = 0; a < 3; ++a) CHECK(rms_r(a) == Approx(s_rot).epsilon(0.08));
  }
}

TEST_CASE("roe simulate --models-info describes the flips' symmetries for the filter, nothing else changes",
          "[sim][symmetry]") {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / "roe_test_sim_models_info";
  fs::remove_all(root);
  app::SimulateOptions opt;
  opt.preset = "paper-seq2";  // objects 13 (continuous) and 19 (two-fold) among them
  opt.duration_s = 3.0;
  app::simulate(opt, root / "plain");
  opt.models_info = true;
  app::simulate(opt, root / "described");
  const DatasetManifest plain = store::read_manifest(root / "plain");
  const DatasetManifest described = store::read_manifest(root / "described");  // reads models_info.json back
  REQUIRE(plain.objects.size() == described.objects.size());
  int symmetric = 0;
  for (std::size_t i = 0; i < plain.objects.size(); ++i) {
    const ObjectInfo& a = plain.objects[i];
    const ObjectInfo& b = described.objects[i];
    INFO("object " << b.id);
    CHECK(a.models_info.empty());
    CHECK(a.symmetry.empty());
    CHECK(b.symmetric == a.symmetric);
    if (!b.symmetric) {
      CHECK(b.models_info.empty());
      continue;
    }
    ++symmetric;
    CHECK(b.models_info == "models_info.json");
    const ObjectSymmetry want = simulated_symmetry(b.id);
    REQUIRE(b.symmetry.discrete.size() == want.discrete.size());
    for (std::size_t k = 0; k < want.discrete.size(); ++k)
      CHECK(math::pose_difference(b.symmetry.discrete[k], want.discrete[k]).norm() < 1e-12);
    REQUIRE(b.symmetry.continuous.has_value() == want.continuous.has_value());
    if (want.continuous) CHECK((b.symmetry.continuous->axis - want.continuous->axis).norm() < 1e-15);
  }
  CHECK(symmetric >= 2);
  // The detections are the same bytes: the flag only describes them.
  const auto bytes = [](const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    std::ostringstream ss;
    ss << f.rdbuf();
    return ss.str();
  };
  const std::string d = "detections/sim/detections.csv";
  CHECK(bytes(root / "plain" / d) == bytes(root / "described" / d));
  CHECK(!bytes(root / "plain" / d).empty());
  fs::remove_all(root);
}
