// The core's configuration: the Config struct, its validation and its YAML loader.
//
// The YAML keys, their defaults and what each does are documented in ONE place,
// config/reference.yaml (every key, each value equal to the default here; test_config fails
// when the two differ, or when a key of the loader's table is missing there). The presets
// (config/vlp16.yaml, ...) hold only what differs from it. The comments below say why a default is
// what it is. Every stage's options are here, before Config, so that this one header is the whole
// schema and the stages (lio/, ppf/) depend on it rather than the other way round.
//
// Validation: ValidateConfig() is the one rule set. LoadConfigYaml() applies it so that a clamped
// value is reported with the file that set it; LioPpf applies it again for configs built in code
// (a config that passed once yields no notes, so nothing is reported twice). The stages trust
// the config they are given.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/log.hpp"
#include "ppf_core/ppf_config.hpp"

namespace ppf {

// --- options of time_field.hpp (per-point time conventions) -------------------------------------
enum class StampPosition { kAuto, kStart, kEnd };
enum class TimeReference { kAuto, kRelative, kAbsolute };
enum class NoTimePolicy { kNoDeskew, kAzimuth };

struct TimeFieldOptions {
  std::string field;             // "" = detect among t, time, timestamp, time_stamp, offset_time
  double unit_scale_s = 0.0;     // seconds per raw unit; 0 = by type (uint -> 1e-9, float -> 1)
  TimeReference reference = TimeReference::kAuto;
  StampPosition stamp = StampPosition::kAuto;  // which end of the sweep the header stamp marks
  NoTimePolicy no_time_policy = NoTimePolicy::kAzimuth;
  // Spin period: the azimuth estimate's, and twice it bounds the point times a sweep may have
  // (time_field.hpp: later ones are dropped and counted). In (0, kMaxScanPeriodS]; any other
  // value is not a LiDAR's and the decoder uses 0.1 s (config validation says so).
  double scan_period_s = 0.1;
  bool azimuth_clockwise = true; // Velodyne/Ouster spin clockwise seen from above
};
// The longest spin period taken as one: slow scanners (a nodding or rotated 2D LiDAR) take
// seconds; an infinite or astronomical period would make every azimuth time non-finite and the
// sweep window unbounded.
constexpr double kMaxScanPeriodS = 10.0;

// --- options of voxel_map.hpp (the kNN map) -----------------------------------------------------
enum class NearbyType { kCenter = 1, kNearby7 = 7, kNearby19 = 19, kNearby27 = 27 };

struct VoxelMapOptions {
  double resolution = 0.5;                   // voxel edge length, metres (> 0)
  NearbyType nearby = NearbyType::kNearby19;  // neighbourhood searched by GetClosest
  size_t max_voxels = 200000;                // LRU capacity (voxels); bounds memory
  size_t max_points_per_voxel = 10;          // further points into a full voxel are ignored
  // A point closer than this to a point already in its voxel is not stored: re-observations of a
  // surface would otherwise fill voxels with near-duplicates. 0 stores every point (tests).
  double min_point_distance = 0.1;
  // Voxels farther than this from the sensor are dropped (the core prunes every 10 scans,
  // RemoveFarFrom); 0 = off. The map itself never reads it.
  double radius = 150.0;
};

// --- options of hypothesis_search.hpp (LiDAR-only registration) ---------------------------------
struct LidarOnlyOptions {
  // Fit (ScoreFit: share of the sample points near the map that lie within fit_gate of its
  // planes, after the coarse alignment) at which a guess is kept without trying further ones.
  double good_fit = 0.8;
  // ... or at least this share of the median fit of the last 10 scans, if that is lower: in kPpf
  // a right pose fits less (covered skeleton points meet the sparse scattered map at plane
  // borders), and an absolute bar made it try every guess on almost every scan
  // (docs/decisions.md, "Relative good fit").
  double good_fit_relative = 0.95;
  // Best fit below this: the scan is registered anyway, but reported Status::kDegenerate with
  // the fit in the reason (the pose may be off).
  double min_fit = 0.5;
  double fit_gate = 0.1;             // m
  int coarse_iterations = 10;        // iterations of each guess's coarse alignment
  double coarse_max_residual = 1.0;  // m; residual gate of the coarse alignment
  int coarse_points = 2000;          // sample of the downsampled scan used by the coarse stage
  // Extra guesses when the constant-velocity one fits badly: the model's rotation turned about
  // the LiDAR's axes by these angles (the turn rate changed), besides "no motion" and the
  // model's rotation halved and 1.5-fold.
  double offset_deg = 15.0;  // turns of +-offset and +-2*offset about z, +-offset about x, y
  // Prior of the fine update about the coarse pose (1 sigma).
  double prior_rot_std = 0.05;  // rad
  double prior_pos_std = 0.1;   // m
  // De-skew again after the coarse alignment, with the motion interpolated between the last
  // registered pose and the aligned one, then update again (kNN, from that pose): this many
  // times at most (0 = off), fewer once the pose moves less than redeskew_min_change.
  // The constant-velocity de-skew extrapolates the previous interval's twist; a hand-held turn
  // rate changes by tens of deg/s within one scan interval, a de-skew error of degrees. Off by
  // default: on car-like motion, which the model already de-skews well, the extra updates made
  // the poses noisier (docs/results.md, "LiDAR-only on real and simulated data"); 2 for a
  // hand-held sensor.
  int redeskew_iterations = 0;
  double redeskew_min_change = 0.002;  // rad and m
};

// --- the LiDAR's check of the IMU prediction (lio_ppf_process.cpp, OverruleIfInconsistent) ------
// The update counts a scan's rows as far less informative than independent returns (iekf.hpp,
// laser_point_std) and gates them narrowly, so that shared row errors cannot tilt the world: that
// also leaves it no say over a few degrees or decimetres that the IMU got wrong without knowing
// (a gyro saturated on a bump, a sample lost in a turn, a slipping mount, a bridged gap). So each
// LIO scan's posterior is scored as the LiDAR-only guesses are (ScoreFit, here from the kNN rows'
// own neighbours of the update's last iteration: ProbePoseAssociated); when it fits the map far
// worse than the recent scans did, guesses around it are aligned coarsely
// (hypothesis_search.hpp), and a clearly better one re-anchors the prediction: pose moved, the
// velocity turned with it, and the covariance widened by the size of the correction along its
// own direction (a pure heading correction leaves the IMU's roll and pitch in charge). The
// update then runs again from there. ScanResult::overruled and the reason say so.
struct ConsistencyOptions {
  bool check = true;
  // A posterior fitting below this share of the median fit of the last scans is searched again.
  double fit_ratio = 0.7;
  // Sample of the downsampled scan searched to compare the guesses (and to score a scan whose
  // kNN rows met the map with fewer than 100 points).
  int fit_points = 1000;
  // ... or the scan alone (ProbePose: one step of the rows within lidar_only.coarse_max_residual,
  // no prior) would still move the posterior's position farther than this. The narrow gates hide
  // a step along the way from the fit: most points lie on surfaces parallel to it.
  double max_step_pos = 0.1;  // m
  // ... and by more than this many standard deviations of the step itself, its rows counted as
  // independent (which they are not: they share the map's and the de-skew's errors, so a step
  // of a few noisy rows reaches several of these on undisturbed scans).
  double min_step_sigmas = 15.0;
  // A re-anchored posterior is taken when it fits at least this much better (share of the sample
  // points), or no worse while the scan alone no longer moves it past the bounds above.
  double min_gain = 0.1;
  // Guesses besides the posterior and the prediction: turned by +-turn and +-2 turn about the
  // vertical through the sensor (the coarse alignment reaches a few degrees from each).
  double turn_deg = 7.5;
};

// --- options of imu_init.hpp (static and moving start) ------------------------------------------
struct ImuInitOptions {
  double duration_s = 1.0;    // static time needed
  int min_samples = 20;       // and at least this many samples
  double max_acc_std = 0.3;   // m/s^2 (after unit scaling); above: "moving", restart
  double max_gyro_std = 0.05; // rad/s; above: "moving", restart
  double acc_scale = 0.0;     // multiply raw accelerometer readings; 0 = detect (1 or 9.80665)
  double gravity = 0.0;       // gravity magnitude m/s^2; 0 = use the measured norm
  // A steady motion has no spread and still is not rest: a constant turn shows as a gyro mean far
  // above any plausible bias (taking it for one bends every later heading), and an acceleration
  // or the centripetal part of a fast turn as an accelerometer norm off gravity (taking it for
  // gravity tilts the world). Checked against `gravity` (or 9.80665 if that is 0).
  double max_gyro_bias = 0.05;      // rad/s (~3 deg/s: above MEMS turn-on biases)
  double max_gravity_error = 0.3;   // m/s^2 between the mean accelerometer norm and gravity
  // Moving start (moving_start.hpp, run by the facade): when a window is refused for motion,
  // gravity, velocity and gyro bias are estimated from moving_start_window_s of scans registered
  // without the IMU meanwhile and the IMU, instead of waiting for rest.
  bool moving_start = true;
  double moving_start_window_s = 1.5;
  double moving_start_max_gravity_error = 0.5;  // m/s^2: |g| of the free estimate vs gravity
};

// --- options of imu_propagation.hpp (noise densities) -------------------------------------------
// Continuous-time noise densities (white noise: sigma^2 * dt enters the covariance per step).
struct ImuNoise {
  double gyro = 0.01;        // rad/s/sqrt(Hz)
  // m/s^2/sqrt(Hz). MEMS datasheets say ~0.002; the margin covers vibration. 0.1 made the filter
  // discount the accelerometer so far that bias and gravity separated only slowly after turns.
  double acc = 0.02;
  double gyro_bias = 1e-4;   // rad/s^2/sqrt(Hz) random walk
  double acc_bias = 1e-3;    // m/s^3/sqrt(Hz) random walk
  // rad/sqrt(s): random walk of the gravity direction in the map frame (0: a fixed direction,
  // estimated once). Non-zero lets it follow a map that tilts slowly over a long drive.
  double gravity_dir = 0.0;
  // rad/s: the gyro's full scale (datasheet). A reading at it is a bound, not a measurement: the
  // turn beyond it is unknown, so the rotation it integrates is widened and the scan measures it
  // (imu_propagation.hpp, docs/behaviour.md "Gyro saturation"). 0 = unknown: no reading is taken
  // for saturated (a repeated reading is no sign of it: quantized gyros repeat values while
  // turning steadily).
  double gyro_range = 0.0;
};

// --- options of iekf.hpp (the iterated update) --------------------------------------------------
struct IekfOptions {
  int max_iterations = 4;
  double convergence_rot_rad = 1e-4;  // |dtheta| below this ...
  double convergence_trans_m = 1e-3;  // ... and |dp| below this: converged
  // Metres: the noise of one point-to-plane row (weight 1) as the update counts it. Far above one
  // return's range noise on purpose: a scan's rows are not independent measurements. Neighbouring
  // rows share their map plane's (or skeleton patch's) fitting error, and every row shares the
  // scan's de-skew error, so a few thousand rows carry far less information than a few thousand
  // independent ones. Counted as independent at the range noise, they made the LiDAR so sure of
  // roll and pitch that each scan overruled the gyro and the accelerometer, and whatever error
  // the rows shared tilted the world away from gravity (docs/decisions.md, "Row noise and
  // gravity"); counted at this level the IMU keeps the tilt, and position is still the LiDAR's.
  double laser_point_std = 0.3;
  // Radians: the part of a row's noise that grows with the point's range. A far point is matched
  // to a plane fitted from neighbours as far apart as the beams are there, so its row's error
  // grows with range and, through its lever arm, turns the map about a horizontal axis
  // (docs/decisions.md, "Row noise and gravity").
  // Row variance = laser_point_std^2 + (laser_angular_std * range)^2; 0 = range-independent.
  // Scaled with laser_point_std (same ratio), so near and far rows keep their relative weights.
  double laser_angular_std = 0.05;
  // Metres; from the second iteration on, rows whose residual at the current estimate exceeds
  // this are dropped (0 = off). The providers' own gates must be wide enough for the prediction's
  // error (a fast turn, a bumpy start), but at those widths wrong associations (a road point
  // matched to a kerb, a facade to its neighbour) pass at full weight, and they are not symmetric
  // about the vehicle: they turn the map away from gravity. Once the first iteration has brought
  // the estimate near, true matches sit within a few laser sigmas, and only they shape the
  // posterior. Not while the map is young: built from the static start's few rings, it fits
  // planes whose true matches lie farther out while the platform first moves away.
  double refined_gate = 0.1;
  double refined_gate_after_s = 3.0;  // seconds after the map's first scan
  int min_rows = 20;                  // fewer rows: skip the update, keep the prediction
  // J^T J eigenvalue (points) per direction below which the direction is degenerate. 10 rows of
  // 3 cm noise still pin it to ~1 cm per scan; 30 (the first default) threw that away in PPF
  // mode in corridors, where the sandwich layer discards the door frames (docs/decisions.md,
  // "Degeneracy threshold").
  double degeneracy_min_eig_translation = 10.0;
  double degeneracy_min_eig_rotation = 300.0;  // J^T J eigenvalue (points * m^2)
  // Metres from the LiDAR beyond which points give no residual (0 = no limit); they are still
  // mapped. Far rows fit planes to sparse, grazing returns and their errors act through long
  // lever arms: on the simulated drives they tilted the map away from gravity (docs/decisions.md,
  // "Row noise and gravity").
  double residual_max_range = 0.0;
};

// --- options of knn_residual.hpp (kNN point-to-plane rows) --------------------------------------
struct KnnOptions {
  int k = 5;                          // neighbours per point
  double max_neighbor_distance = 1.0; // metres; farther neighbours do not count
  double plane_threshold = 0.1;       // metres; every neighbour within this of the fitted plane
  // Metres; if > 0, neighbours must also spread at least this much (std) across their main
  // direction. Neighbours along one scan ring are nearly collinear and their plane normal is
  // poorly defined. Off by default: with 0.5 m voxels it also removes most floor rows of a
  // 16-beam LiDAR (z then rests on the IMU alone); it pays off with finer voxels (0.25 m).
  double min_plane_spread = 0.0;
  // Metres; larger residuals are outliers. Wide enough for the prediction's error; the IEKF's
  // refined gate (IekfOptions::refined_gate) narrows it once the estimate is near.
  double max_residual = 0.5;
  // Metres; > 0: within one scan a point keeps the neighbours (and their plane) of its last search
  // while its world position stays within this distance of where that search was made; the row
  // itself is always evaluated at the current pose. 0: every iteration searches again. Applied
  // only to a scan whose prediction is that near (LioPpf keeps it off for LiDAR-only scans and
  // while the prior's position std is above it): the later iterations of such a scan move its
  // points by millimetres, and searching again finds the same neighbours.
  double search_again_distance = 0.05;
  int num_threads = 0;                // 0 = OpenMP default
};

// --- the YAML section preprocess: (the stage's own options, preprocess.hpp, are built from it) -
struct PreprocessConfig {
  double min_range = 0.5;        // metres; closer points (the vehicle itself) are dropped
  double max_range = 150.0;      // metres
  int point_stride = 1;          // keep every n-th point (1 = all)
  double scan_voxel_size = 0.5;  // metres, voxel grid applied to the de-skewed scan
};

// Where the prediction comes from (docs/behaviour.md, "LiDAR-only"). kLio: the IMU (static
// initialization first). kNone: no IMU; a constant-velocity model and several registration
// guesses (hypothesis_search.hpp); IMU samples are ignored. kAuto: kLio as soon as an IMU sample
// arrives; kNone if scans spanning imu.auto_wait_s (or the whole input, at flush) came without one.
enum class ImuMode { kAuto, kLio, kNone };

// --- the YAML section imu: ----------------------------------------------------------------------
// Its groups init: and noise: are the members init and noise (YAML imu.init.duration is
// imu.init.duration_s here).
struct ImuOptions {
  ImuMode mode = ImuMode::kAuto;
  // Seconds of scans without any IMU sample after which kAuto decides "no IMU". Scans wait (are
  // not lost) meanwhile. Long enough for an IMU driver that starts a moment after the LiDAR's.
  double auto_wait_s = 2.0;
  ImuInitOptions init;     // static initialization (imu_init.hpp)
  ImuNoise noise;          // continuous-time noise densities (imu_propagation.hpp)
  double max_gap_s = 0.5;  // longer gaps between IMU samples are bridged or re-anchored
  // A gap between valid IMU samples longer than this is counted (InputStats::imu_gaps) and named
  // in one WARN line (gaps beyond imu.max_gap_s in the bridge / IMU-loss line): even a gap the
  // propagation integrates across unnoticed says the driver or the link drops samples.
  double max_gap_warn_s = 0.1;
  // IMU loss (docs/behaviour.md, "IMU loss"): a scan whose end lies more than this beyond the
  // last IMU sample, while later scans show the stream has stalled (imu.max_gap_s), is registered
  // LiDAR-only (constant-velocity model seeded from the filter's velocity and turn rate, the
  // guesses of hypothesis_search.hpp), keeping map, gravity and biases; LIO resumes, re-anchored,
  // when IMU samples are back. Scans closer to the last sample are propagated with it held
  // (extrapolated): a held acceleration and turn rate are only right for a moment, and on the
  // simulated drives the LiDAR-only registration was the more accurate from a quarter second on
  // (docs/decisions.md, "IMU loss timeout"). Shorter values gain nothing: the scan interval is
  // 0.1 s.
  double loss_timeout_s = 0.25;
  // The fine update's prior about the coarse pose for those scans (as lidar_only.prior_*_std).
  // Looser than LiDAR-only's own: the map the fallback registers against was built with the
  // IMU and the coarse alignment starts from the filter's motion, so the scan's own residuals
  // are worth more than the guess; a tight prior held the pose off the map by centimetres.
  double loss_prior_pos_std = 0.3;  // m
  double loss_prior_rot_std = 0.1;  // rad
  // A gap between IMU samples up to this long, without scans that needed the LiDAR-only
  // fallback meanwhile (both streams silent), is bridged: state and map are kept, the IMU is
  // integrated across the gap from the samples on either side (as if it had been constant), and
  // the uncertainty is widened by gap_acc_std / gap_gyro_std for the unmeasured motion, so the
  // next scan re-registers against the map (ScanResult::imu_gap_s says so). Extrapolation errors
  // grow with the square of the gap and registration (0.5 m residual gates) only recovers small
  // ones (docs/decisions.md, "IMU gap bridging"). After a longer gap the first scan is registered
  // LiDAR-only and LIO re-anchors (no reset). 0 = never bridge by integration.
  double max_gap_bridge_s = 2.5;
  double gap_acc_std = 1.0;    // m/s^2, unmeasured acceleration assumed during a bridged gap
  double gap_gyro_std = 0.05;  // rad/s, unmeasured turn rate assumed during a bridged gap
};

// --- the YAML section extrinsic: -----------------------------------------------------------------
struct ExtrinsicConfig {
  // LiDAR -> IMU: p_imu = T_imu_lidar * p_lidar.
  Eigen::Isometry3d T_imu_lidar = Eigen::Isometry3d::Identity();
};

// --- the core ------------------------------------------------------------------------------------
enum class Mode { kKnn, kPpf };

struct Config {
  Mode mode = Mode::kKnn;

  // One member per YAML section, named as the section (config/reference.yaml).
  ExtrinsicConfig extrinsic;    // T_imu_lidar, the LiDAR's mount on the IMU
  PreprocessConfig preprocess;  // range and stride filter, scan voxel grid
  TimeFieldOptions time;        // per-point time conventions (time_field.hpp)
  VoxelMapOptions map;          // kNN map (voxel_map.hpp): 0.5 m voxels, LRU bound, map.radius

  ImuOptions imu;               // YAML section imu: (mode, init, noise, gaps, IMU loss)
  LidarOnlyOptions lidar_only;  // imu.mode none (hypothesis_search.hpp), YAML section lidar_only:

  // --- registration ----------------------------------------------------------------------------
  IekfOptions iekf;  // max 4 iterations, degeneracy thresholds (iekf.hpp)
  ConsistencyOptions consistency;  // the LiDAR overrules a prediction the map contradicts
  KnnOptions knn;    // 5 neighbours, planes valid within 0.1 m (knn_residual.hpp)
  // Plane pre-fitting and skeleton tracking (Mode::kPpf), YAML section `ppf:`; why each default
  // is what it is: ppf_config.hpp (PpfConfigForBeams() for 16/32/64/128 beams).
  PpfConfig ppf;

  int num_threads = 0;  // OpenMP threads for de-skew and kNN residuals (0 = OpenMP default)
  // Fill ScanResult::deskewed_points_lidar (the node's registered_points output). Set by the
  // caller that publishes them, not read from YAML.
  bool output_deskewed_points = false;
  LogCallback log;  // receives all messages; nullptr = silent
};

// Clamps nonsensical values to safe ones; returns one note per fix (empty if valid). Never throws.
std::vector<std::string> ValidateConfig(Config* config);

// The outcome of loading a config file (core or ppf_node): the first hard error, naming the key,
// or ok with the warnings (unknown keys, clamped values).
struct ConfigLoadReport {
  bool ok = true;
  std::string error;                  // first hard error (wrong type, unreadable file)
  std::vector<std::string> warnings;  // unknown keys, clamped values
};

// Parses YAML into *config, starting from what *config holds (defaults, or an earlier file: a
// calibration file is layered after a preset this way), then validates (ValidateConfig). All or
// nothing: a failed load leaves *config unchanged. Never throws.
ConfigLoadReport LoadConfigYamlString(const std::string& yaml, Config* config);
ConfigLoadReport LoadConfigYaml(const std::string& path, Config* config);

}  // namespace ppf
