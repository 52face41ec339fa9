// LioPpf: the LiDAR-inertial odometry facade. Middleware free: feed ImuSample and CloudView, get
// one ScanResult per scan.
//
// Usage:
//   ppf::Config config;                  // or ppf::LoadConfigYaml("config/hdl64.yaml", ...)
//                                        // (config.hpp; every key in config/reference.yaml)
//   ppf::LioPpf lio(config);
//   lio.AddImu(imu);                     // any order relative to scans, each stream in time order
//   lio.AddScan(cloud);                  // decoded at once: the view may be released afterwards
//   for (const ppf::ScanResult& r : lio.Process()) { ... }   // scans whose IMU coverage is complete
//   lio.Process(/*flush=*/true);         // at the end: process the rest (IMU extrapolated)
//
// Pipeline per scan (timings in ScanResult::timings):
//   preprocess  decode layout and per-point time (time_field.hpp), drop NaN points
//   downsample  stride/range filter and voxel grid (Config::scan_voxel_size, 0.5 m) of the raw
//               scan; every kept point has its voxel's mean time (preprocess.hpp)
//   deskew      propagate the IMU to the scan end (midpoint, imu_propagation.hpp) and move every
//               kept point to the LiDAR pose at the scan END with its own time (deskew.hpp)
//   ppf         the skeleton tracker labels points kSkeleton / kScattered / kDiscarded (kPpf only;
//               ppf/skeleton_tracker.hpp, parameters Config::ppf)
//   residuals   + update: IEKF (lio/iekf.hpp); every iteration the kNN rows of the kScattered
//               points and, in kPpf, the skeleton rows (lio/residual_provider.hpp)
//   map insert  points labelled kScattered ("map points") go into the kNN VoxelMap
//
// Initialization (imu_init.hpp): needs Config::init.duration_s (1 s) of static IMU data; scans
// before that return Status::kInitializing. Motion during that window restarts the collection.
// The first scan after initialization builds the map (Status::kOk, reason "map initialized").
// Moving start (Config::init.moving_start, on by default; moving_start.hpp): while the IMU is
// judged, the scans are registered LiDAR-only (as below, their map in the first one's LiDAR
// frame; the rotation predicted and de-skewed from the gyro), still Status::kInitializing. If the
// IMU shows rest, that map is dropped and the static path above runs. If its window is refused
// for motion, the poses of init.moving_start_window_s of scans (after 5 warm-up scans) and the
// preintegrated IMU give gravity, velocity and gyro bias, and the filter continues as LIO from
// the last of them, which is the first kOk result (reason "moving-start initialization: ...";
// one INFO log line with the gravity estimate). The map frame is then the first registered
// scan's LiDAR frame (T_world_map levels it). An estimate that fails its checks, or a scan that
// does not register, starts the window again. Known gap: a start at constant velocity in a
// straight line without vibration looks like rest to an IMU and takes the static path (with
// zero velocity).
//
// LiDAR-only (Config::imu_mode none, or kAuto when scans spanning imu_auto_wait_s came without an
// IMU sample; ppf_offline decides at once from a bag without an IMU topic): no static
// initialization, the first scan builds the map. The prediction is a constant-velocity model of
// the last two registered poses (motion_model.hpp); points with their own time are de-skewed from
// it. Each scan is first aligned coarsely from several guesses (the model, no motion, the model's
// turn scaled or turned further; hypothesis_search.hpp) and the best-fitting one becomes the
// prediction of the usual update and of the skeleton tracker. Gravity is unobservable: the world
// frame is the first scan's LiDAR frame (z is the LiDAR's z then, not "up"), T_world_map stays
// the identity and velocity, biases and gravity are not estimated (velocity_world and
// angular_velocity report the model's). ScanResult::fit says how well the scan fit the map; a fit
// below lidar_only.min_fit is Status::kDegenerate with the reason. imu.mode none is decided once
// per object; ScanResult::lidar_only marks each such scan.
//
// Late IMU (kAuto decided LiDAR-only, then IMU samples arrive: a driver that started late): the
// scans go on being registered LiDAR-only, with the gyro predicting the turn, while the
// moving-start estimate above runs on their poses in the LiDAR-only map; once it passes, the IMU
// predicts from that scan on (ScanResult::lio_started_late, one INFO line). No reset and no jump:
// the map and the world stay the LiDAR-only start's, so z is not "up" in it (T_world_map stays
// the identity; gravity_map says where down is). For a gravity-aligned world when the IMU may
// start late, set imu.mode lio (scans then wait for the IMU's static initialization).
//
// IMU loss (LIO running): when the IMU stream stops, or delivers only invalid samples, while the
// scans go on, a scan ending more than Config::imu_loss_timeout_s after the last IMU sample (the
// later scans showing the stream has stalled) is registered LiDAR-only as above: the
// constant-velocity model starts from the filter's own velocity and turn rate, the same guesses
// are aligned, and the map, gravity and biases are kept (one WARN "IMU lost ...: continuing
// LiDAR-only", ScanResult::imu_lost on each such scan). Scans closer to the last sample are
// propagated with it held, as before. When IMU samples are back, the first scan they cover
// resumes LIO: propagation starts from the last LiDAR-only pose with the velocity of the
// LiDAR-only pose history, biases and gravity with their covariance from before the loss (no
// reset, no jump; one INFO line, and ScanResult::imu_gap_s on that scan).
//
// Time glitches: an IMU sample or scan older than the previous one (bag loop) resets the filter
// and the map (Status::kReset with the reason) and initialization starts over. An IMU gap that
// exceeds max_imu_gap_s without scans needing the fallback meanwhile (both streams silent: a
// network link down for a moment, a stalled driver) is bridged up to max_imu_gap_bridge_s
// (integrated across, uncertainty widened); after a longer one the first scan is registered
// LiDAR-only and LIO re-anchors, as after an IMU loss. A reset would need a static start again,
// which a moving robot never gives, so its odometry would not come back.
// Single bad values never reset or stall: a point time outside the plausible sweep window (more
// than 0.01 s before a scan-start header stamp, or more than 2 x time.scan_period after it;
// time_field.hpp) is dropped and counted (ScanResult::points_bad_time) and does not move the
// scan's time span; a scan that loses most of its points so is skipped (kRejected, nothing
// changed). An IMU sample with the newest sample's stamp is dropped if its values are the same
// (InputStats::imu_duplicates); with other values it is a conflict, decided by the next sample:
// the copy consistent with the samples on either side is kept, or none (never the first by
// arrival; ScanResult::imu_conflicts, one WARN). Every gap between valid IMU samples longer than
// imu.max_gap_warn (0.1 s) is counted (ScanResult::imu_gaps, imu_gap_longest_s) and named in one
// WARN. input_stats() has the totals.
// Clock offset: while IMU samples keep arriving between scans but the newest is a second or more
// behind every scan's end (10 scans in a row), the IMU's clock runs behind the LiDAR's: one WARN
// names the offset, the samples are not used, and the scans are registered LiDAR-only (the
// IMU-loss fallback if LIO ran, else as without an IMU; ScanResult::imu_clock_offset_s). When
// the clocks agree again for as many scans, the IMU is taken up (LIO resumes, or starts as a late
// IMU), without a reset. An IMU ahead is not judged: a core lagging behind its input sees that.
// Malformed clouds return Status::kRejected and change nothing.
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
  // What LioPpf::AddScan returned for the scan this result belongs to. 0 for a notice that
  // belongs to no scan: a kReset the IMU stream caused (its time going back), reported before
  // the next scan's result. A gap too long to bridge resets nothing (see the class comment).
  uint64_t input_id = 0;
  double stamp_s = 0.0;        // time of the pose: the scan end
  double scan_begin_s = 0.0;   // earliest point time
  Status status = Status::kInitializing;
  std::string reason;          // human readable: why not kOk, notes (e.g. time field fallback)
  bool pose_valid = false;     // false for kInitializing / kRejected / kReset
  double imu_gap_s = 0.0;      // > 0: an IMU gap this long before this scan was bridged
  // IMU input since the previous result (InputStats has the totals): gaps between valid samples
  // longer than imu.max_gap_warn and the longest of them, and stamps that came twice with
  // different values (the copy kept is the one consistent with the samples either side, or
  // neither: imu_conflicts_unresolved).
  size_t imu_gaps = 0;
  double imu_gap_longest_s = 0.0;
  size_t imu_conflicts = 0;
  size_t imu_conflicts_unresolved = 0;
  // != 0: the IMU's clock runs this many seconds behind the LiDAR's (scan end minus the newest
  // IMU sample, both streams live): the scan was registered LiDAR-only and the IMU is not used
  // until the clocks agree again (the reason says so; imu_lost is set too once LIO had run).
  double imu_clock_offset_s = 0.0;
  // Registered LiDAR-only because the IMU stream is lost mid-run (IMU loss fallback, Config::
  // imu_loss_timeout_s); the reason says so. The first LIO scan after it has imu_gap_s > 0.
  bool imu_lost = false;
  // The first LIO scan after an IMU loss (the reason says "LIO resumed"; imu_gap_s is the gap).
  bool lio_resumed = false;
  // Registered without an IMU because none has come (imu.mode none, or auto that decided none),
  // including the window in which IMU samples that arrived late are judged (the "Late IMU"
  // paragraph of LioPpf's class comment). Not set for an IMU loss (imu_lost) or a moving start.
  bool lidar_only = false;
  // The scan with which the LiDAR-only start became LiDAR-inertial (late IMU): from it on the
  // IMU predicts, in the same world as before (no jump; its z is not "up", gravity_map says
  // where down is).
  bool lio_started_late = false;

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

  StageTimings timings;
  size_t map_size = 0;            // points in the kNN map after insertion

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
  // kPpf: the skeleton tracker's world-frame skeleton-plane window after this scan. Track
  // ids are stable for the same physical plane across scans (ppf_msgs/SkeletonPlaneArray).
  std::vector<SkeletonPlane> skeleton_planes;
  // kPpf: the skeleton tracker's plane patches (plane_patch_map.hpp), the skeleton
  // points' share of the local map (a patch summarises up to patch_max_points points).
  size_t skeleton_patches = 0;
  size_t map_inserted = 0;        // points offered to the map

  // Config::output_deskewed_points: the points this scan was registered with (range-filtered,
  // downsampled, de-skewed to stamp_s), LiDAR frame; T_world_lidar places them in the world.
  std::vector<Eigen::Vector3f> deskewed_points_lidar;
  // Same switch, same order: each point's PPF label (all kScattered in kKnn mode and in the scan
  // that initializes the map), so a plot can show the skeleton points next to their planes.
  std::vector<PointLabel> deskewed_point_labels;

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
  // With consistency.check: how far the scan alone (wide gate, no prior; ProbePose) would still
  // move the posterior; large values with overruled false say the map and the IMU disagree.
  double disagreement_rot_deg = 0.0;
  double disagreement_pos_m = 0.0;

  int iterations = 0;
  bool converged = false;
  Eigen::Vector3d eig_rotation = Eigen::Vector3d::Zero();     // J^T J, ascending
  Eigen::Vector3d eig_translation = Eigen::Vector3d::Zero();  // J^T J, ascending
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
