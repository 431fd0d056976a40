// roe eval's detection σ calibration end to end: a dataset with simulated detections whose reported σ
// are half the true ones (errors drawn with σ_true = 2 · σ_reported), evaluated from a run folder that
// names the set (automatic) and with --detections; the error paths.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "roe/app/eval.hpp"
#include "roe/core/error.hpp"
#include "roe/eval/detection_calibration.hpp"
#include "roe/store/dataset.hpp"
#include "roe/store/run_record.hpp"
#include "roe/io/output.hpp"
#include "roe/io/trajectory_io.hpp"
#include "support/scaled_sigma_detections.hpp"

using namespace roe;
namespace fs = std::filesystem;

namespace {

struct SigmaFixture {
  fs::path root, dataset, run;
  explicit SigmaFixture(const std::string& name, double scale = 2.0, bool with_truth_objects = true) {
    root = fs::temp_directory_path() / ("roe_test_eval_sigmas_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(root);
    dataset = root / "ds";
    run = root / "run";
    Dataset d;
    d.manifest.name = "sigmas";
    CameraInfo cam;
    cam.width = 640;
    cam.height = 480;
    cam.fx = cam.fy = 500;
    cam.cx = 320;
    cam.cy = 240;
    cam.time_offset_s = 0.02;  // t_imu = t_cam + 0.02
    Eigen::Matrix3d R_I_C;     // optical axis = IMU x
    R_I_C << 0, 0, 1, -1, 0, 0, 0, -1, 0;
    cam.T_I_C = Pose(Eigen::Quaterniond(R_I_C), Eigen::Vector3d(0.03, 0.0, 0.01));
    d.manifest.camera = cam;
    Truth truth;
    truth.T_I_C = cam.T_I_C;
    const std::vector<TruthObject> objects = {
        {1, Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX())), Eigen::Vector3d(0.1, 0.0, 1.0))},
        {2, Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.1, 0.2, 0.8))}};
    if (with_truth_objects) truth.objects = objects;
    d.manifest.truth = truth;
    const Timestamp t0 = 1'000'000'000'000LL;
    for (int k = 0; k <= 3000; ++k) {  // 30 s at 100 Hz on a circle, looking at the centre
      const double a = 0.002 * k;
      ImuState s;
      s.t_ns = t0 + k * 10'000'000LL;
      const Eigen::Vector3d p(2.0 * std::cos(a), 2.0 * std::sin(a), 1.0);
      const Eigen::Vector3d x = (Eigen::Vector3d(0, 0, 0.9) - p).normalized();
      const Eigen::Vector3d z = x.cross(Eigen::Vector3d::UnitZ()).cross(x).normalized();
      Eigen::Matrix3d R;
      R << x, z.cross(x), z;
      s.T_W_I = Pose(Eigen::Quaterniond(R), p);
      d.groundtruth.push_back(s);
    }
    test::ScaledSigmaDetector detect(scale, 11);
    auto& dets = d.detections["sim"];
    for (std::size_t k = 5; k + 5 < d.groundtruth.size(); k += 5) {
      for (const auto& o : objects) {
        const Pose T_C_O = eval::true_T_C_O(d.groundtruth[k].T_W_I, truth.T_I_C, o.T_W_O);
        dets.push_back(detect(d.groundtruth[k].t_ns - 20'000'000LL, o.id, T_C_O));
      }
    }
    store::write_dataset(d, dataset, false);
    // A run folder: the true trajectory at 20 Hz and a run.json naming the dataset and the set.
    fs::create_directories(run);
    std::vector<Timestamp> t;
    std::vector<Pose> p;
    for (std::size_t k = 0; k < d.groundtruth.size(); k += 5) {
      t.push_back(d.groundtruth[k].t_ns);
      p.push_back(d.groundtruth[k].T_W_I);
    }
    io::write_trajectory(run / "trajectory.csv", t, p, io::TrajectoryFormat::kCsv);
    store::RunRecord rec;
    rec.inputs.dataset = dataset.string();
    rec.inputs.detections = "sim";
    store::write_run_json(run / "run.json", rec);
  }
  ~SigmaFixture() { fs::remove_all(root); }
};

}  // namespace

TEST_CASE("roe eval calibrates the detection sigmas of the set run.json names", "[app][eval][sigmas]") {
  SigmaFixture f("auto");
  app::EvalOptions o;
  o.est = f.run.string();
  o.force = true;
  const app::EvalResult r = app::run_eval(o);
  const auto d = r.report_json()["detection_calibration"];
  REQUIRE(d.is_object());
  CHECK(d["n_evaluated"] == 2 * 599);
  const double s = d["all"]["sigma_scale"].get<double>();
  CHECK(std::abs(s / 2.0 - 1.0) < 0.2);  // the criterion; 1198 detections give ~2 %
  CHECK(std::abs(s / 2.0 - 1.0) < 0.05);
  CHECK(d["all"]["R_scale"].get<double>() == Approx(s * s));
  CHECK(d["per_object"].size() == 2);
  CHECK(d["expected"]["within_sigma"][0].get<double>() == Approx(0.6826894921370859));
  // σ half the true one: about χ²₁ CDF(1/4) = 38.3 % within 1σ (scipy), not 68 %.
  CHECK(d["all"]["within_sigma_t"][0].get<double>() == Approx(0.3829).margin(0.03));
  CHECK(d["all"]["ks_p_value"].get<double>() < 1e-6);
  // detection_sigmas.csv: one row per evaluated detection.
  const fs::path csv = f.run / "eval" / "detection_sigmas.csv";
  REQUIRE(fs::exists(csv));
  std::ifstream in(csv);
  std::string line;
  std::size_t rows = 0;
  std::getline(in, line);
  CHECK(line.rfind("timestamp_ns,object_id,e_tx_m", 0) == 0);
  while (std::getline(in, line)) ++rows;
  CHECK(rows == 2 * 599);
  const std::string text = r.to_text();
  CHECK(text.find("detection sigmas against the truth") != std::string::npos);
  CHECK(text.find("scale = true errors / reported sigma") != std::string::npos);
}

TEST_CASE("roe eval --detections: a file, a set name, and the errors", "[app][eval][sigmas]") {
  SigmaFixture f("explicit", 0.5);
  app::EvalOptions o;
  o.est = f.run.string();
  o.gt = f.dataset.string();
  o.no_out = true;
  o.detections = (f.dataset / "detections/sim/detections.csv").string();
  auto r = app::run_eval(o);
  CHECK(std::abs(r.report_json()["detection_calibration"]["all"]["sigma_scale"].get<double>() / 0.5 - 1.0) < 0.2);
  o.detections = "sim";
  r = app::run_eval(o);
  CHECK(std::abs(r.report_json()["detection_calibration"]["all"]["sigma_scale"].get<double>() / 0.5 - 1.0) < 0.2);
  o.detections = "nope";
  CHECK_THROWS_WITH(app::run_eval(o), Catch::Contains("neither a detections.csv file nor a detection set"));
  // The truth needs a dataset: a trajectory file as --gt is refused, naming the option.
  o.detections = "sim";
  o.gt = (f.run / "trajectory.csv").string();
  CHECK_THROWS_WITH(app::run_eval(o), Catch::Contains("--detections needs --gt DATASET"));
}

TEST_CASE("roe eval: no truth objects is an error when asked, a warning otherwise", "[app][eval][sigmas]") {
  SigmaFixture f("notruth", 2.0, false);
  app::EvalOptions o;
  o.est = f.run.string();
  o.no_out = true;
  auto r = app::run_eval(o);
  CHECK(r.report_json()["detection_calibration"].is_null());
  bool warned = false;
  for (const std::string& w : r.report.warnings) warned |= w.find("truth.objects") != std::string::npos;
  CHECK(warned);
  o.detections = "sim";
  try {
    (void)app::run_eval(o);
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(e.context().key == "truth.objects");
  }
}
