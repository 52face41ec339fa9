// LioPpf: the LiDAR-inertial odometry facade. Middleware free: feed ImuSample and CloudView, get
// one ScanResult per scan.
//
// Usage:
//   ppf::Config config;                  // or ppf::LoadConfigYaml("config/hdl64.yaml", ...)
//                                        // (config.hpp; config/basic.yaml, then every key in
//                                        // config/reference.yaml)
//   ppf::LioPpf lio(config);
//   lio.AddImu(imu);                     // any order relative to scans, each stream in time order
//   lio.AddScan(cloud);                  // decoded at once: the view may be released afterwards
//   for (const ppf::ScanResult& r : lio.Process()) { ... }   // scans whose IMU coverage is complete
//   lio.Process(/*flush=*/true);         // at the end: process the rest (IMU extrapolated)
//
// Pipeline per scan (timings in ScanResult::timings):
//   preprocess  decode layout and per-point time (time_field.hpp), drop NaN points
//   downsample  stride/range filter and voxel grid (preprocess.scan_voxel_size, 0.5 m) of the raw
//               scan; every kept point has its voxel's mean time (preprocess.hpp)
//   deskew      propagate the IMU to the scan end (midpoint, imu_propagation.hpp) and move every
//               kept point to the LiDAR pose at the scan END with its own time (deskew.hpp)
//   ppf         the skeleton tracker labels points kSkeleton / kScattered / kDiscarded (kPpf only;
//               ppf/skeleton_tracker.hpp, parameters Config::ppf)
//   residuals   + update: IEKF (lio/iekf.hpp); every iteration the kNN rows of the kScattered
//               points and, in kPpf, the skeleton rows (lio/residual_provider.hpp)
//   map insert  points labelled kScattered ("map points") go into the kNN VoxelMap
//
// Behaviour, one section per topic: docs/behaviour.md, "Initialization", "Moving start",
// "LiDAR-only", "Late IMU", "IMU loss", "Time glitches", "Single bad values", "Clock offset".
// Every scan gets a ScanResult with a status and a reason; of the input, only time running
// backwards resets the filter and the map (Status::kReset). Single bad values are dropped and
// counted (InputStats).
#pragma once

#include <cstddef>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

// The public face only: the stages (lio/, ppf/) are the implementation's.
#include "ppf_core/cloud_view.hpp"
#include "ppf_core/config.hpp"
#include "ppf_core/imu_sample.hpp"
#include "ppf_core/log.hpp"
#include "ppf_core/result_types.hpp"

namespace ppf {

// The kNN map's size (the map itself is the core's).
struct MapStats {
  size_t points = 0;           // stored points
  size_t voxels = 0;           // occupied voxels
  size_t capacity_points = 0;  // the bound: max_voxels * max_points_per_voxel
};

// What the core refused or repaired in its input streams since it was constructed (Reset()
// included): a node shows these counters beside its own. Each ScanResult carries the part since
// the previous result (ScanResult::imu_gaps etc.).
struct InputStats {
  size_t scans_bad_time = 0;      // scans skipped: most point times outside the sweep window
  size_t points_bad_time = 0;     // points dropped for such a time (ScanResult::points_bad_time)
  size_t imu_duplicates = 0;      // same stamp and values as the sample before: dropped
  size_t imu_conflicts = 0;       // same stamp, different values (each stamp counted once)
  size_t imu_conflicts_unresolved = 0;  // ... of which neither copy fit its neighbours: none kept
  size_t imu_gaps = 0;            // gaps between valid IMU samples longer than imu.max_gap_warn
  size_t imu_clock_offset_dropped = 0;  // samples not used: the IMU clock was off the LiDAR's
  double imu_gap_longest_s = 0.0;  // the longest of them
};

enum class Status {
  kOk,            // pose estimated from this scan
  kInitializing,  // IMU initialization not finished (reason says why); no pose yet
  kDegenerate,    // pose estimated, but some directions are unconstrained (IMU kept there)
  kReset,         // a time glitch reset the filter and the map; initialization restarts
  kRejected,      // malformed cloud (reason says what); nothing changed
};
const char* StatusName(Status status);

// What set off a scan's search of guesses around its posterior (Config::consistency): nothing
// (no search ran), a fit far below the recent scans', or the scan alone still moving the posterior
// too far while it fit as well as they did.
enum class ConsistencySearch {
  kNone,
  kPoorFit,  // fit < consistency.fit_ratio x the recent scans' median
  // fit good; the scan alone moves it > consistency.max_step_pos, > 3x usual and by more than
  // consistency.min_step_sigmas of its own standard deviation
  kScanStep,
};
const char* ConsistencySearchName(ConsistencySearch search);  // "none", "fit", "step"

// Milliseconds. preprocess = decoding the cloud (layout, per-point time); downsample = stride and
// range filter + voxel grid on the raw points; deskew = IMU propagation + de-skew of the
// downsampled points (preprocess.hpp explains the order). guesses = LiDAR-only coarse alignment
// of the motion guesses (hypothesis_search.hpp); with an IMU, the consistency check of the
// posterior (Config::consistency) and, when the map contradicted the prediction, its search.
struct StageTimings {
  double preprocess = 0, deskew = 0, downsample = 0, ppf = 0, residuals = 0, update = 0,
         map_insert = 0, total = 0, guesses = 0;
};

struct ScanResult {
  // --- The scan and its outcome -----------------------------------------------------------------
  // What LioPpf::AddScan returned for the scan this result belongs to. 0 for a notice that
  // belongs to no scan: a kReset the IMU stream caused (its time going back), reported before
  // the next scan's result. A gap too long to bridge resets nothing (docs/behaviour.md,
  // "Time glitches").
  uint64_t input_id = 0;
  double stamp_s = 0.0;        // time of the pose: the scan end
  double scan_begin_s = 0.0;   // earliest point time
  Status status = Status::kInitializing;
  std::string reason;          // human readable: why not kOk, notes (e.g. time field fallback)
  bool pose_valid = false;     // false for kInitializing / kRejected / kReset

  // --- Pose and state ---------------------------------------------------------------------------
  // Poses, velocity, planes and covariances are in the gravity-aligned world: z up as the filter
  // now estimates it, origin and yaw of the IMU at initialization. The map is built in the frame
  // the filter started with ("map": z = the accelerometer's "up" at rest, which carries its
  // bias); T_world_map is the rotation (about the origin, no yaw) between the two, refined as the
  // motion makes gravity and accelerometer bias separable. Identity while nothing is known.
  Eigen::Isometry3d T_world_imu = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_map = Eigen::Isometry3d::Identity();
  Eigen::Vector3d velocity_world = Eigen::Vector3d::Zero();
  // IMU frame, gyro bias removed: the last IMU sample at or before stamp_s (odometry twist).
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d acc_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d gravity_map = Eigen::Vector3d::Zero();  // the filter's gravity, map frame
  // Error-state order of imu_propagation.hpp; position and velocity blocks in the world frame.
  StateCov covariance = StateCov::Zero();
  Eigen::Matrix<double, 6, 6> pose_covariance = Eigen::Matrix<double, 6, 6>::Zero();  // [rot, pos]

  // --- LiDAR-only and the IMU stream: what predicted this scan ----------------------------------
  // Registered without an IMU because none has come (imu.mode none, or auto that decided none),
  // including the window in which IMU samples that arrived late are judged (docs/behaviour.md,
  // "Late IMU"). Not set for an IMU loss (imu_lost) or a moving start.
  bool lidar_only = false;
  // The scan with which the LiDAR-only start became LiDAR-inertial (late IMU): from it on the
  // IMU predicts, in the same world as before (no jump; its z is not "up", gravity_map says
  // where down is).
  bool lio_started_late = false;
  // Registered LiDAR-only because the IMU stream is lost mid-run (IMU loss fallback,
  // imu.loss_timeout_s); the reason says so. The first LIO scan after it has imu_gap_s > 0.
  bool imu_lost = false;
  // The first LIO scan after an IMU loss (the reason says "LIO resumed"; imu_gap_s is the gap).
  bool lio_resumed = false;
  // Registered LiDAR-only after a gap longer than the IMU bridges (both streams silent, or the
  // IMU lost that long, while moving): the pose was found again on the map from guesses along
  // the way (motion_guess, fit). It extends no map until LIO confirms it; one WARN says so.
  bool relocalized = false;
  double imu_gap_s = 0.0;      // > 0: an IMU gap this long before this scan was bridged
  // != 0: the IMU's clock runs this many seconds behind the LiDAR's (scan end minus the newest
  // IMU sample, both streams live): the scan was registered LiDAR-only and the IMU is not used
  // until the clocks agree again (the reason says so; imu_lost is set too once LIO had run).
  double imu_clock_offset_s = 0.0;
  // IMU input since the previous result (InputStats has the totals): gaps between valid samples
  // longer than imu.max_gap_warn and the longest of them, and stamps that came twice with
  // different values (the copy kept is the one consistent with the samples either side, or
  // neither: imu_conflicts_unresolved).
  size_t imu_gaps = 0;
  double imu_gap_longest_s = 0.0;
  size_t imu_conflicts = 0;
  size_t imu_conflicts_unresolved = 0;
  // > 0: some gyro axis read at saturation (imu.noise.gyro_range) this long while predicting this
  // scan; the turn beyond the reading was left to the LiDAR (its rotation covariance widened).
  double gyro_saturated_s = 0.0;

  // --- Counts: points through the stages, residual rows, map ------------------------------------
  size_t input_points = 0;        // width * height
  size_t dropped_nan = 0;
  // Points dropped because their time lies outside the plausible sweep window (time_field.hpp:
  // before the header stamp, or later than 2 x time.scan_period after it); they never move
  // scan_begin_s or stamp_s. When they outnumber the points kept the scan is skipped: kRejected,
  // the reason says so, nothing changed.
  size_t points_bad_time = 0;
  size_t valid_points = 0;        // after NaN and range filtering
  size_t downsampled_points = 0;
  size_t skeleton_points = 0;     // labelled kSkeleton
  size_t scattered_points = 0;    // labelled kScattered
  size_t discarded_points = 0;    // labelled kDiscarded
  size_t knn_residuals = 0;       // rows of the kNN provider (last iteration)
  size_t skeleton_residuals = 0;  // rows of the skeleton provider (last iteration)
  size_t map_inserted = 0;        // points offered to the map
  size_t map_size = 0;            // points in the kNN map after insertion
  // kPpf: the skeleton tracker's plane patches (plane_patch_map.hpp), the skeleton
  // points' share of the local map (a patch summarises up to patch_max_points points).
  size_t skeleton_patches = 0;

  // --- Timings ----------------------------------------------------------------------------------
  StageTimings timings;

  // --- Diagnostics: how well the scan fit, how far the LiDAR moved the prediction, the update ---
  // LiDAR-only: the share of scan points on a map plane after the coarse alignment
  // (hypothesis_search.hpp), the guess it came from and how many guesses were aligned. LIO with
  // consistency.check: the same share at the posterior (ScoreFit), and the guesses of a search.
  double fit = 0.0;
  std::string motion_guess;
  int guesses_tried = 0;
  // How far the LiDAR moved the prediction (IMU-propagated, or the LiDAR-only guess) in this
  // scan: rotation in degrees, translation in metres, between the prior and the posterior.
  double correction_rot_deg = 0.0;
  double correction_pos_m = 0.0;
  // The map contradicted the IMU prediction (the posterior fit far worse than the recent scans)
  // and a pose found from guesses around it fit clearly better: the prediction was re-anchored
  // there and the update ran again (Config::consistency). The reason and one WARN say how far.
  bool overruled = false;
  // With consistency.check: what set this scan's search off (kNone: the scan passed the check and
  // nothing was searched). Every overruled scan had one; a search that found nothing better kept
  // the pose and says so in the reason ("pose kept").
  ConsistencySearch consistency_search = ConsistencySearch::kNone;
  // With consistency.check: how far the scan alone (wide gate, no prior; ProbePose) would still
  // move the posterior; large values with overruled false say the map and the IMU disagree.
  double disagreement_rot_deg = 0.0;
  double disagreement_pos_m = 0.0;
  int iterations = 0;
  bool converged = false;
  Eigen::Vector3d eig_rotation = Eigen::Vector3d::Zero();     // J^T J, ascending
  Eigen::Vector3d eig_translation = Eigen::Vector3d::Zero();  // J^T J, ascending

  // --- Planes and points of this scan, for display ----------------------------------------------
  // kPpf: the skeleton tracker's world-frame skeleton-plane window after this scan. Track
  // ids are stable for the same physical plane across scans (ppf_msgs/SkeletonPlaneArray).
  std::vector<SkeletonPlane> skeleton_planes;
  // Config::output_deskewed_points: the points this scan was registered with (range-filtered,
  // downsampled, de-skewed to stamp_s), LiDAR frame; T_world_lidar places them in the world.
  std::vector<Eigen::Vector3f> deskewed_points_lidar;
  // Same switch, same order: each point's PPF label (all kScattered in kKnn mode and in the scan
  // that initializes the map), so a plot can show the skeleton points next to their planes.
  std::vector<PointLabel> deskewed_point_labels;
};

class LioPpf {
 public:
  explicit LioPpf(const Config& config = Config());
  ~LioPpf();
  LioPpf(const LioPpf&) = delete;
  LioPpf& operator=(const LioPpf&) = delete;

  void AddImu(const ImuSample& sample);

  // Decodes the cloud now (the view need not outlive the call) and queues it. A malformed cloud
  // is queued as a kRejected result so results stay in input order. Returns the scan's input id
  // (ScanResult::input_id): 1, 2, 3, ... over the object's life, Reset() included.
  uint64_t AddScan(const CloudView& cloud);

  // Processes queued scans whose IMU coverage reaches the scan end (all of them if flush).
  std::vector<ScanResult> Process(bool flush = false);

  // AddScan + Process(true), returning the result of this scan (convenience for tests/tools).
  ScanResult ProcessScan(const CloudView& cloud);

  void Reset();  // forget state, map and queues; initialization starts over

  const Config& config() const;
  MapStats map_stats() const;
  InputStats input_stats() const;
  // A copy of the kNN map's points in the world frame of the results (the current T_world_map
  // applied): what the scans are registered against now, bounded as MapStats says. In kPpf the
  // skeleton points are not in it (they are kept as plane patches, not points).
  std::vector<Eigen::Vector3f> LocalMapPoints() const;
  const TimeFieldInfo& time_field_info() const;
  bool initialized() const;
  bool lidar_only() const;  // LiDAR-only mode decided (imu.mode none, or auto without IMU)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ppf
