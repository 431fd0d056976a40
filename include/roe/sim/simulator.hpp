#pragma once
/// @file
/// The sequence simulator behind `roe simulate`: an analytic inspection trajectory around a group of
/// YCB-V objects, a D435i-like camera + IMU rig, motion capture of the rig, and PoET-like object pose
/// detections. Produces a roe::Dataset (DESIGN §3) with `truth` filled; typed in, typed out (no I/O).
///
/// Frames: M is the room (mocap world, z up, origin on the floor below the object group); W is the
/// navigation world: gravity-aligned (z up, g = (0, 0, 9.81)), parallel to M, with its origin at the
/// IMU's initial position (DESIGN §2: "IMU starts at its origin"). So T_M_W is a pure translation.
/// state_groundtruth_estimate0 holds T_W_I; mocap0 holds T_M_B = T_M_W T_W_I T_I_B (noisy);
/// truth.objects holds T_W_O.
///
/// IMU (DESIGN §2, paper eq. 3): a_m = R_W_Iᵀ (a_W + g) + b_a + n_a, ω_m = ω_I + b_g + n_g, so that
/// v̇ = R_W_I (a_m − b_a − n_a) − g. n ~ N(0, σ_c² · rate) per sample (σ_c the continuous noise
/// density), biases are random walks b_{k+1} = b_k + σ_w √Δt · N(0, I). Samples are point samples of
/// the analytic trajectory at the IMU stamps.
///
/// Determinism: every random draw comes from roe::sim::Rng streams of the seed (random.hpp); the
/// same config and seed give the same Dataset bit for bit.
///
/// Every default below is documented with its source in docs/simulator.md.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "roe/core/dataset.hpp"
#include "roe/sim/detection_model.hpp"
#include "roe/sim/trajectory.hpp"

namespace roe::sim {

/// The simulated IMU. Defaults: Bosch BMI055 (the D435i's IMU) datasheet noise densities; random
/// walks as in EuRoC's sensor.yaml (the datasheet gives none).
struct ImuConfig {
  double rate_hz = 200.0;
  double gyro_noise_density = 2.443e-4;   ///< rad/s/√Hz (BMI055: 0.014 °/s/√Hz)
  double gyro_random_walk = 1.9393e-5;    ///< rad/s²/√Hz
  double accel_noise_density = 1.471e-3;  ///< m/s²/√Hz (BMI055: 150 µg/√Hz)
  double accel_random_walk = 3.0e-3;      ///< m/s³/√Hz
  double gyro_bias_sigma = 0.005;         ///< rad/s, σ of the initial gyro bias per axis
  double accel_bias_sigma = 0.05;         ///< m/s², σ of the initial accelerometer bias per axis
};

/// The processed camera (D435i colour 1280x720, undistorted, centre-cropped to 640x480, so the focal
/// length of the 1280x720 stream) and its mounting.
struct CameraConfig {
  double rate_hz = 30.0;
  PinholeCamera intrinsics{640, 480, 919.806, 920.129, 319.909, 238.775};
  /// True camera → IMU extrinsics (x_I = T_I_C x_C): D435i-like, about 2 cm lever arm and 1.09°
  /// misalignment (colour ← accel factory extrinsics of a D435i).
  Pose T_I_C{Eigen::Quaterniond(0.999954886, -3.17228604e-04, -2.61229772e-03, 9.12693651e-03),
             Eigen::Vector3d(-0.01995682, 0.00414398, 0.01103334)};
  /// Error of the prior T_I_C written to roe.json camera.T_I_C (identity: prior = truth):
  /// prior = T_I_C * prior_error.
  Pose prior_error;
  /// The true camera–IMU time offset (s; Kalibr/OpenVINS convention t_imu = t_cam + offset): a frame that saw
  /// the rig at IMU time t is stamped t − offset (roe.json truth.camera_time_offset_s).
  double time_offset_s = 0.0;
  /// What roe.json's camera.time_offset_s declares (the user's prior; may differ from the truth).
  double declared_time_offset_s = 0.0;
};

/// One object of the scene.
struct ObjectSpec {
  int id = 0;             ///< YCB-V class id (1..21) or any positive id
  bool has_pose = false;  ///< when true, T_M_O is used as given; otherwise it is drawn
  Pose T_M_O;             ///< pose in the room frame M
};

struct ObjectsConfig {
  std::vector<ObjectSpec> objects{{1, false, {}}, {5, false, {}}, {13, false, {}}};
  Eigen::Vector3d area_center = Eigen::Vector3d(0.0, 0.0, 0.8);  ///< centre of the placement area (M)
  double area_size_m = 1.0;                                      ///< side of the square area (about 1 m²)
  double min_separation_m = 0.15;                                ///< between drawn object centres
  double height_jitter_m = 0.05;  ///< drawn centre height: area_center.z + U(0, height_jitter)
  double lying_prob = 0.3;        ///< probability that a drawn object lies on its side (90° roll)
  std::uint64_t layout_seed = 1;  ///< seed of the placement draw (fixed per preset, not --seed)
  std::vector<int> symmetric_ids{13, 16, 19, 20, 21};  ///< PoET's YCB-V symmetric classes
};

/// How --seed varies a preset's trajectory ("similar but not identical" repeated runs).
struct VariationConfig {
  double amplitude_rel = 0.15;     ///< each sinusoid amplitude × U(1 − a, 1 + a)
  double frequency_rel = 0.05;     ///< each frequency × U(1 − f, 1 + f)
  double phase_rad = 0.5;          ///< each phase + U(−φ, φ)
  double offset_rel = 0.05;        ///< offsets of radius and height × U(1 − o, 1 + o)
  double azimuth_start_rad = 0.3;  ///< azimuth offset + U(−a, a)
};

struct MocapConfig {
  bool enabled = true;
  double rate_hz = 120.0;
  double position_sigma_m = 0.0005;
  double rotation_sigma_deg = 0.1;
  std::string body = "rig";
  Pose T_B_I;  ///< IMU in the mocap body frame (identity default)
};

struct SimConfig {
  std::string name = "custom";
  double duration_s = 60.0;
  Timestamp start_time_ns = 1'600'000'000'000'000'000;  ///< stamp of the first IMU sample
  TrajectoryConfig trajectory;
  VariationConfig variation;
  ObjectsConfig objects;
  ImuConfig imu;
  CameraConfig camera;
  VisibilityConfig visibility;
  DetectionNoiseConfig detection;
  MocapConfig mocap;
};

/// Counts and extremes of one simulated sequence (for summaries and tests).
struct SimStats {
  std::size_t imu_samples = 0;
  std::size_t frames = 0;
  std::size_t frames_with_detections = 0;
  std::size_t detections = 0;
  std::size_t outliers = 0;
  std::size_t flips = 0;
  std::size_t blurred_frames = 0;
  std::size_t blurred_detections = 0;
  std::size_t bad_frames = 0;            ///< frames inside a run of bad frames (detection_model.hpp, 8)
  std::size_t bad_frame_detections = 0;  ///< detections in such frames
  std::size_t missed = 0;  ///< in view but dropped by the miss draw
  double max_speed_m_s = 0.0;
  double max_rate_deg_s = 0.0;
  double min_distance_m = 0.0;  ///< camera to object-group centre
  double max_distance_m = 0.0;
  std::map<int, std::size_t> detections_per_object;
};

/// A simulated sequence with its per-detection labels (same order as dataset.detections["sim"]).
struct SimRun {
  Dataset dataset;
  std::vector<DetectionLabel> labels;
  SimStats stats;
};

/// Simulates a sequence. Throws roe::ConfigError on an inconsistent config (non-positive rates or
/// duration, unknown object ids ≤ 0, an object that can never be placed, ...).
Dataset simulate(const SimConfig& config, std::uint64_t seed);
/// The same, with labels and statistics.
SimRun simulate_run(const SimConfig& config, std::uint64_t seed);

/// The trajectory after the seed's variation (what simulate uses).
TrajectoryConfig vary_trajectory(const TrajectoryConfig& nominal, const VariationConfig& variation,
                                 std::uint64_t seed);
/// Object poses in M after placement (explicit poses kept, others drawn with objects.layout_seed).
std::vector<TruthObject> place_objects(const ObjectsConfig& objects);
/// Validates a config; throws roe::ConfigError naming the offending key.
void validate(const SimConfig& config);

/// `roe simulate --from-groundtruth`: a real recording's IMU and ground truth kept unchanged, objects
/// placed where the camera sees them along the real trajectory, detections synthesised.
///
/// Placement rule (place_along_trajectory, docs/simulator.md "--from-groundtruth"): candidate object
/// centres are drawn in front of the camera at frames spread over the whole recording (every
/// place_candidate_every_s, place_candidates_per_frame each: pixel uniform in the central
/// place_inner_fraction of the image, depth uniform in [place_min_depth_m, place_max_depth_m]); for each
/// candidate the set of frames that see it geometrically (object_in_view: depth range and image margin)
/// is computed. The anchor (object_ids[0]) is the candidate seen in the most frames among those first
/// seen within anchor_window_s of the first frame; the other objects are chosen greedily, each the
/// candidate that adds the most frames not yet seeing any object (ties: most frames overall), among
/// candidates at least min_separation_m from the chosen ones, seen in ≥ min_frames_visible frames and
/// never in view before anchor_lead_s after the anchor's first sight (so the filter takes the anchor as
/// its main object). Deterministic for a seed (the candidate draw uses the seed's "placement" stream).
struct FromGroundtruthConfig {
  int num_objects = 3;
  std::vector<int> object_ids{1, 5, 13, 2, 4, 8, 14, 19, 10, 12, 15, 21};  ///< the first N are used
  std::vector<int> symmetric_ids{13, 16, 19, 20, 21};
  double camera_rate_hz = 30.0;
  /// No camera frame where the ground truth has a gap longer than this (its two poses around the frame's
  /// stamp further apart): the camera pose, and so what it would see, is not known there. TUM-VI's
  /// mocap has gaps of up to 1.06 s (room1); EuRoC's state estimate has none.
  double max_groundtruth_gap_s = 0.1;
  /// The recording's own camera: EuRoC MAV cam0 (mav0/cam0/sensor.yaml: 752x480, fu 458.654,
  /// fv 457.296, cu 367.215, cv 248.375), taken as undistorted pinhole. Its ~79°x55° field of view
  /// (not the 38°x29° of the processed D435i image of the presets) decides which frames see an object.
  PinholeCamera intrinsics{752, 480, 458.654, 457.296, 367.215, 248.375};
  /// EuRoC MAV cam0 → IMU (body) extrinsics, T_BS of mav0/cam0/sensor.yaml (x_I = T_I_C x_C).
  Pose T_I_C = euroc_T_I_C();
  double place_min_depth_m = 0.8;  ///< candidate depth range in front of the camera (handheld/MAV view)
  double place_max_depth_m = 2.0;
  double place_inner_fraction = 0.6;      ///< candidate pixel uniform in the central fraction of the image
  double place_candidate_every_s = 0.03;  ///< spacing of the frames that spawn candidates (≤ 1/rate: all)
  int place_candidates_per_frame = 4;     ///< candidates drawn at each such frame
  double anchor_window_s = 1.0;           ///< the anchor is first seen within this time of the start
  double anchor_lead_s = 0.5;             ///< no other object is in view before anchor sight + this
  double min_separation_m = 0.3;          ///< between object centres
  std::size_t min_frames_visible = 30;    ///< reject a placement seen (geometrically) in fewer frames
  ImuNoise imu_noise{1.6968e-4, 1.9393e-5, 2.0e-3, 3.0e-3};  ///< EuRoC ADIS16448 (sensor.yaml)
  VisibilityConfig visibility;
  DetectionNoiseConfig detection;
  /// The true camera–IMU time offset and the declared one, as CameraConfig's (roe simulate --time-offset).
  double time_offset_s = 0.0;
  double declared_time_offset_s = 0.0;

  static Pose euroc_T_I_C();
};

/// How well a set of object centres covers a sequence of camera poses (geometric visibility only).
struct PlacementCoverage {
  std::size_t frames = 0;                      ///< camera frames
  std::size_t frames_covered = 0;              ///< frames in which at least one object is in view
  std::vector<std::size_t> frames_per_object;  ///< frames in which each object is in view
  double longest_gap_s = 0.0;  ///< longest time between two covered frames (or from the first / to the
                               ///< last frame when those are not covered)
  double fraction() const { return frames ? static_cast<double>(frames_covered) / frames : 0.0; }
};

/// Coverage of the object centres p_W by the cameras T_W_C at stamps t (same size, sorted).
PlacementCoverage placement_coverage(const std::vector<Timestamp>& t, const std::vector<Pose>& T_W_C,
                                     const std::vector<Eigen::Vector3d>& p_W, const PinholeCamera& cam,
                                     const VisibilityConfig& vis);

/// The placement rule above: num_objects centres in W (the anchor first) for the cameras T_W_C at
/// stamps t. Throws roe::DataError when fewer than num_objects admissible positions exist.
std::vector<Eigen::Vector3d> place_along_trajectory(const std::vector<Timestamp>& t,
                                                    const std::vector<Pose>& T_W_C,
                                                    const FromGroundtruthConfig& config, std::uint64_t seed);

/// Builds the dataset from typed real streams (time-sorted, IMU in I, ground truth T_W_I).
/// Throws roe::DataError when the streams do not overlap or the objects cannot be placed.
SimRun simulate_from_groundtruth(const std::vector<ImuSample>& imu, const std::vector<ImuState>& groundtruth,
                                 const FromGroundtruthConfig& config, std::uint64_t seed);

}  // namespace roe::sim
