#include "ppf_core/lio_ppf.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "ppf_core/deskew.hpp"
#include "ppf_core/hypothesis_search.hpp"
#include "ppf_core/motion_model.hpp"
#include "ppf_core/moving_start.hpp"
#include "ppf_core/preprocess.hpp"
#include "ppf_core/skeleton_tracker.hpp"
#include "ppf_core/so3.hpp"

namespace ppf {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

void Append(std::string* reason, const std::string& what) {
  if (what.empty()) return;
  if (!reason->empty()) *reason += "; ";
  *reason += what;
}

}  // namespace

const char* StatusName(Status status) {
  switch (status) {
    case Status::kOk:
      return "ok";
    case Status::kInitializing:
      return "initializing";
    case Status::kDegenerate:
      return "degenerate";
    case Status::kReset:
      return "reset";
    case Status::kRejected:
      return "rejected";
  }
  return "?";
}

struct LioPpf::Impl {
  struct QueuedScan {
    uint64_t id = 0;
    bool rejected = false;
    std::string error;
    double stamp_s = 0.0;
    double decode_ms = 0.0;
    DecodedScan scan;
  };

  explicit Impl(const Config& c) : config(c), map(c.map) {
    for (const std::string& note : ValidateConfig(&config)) Log(LogLevel::kWarn, "config: " + note);
    if (config.num_threads > 0) {
      config.knn.num_threads = config.num_threads;
    }
    decoder = TimeFieldDecoder(config.time, config.log);
    init = ImuInitializer(config.init);
    map = VoxelMap(config.map);
    knn = std::make_shared<KnnResidualProvider>(config.knn);
    // PPF: the paper's plane pre-fitting + skeleton tracking is the default kPpf splitter.
    if (config.mode == Mode::kPpf) {
      if (config.num_threads > 0 && config.ppf.num_threads == 0) {
        config.ppf.num_threads = config.num_threads;
      }
      ppf_tracker = std::make_shared<SkeletonTracker>(config.ppf);
      splitter = ppf_tracker;
    }
  }

  void Log(LogLevel level, const std::string& msg) const {
    if (config.log) config.log(level, msg);
  }

  // Drops filter state and map; the next IMU samples start a new initialization.
  void ResetFilter(const std::string& reason) {
    initialized = false;
    map_initialized = false;
    moving_init = false;
    moving_refused = false;
    moving_poses.clear();
    moving_scans = 0;
    init.Reset();
    motion.Reset();
    recent_fits.clear();
    map.clear();
    imu.clear();
    state = NavState();
    last_scan_end = -std::numeric_limits<double>::infinity();
    bridged_gaps.clear();
    if (splitter) splitter->Reset();
    for (auto& p : extra) p->Reset();
    knn->Reset();
    scans_since_prune = 0;
    // LiDAR-only needs no initialization: the next scan starts the map again.
    if (lidar_only) initialized = true;
    if (!reason.empty()) {
      Log(LogLevel::kWarn, "reset: " + reason);
      ScanResult r;
      r.status = Status::kReset;
      r.reason = reason;
      r.stamp_s = last_imu_stamp;
      pending.push_back(r);
    }
  }

  void AddImu(const ImuSample& s) {
    // kNone: ignored even before the first scan has made the decision (DecideImuMode).
    if (lidar_only || config.imu_mode == ImuMode::kNone) {
      ++ignored_imu;
      return;
    }
    if (!lio_decided) {
      lio_decided = true;
      if (config.imu_mode == ImuMode::kAuto) {
        Log(LogLevel::kInfo, "IMU data present: LiDAR-inertial mode");
      }
    }
    if (!std::isfinite(s.stamp_s) || !s.angular_velocity.allFinite() ||
        !s.linear_acceleration.allFinite()) {
      ++dropped_imu;
      return;
    }
    if (s.stamp_s < last_imu_stamp - 1e-9) {
      std::ostringstream os;
      os << "IMU time went backwards by " << last_imu_stamp - s.stamp_s << " s";
      last_imu_stamp = -std::numeric_limits<double>::infinity();
      ResetFilter(os.str());
    } else if (moving_init && s.stamp_s - last_imu_stamp > config.max_imu_gap_s) {
      // The preintegration would span the gap: register the scans again after it.
      std::ostringstream os;
      os << "IMU gap of " << s.stamp_s - last_imu_stamp << " s";
      RestartMovingInit(os.str());
    } else if (initialized && s.stamp_s - last_imu_stamp > config.max_imu_gap_s) {
      const double gap = s.stamp_s - last_imu_stamp;
      std::ostringstream os;
      os << "IMU gap of " << gap << " s > max_imu_gap " << config.max_imu_gap_s << " s";
      if (gap <= config.max_imu_gap_bridge_s) {
        // Widened when the next scan has been propagated across it (ProcessOne): a scan still
        // queued from before the gap must not see the extra uncertainty.
        bridged_gaps.push_back({last_imu_stamp, gap});
        Log(LogLevel::kWarn, os.str() + ": bridged (state and map kept, uncertainty widened)");
      } else {
        os << " and > max_imu_gap_bridge " << config.max_imu_gap_bridge_s << " s";
        ResetFilter(os.str());
      }
    }
    last_imu_stamp = s.stamp_s;
    imu.push_back(s);
    if (!initialized) {
      // The scans are registered LiDAR-only while the IMU is judged, so that a moving start has
      // its window of poses by the time the IMU is refused; a static start discards them.
      if (config.init.moving_start) moving_init = true;
      const ImuInitializer::State st = init.Add(s);
      if (st == ImuInitializer::State::kRestarted) {
        Log(LogLevel::kWarn, init.reason());
        if (moving_init && init.refused_for_motion() && !moving_refused) {
          moving_refused = true;
          Log(LogLevel::kInfo,
              "no rest at start: moving-start initialization (gravity and velocity from the "
              "LiDAR-only registration of the first scans and the IMU)");
        }
      }
      if (st == ImuInitializer::State::kDone) StartFilter();
    }
    // Bounded buffer even if no scan ever arrives.
    while (imu.size() > 2 && imu[1].stamp_s < state.stamp_s - 1.0 && initialized) imu.pop_front();
    while (imu.size() > 20000) imu.pop_front();
  }

  void StartFilter() {
    if (moving_init) {
      // Static after all: the LiDAR-only map of the first scans goes, the next scan builds the
      // map as after any static start.
      ClearMovingInit();
      moving_init = false;
      moving_refused = false;
    }
    state = NavState();
    state.stamp_s = init.stamp_s();
    state.R_world_imu = init.R_world_imu();
    state.gyro_bias = init.gyro_bias();
    state.gravity_world = init.gravity_world();
    acc_scale = init.acc_scale();
    state.P = StateCov::Zero();
    state.P.block<3, 3>(kRot, kRot).diagonal().setConstant(1e-4);
    state.P.block<3, 3>(kPos, kPos).diagonal().setConstant(1e-6);
    state.P.block<3, 3>(kVel, kVel).diagonal().setConstant(1e-4);
    state.P.block<3, 3>(kBg, kBg).diagonal().setConstant(1e-6);
    state.P.block<3, 3>(kBa, kBa).diagonal().setConstant(1e-3);
    // The gravity direction is as uncertain as the accelerometer bias it cannot be told from at
    // rest (bias / g radians); the bias prior above is 0.03 m/s^2 (1 sigma).
    const double tilt_sigma = std::sqrt(state.P(kBa, kBa)) / state.gravity_world.norm();
    state.P.block<2, 2>(kGrav, kGrav).diagonal().setConstant(tilt_sigma * tilt_sigma);
    initialized = true;
    std::ostringstream os;
    os << "IMU initialized at t=" << state.stamp_s << ": |g|=" << -state.gravity_world.z()
       << " m/s^2, acc_scale=" << init.acc_scale() << ", gyro bias=[" << state.gyro_bias.transpose()
       << "]";
    Log(LogLevel::kInfo, os.str());
  }

  uint64_t AddScan(const CloudView& cloud) {
    QueuedScan q;
    q.id = ++last_input_id;
    q.stamp_s = cloud.stamp_s;
    const auto t0 = Clock::now();
    std::string error;
    if (!std::isfinite(cloud.stamp_s)) {
      q.rejected = true;
      q.error = "header stamp is not finite";
    } else if (!decoder.Decode(cloud, &q.scan, &error)) {
      q.rejected = true;
      q.error = error;
    }
    if (q.rejected) Log(LogLevel::kWarn, "scan rejected: " + q.error);
    q.decode_ms = MsSince(t0);
    scans.push_back(std::move(q));
    return last_input_id;
  }

  ScanResult Rejected(const QueuedScan& q) const {
    ScanResult r;
    r.input_id = q.id;
    r.stamp_s = q.stamp_s;
    r.status = Status::kRejected;
    r.reason = "malformed cloud: " + q.error;
    r.map_size = map.size();
    return r;
  }

  std::vector<ScanResult> Process(bool flush) {
    std::vector<ScanResult> out;
    if (!DecideImuMode(flush)) return out;
    while (!scans.empty()) {
      QueuedScan& q = scans.front();
      // Wait for the IMU to cover the scan, unless the IMU stream has stalled: scans newer than
      // the last IMU sample by more than max_imu_gap_s are not held back forever.
      const bool imu_stalled = scans.back().stamp_s - last_imu_stamp > config.max_imu_gap_s;
      if (!q.rejected && !flush && !imu_stalled && last_imu_stamp < q.scan.t_end) break;
      // Reset notices belong before the first scan processed after the reset.
      for (ScanResult& r : pending) out.push_back(std::move(r));
      pending.clear();
      if (q.rejected) {
        out.push_back(Rejected(q));
      } else {
        const bool moving = moving_init;
        out.push_back(ProcessOne(q));
        if (moving) MovingInitStep(&out.back());
      }
      scans.pop_front();
    }
    if (flush) {
      for (ScanResult& r : pending) out.push_back(std::move(r));
      pending.clear();
    }
    return out;
  }

  // Rotation of the map frame into the frame whose -z is the estimated gravity: the smallest one,
  // so yaw is kept.
  Eigen::Isometry3d WorldFromMap() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond::FromTwoVectors(state.gravity_world.normalized(),
                                                    -Eigen::Vector3d::UnitZ())
                     .toRotationMatrix();
    return T;
  }

  void FillState(ScanResult* r) const {
    r->T_world_map = WorldFromMap();
    const Eigen::Matrix3d R = r->T_world_map.linear();
    r->T_world_imu = r->T_world_map * state.T_world_imu();
    r->T_world_lidar = r->T_world_imu * config.T_imu_lidar;
    r->velocity_world = R * state.v_world;
    r->angular_velocity = gyro_at_scan_end - state.gyro_bias;
    if (config.output_deskewed_points) {
      r->deskewed_points_lidar = frame.points_lidar;
      r->deskewed_point_labels = frame.labels;
    }
    r->gyro_bias = state.gyro_bias;
    r->acc_bias = state.acc_bias;
    r->gravity_map = state.gravity_world;
    // Rotation errors are body-frame (unchanged); position and velocity errors turn with the map.
    StateCov J = StateCov::Identity();
    J.block<3, 3>(kPos, kPos) = R;
    J.block<3, 3>(kVel, kVel) = R;
    r->covariance = J * state.P * J.transpose();
    r->pose_covariance = r->covariance.topLeftCorner<6, 6>();
    for (SkeletonPlane& sp : r->skeleton_planes) {
      sp.plane = TransformPlane(r->T_world_map, sp.plane);
      sp.centroid = r->T_world_map * sp.centroid;
      sp.scatter = R * sp.scatter * R.transpose();
    }
  }

  ScanResult ProcessOne(QueuedScan& q) {
    const auto t_total = Clock::now();
    ScanResult r;
    r.input_id = q.id;
    const DecodedScan& scan = q.scan;
    r.stamp_s = scan.t_end;
    r.scan_begin_s = scan.t_begin;
    r.input_points = scan.input_points;
    r.dropped_nan = scan.dropped_nan;
    r.map_size = map.size();
    if (!initialized && !moving_init) {
      r.status = Status::kInitializing;
      r.reason = init.reason().empty() ? "waiting for IMU data" : init.reason();
      return r;
    }
    // The moving-start initialization registers its scans as LiDAR-only does.
    const bool lidar = lidar_only || moving_init;
    if (!lidar && scan.t_end <= state.stamp_s && !map_initialized) {
      r.status = Status::kInitializing;
      r.reason = "scan ends before IMU initialization finished";
      return r;
    }
    if (scan.t_end < last_scan_end - 1e-6) {
      std::ostringstream os;
      os << "scan time went backwards by " << last_scan_end - scan.t_end << " s";
      ResetFilter("");
      Log(LogLevel::kWarn, "reset: " + os.str());
      r.status = Status::kReset;
      r.reason = os.str();
      return r;
    }
    Append(&r.reason, scan.note);
    if (config.mode == Mode::kPpf && !splitter) {
      Append(&r.reason, "ppf mode requested but no ScanSplitter installed: running kNN");
    }

    // Preprocess: stride and range filter plus the voxel grid, on the raw scan; each kept point
    // carries the mean time of its voxel (preprocess.hpp: why this comes before de-skew).
    auto t0 = Clock::now();
    std::vector<TimedPoint> pts;
    PreprocessOptions pre;
    pre.min_range = config.min_range;
    pre.max_range = config.max_range;
    pre.point_stride = config.point_stride;
    pre.voxel_size = config.scan_voxel_size;
    const PreprocessStats pre_stats = downsampler.Run(scan.points, scan.t_begin, pre, &pts);
    r.valid_points = pre_stats.valid_points;
    r.downsampled_points = pre_stats.downsampled_points;
    r.timings.preprocess = q.decode_ms;
    r.timings.downsample = MsSince(t0);

    // Propagate to the scan end and de-skew the downsampled points.
    t0 = Clock::now();
    if (lidar && !map_initialized) StartLidarOnly(scan.t_end);
    const double t_end = std::max(scan.t_end, state.stamp_s);
    PoseTrace trace;
    if (lidar) {
      PredictConstantVelocity(t_end, &trace);
      if (moving_init && motion.has_pose()) PredictGyro(t_end, &trace);
    } else {
      std::vector<ImuSample> samples(imu.begin(), imu.end());
      PropagateImu(samples, t_end, acc_scale, config.noise, &state, &trace);
      for (const ImuSample& s : samples) {
        if (s.stamp_s > t_end && s.stamp_s != samples.front().stamp_s) break;
        gyro_at_scan_end = s.angular_velocity;
      }
    }
    if (!lidar && t_end - last_imu_stamp > 0.02) {
      std::ostringstream os;
      os << "IMU extrapolated by " << t_end - last_imu_stamp << " s (last sample held)";
      Append(&r.reason, os.str());
    }
    while (!bridged_gaps.empty() && bridged_gaps.front().begin_s < t_end) {
      WidenForGap(bridged_gaps.front().length_s);
      r.imu_gap_s = std::max(r.imu_gap_s, bridged_gaps.front().length_s);
      bridged_gaps.pop_front();
    }
    if (r.imu_gap_s > 0.0) {
      std::ostringstream os;
      os << "IMU gap of " << r.imu_gap_s << " s bridged";
      Append(&r.reason, os.str());
    }
    frame = ScanFrame();
    if (scan.has_time_field || scan.times_estimated) {
      DeskewToEnd(pts, trace, t_end, config.T_imu_lidar, &frame.points_lidar, config.num_threads);
    } else {
      frame.points_lidar.reserve(pts.size());
      for (const TimedPoint& tp : pts) frame.points_lidar.push_back(tp.p);
    }
    r.timings.deskew = MsSince(t0);
    last_scan_end = t_end;
    r.stamp_s = t_end;
    // Keep one sample at or before the state time for the next interpolation (the moving-start
    // initialization keeps all: it preintegrates from its first scan).
    while (!moving_init && imu.size() > 2 && imu[1].stamp_s <= state.stamp_s) imu.pop_front();

    frame.stamp_s = t_end;
    frame.labels.assign(frame.points_lidar.size(), PointLabel::kScattered);
    frame.T_imu_lidar = config.T_imu_lidar;
    frame.T_world_lidar_predicted = state.T_world_imu() * config.T_imu_lidar;
    frame.map = &map;
    frame.residual_max_range = config.iekf.residual_max_range;

    if (!map_initialized) {
      t0 = Clock::now();
      InsertScattered(frame, frame.T_world_lidar_predicted, &r);
      map_initialized = !frame.points_lidar.empty();
      map_init_stamp_s = t_end;
      if (lidar && map_initialized) motion.Update(state.T_world_imu(), t_end);
      if (lidar_only && map_initialized) {
        Append(&r.reason, "LiDAR-only (no IMU): world frame = this scan's LiDAR frame");
      }
      r.timings.map_insert = MsSince(t0);
      r.status = map_initialized ? Status::kOk : Status::kInitializing;
      Append(&r.reason, map_initialized ? "map initialized" : "empty first scan");
      r.pose_valid = true;
      r.scattered_points = frame.points_lidar.size();
      FillState(&r);
      r.map_size = map.size();
      r.timings.total = MsSince(t_total) + q.decode_ms;
      return r;
    }

    CoarseAlignment coarse;
    if (lidar) {
      t0 = Clock::now();
      coarse = AlignGuesses(t_end);
      r.timings.guesses = MsSince(t0);
    }

    if (config.mode == Mode::kPpf && splitter) {
      t0 = Clock::now();
      splitter->Split(&frame);
      frame.labels.resize(frame.points_lidar.size(), PointLabel::kScattered);
      r.timings.ppf = MsSince(t0);
    }
    for (PointLabel l : frame.labels) {
      if (l == PointLabel::kSkeleton)
        ++r.skeleton_points;
      else if (l == PointLabel::kScattered)
        ++r.scattered_points;
      else
        ++r.discarded_points;
    }

    std::vector<ResidualProvider*> providers;
    providers.push_back(knn.get());
    if (config.mode == Mode::kPpf) {
      // PPF: the built-in tracker's skeleton residuals, only while it is the installed splitter.
      if (ppf_tracker && splitter == ppf_tracker) {
        providers.push_back(ppf_tracker->residual_provider().get());
      }
      for (auto& p : extra) providers.push_back(p.get());
    }
    for (ResidualProvider* p : providers) p->BeginScan(frame);
    IekfOptions iekf = config.iekf;
    if (t_end - map_init_stamp_s < iekf.refined_gate_after_s) iekf.refined_gate = 0.0;
    const IekfReport rep = IekfUpdate(iekf, config.T_imu_lidar, providers, &state);
    r.timings.residuals = rep.residuals_ms;
    r.timings.update = rep.update_ms;
    r.iterations = rep.iterations;
    r.converged = rep.converged;
    r.eig_rotation = rep.eig_rotation;
    r.eig_translation = rep.eig_translation;
    for (size_t i = 0; i < rep.rows_per_provider.size(); ++i) {
      if (i == 0)
        r.knn_residuals = static_cast<size_t>(rep.rows_per_provider[i]);
      else
        r.skeleton_residuals += static_cast<size_t>(rep.rows_per_provider[i]);
    }
    const Eigen::Isometry3d T_world_lidar = state.T_world_imu() * config.T_imu_lidar;
    if (config.mode == Mode::kPpf && splitter) {
      t0 = Clock::now();
      splitter->Finish(frame, T_world_lidar);
      if (ppf_tracker && splitter == ppf_tracker) {
        r.skeleton_planes = ppf_tracker->window().planes();  // map frame until FillState
        r.skeleton_patches = ppf_tracker->patch_map().num_patches();
      }
      r.timings.ppf += MsSince(t0);
    }
    for (ResidualProvider* p : providers) p->EndScan(T_world_lidar);

    if (rep.skipped) {
      r.status = Status::kDegenerate;
      std::ostringstream os;
      os << "too few residuals (" << rep.num_rows << " < " << config.iekf.min_rows
         << "): " << (lidar ? "motion-model prediction only" : "IMU prediction only");
      Append(&r.reason, os.str());
    } else if (rep.degenerate) {
      r.status = Status::kDegenerate;
      Append(&r.reason, "degenerate: " + rep.degenerate_reason);
    } else {
      r.status = Status::kOk;
    }
    if (lidar) {
      r.fit = coarse.fit;
      r.motion_guess = coarse.name;
      r.guesses_tried = coarse.tried;
      if (coarse.fit < config.lidar_only.min_fit) {
        std::ostringstream os;
        os.precision(2);
        os << "LiDAR-only: poor fit " << coarse.fit << " < " << config.lidar_only.min_fit
           << " after " << coarse.tried << " guesses (best " << coarse.name
           << "): the pose may be off";
        r.status = Status::kDegenerate;
        Append(&r.reason, os.str());
      }
      motion.Update(state.T_world_imu(), t_end);
    }
    r.pose_valid = true;

    t0 = Clock::now();
    // A scan that could not be registered is not trusted to extend the map.
    if (!rep.skipped) InsertScattered(frame, T_world_lidar, &r);
    if (config.map_radius > 0.0 && ++scans_since_prune >= 10) {
      map.RemoveFarFrom(state.p_world_imu, config.map_radius);
      scans_since_prune = 0;
    }
    r.timings.map_insert = MsSince(t0);
    r.map_size = map.size();
    FillState(&r);
    r.timings.total = MsSince(t_total) + q.decode_ms;
    return r;
  }

  // kAuto: decides when the input says whether there is an IMU. Returns false while undecided
  // (the scans wait: none is lost to the decision).
  bool DecideImuMode(bool flush) {
    if (lidar_only || lio_decided) return true;
    if (config.imu_mode == ImuMode::kLio) {
      lio_decided = true;
      return true;
    }
    const bool none = config.imu_mode == ImuMode::kNone;
    if (!none) {
      if (scans.empty()) return true;
      const double span = scans.back().stamp_s - scans.front().stamp_s;
      if (!flush && span < config.imu_auto_wait_s) return false;
    }
    lidar_only = true;
    initialized = true;
    imu.clear();
    std::ostringstream os;
    os << (none ? "imu.mode none" : "no IMU data with the first scans")
       << ": LiDAR-only mode (constant-velocity prediction, world = first scan's LiDAR frame)";
    Log(LogLevel::kInfo, os.str());
    return true;
  }

  // The first scan of a LiDAR-only map: the world is its LiDAR frame. Gravity cannot be observed,
  // so it is set straight down in that frame only to make T_world_map the identity.
  void StartLidarOnly(double t) {
    state = NavState();
    state.stamp_s = t;
    const Eigen::Isometry3d T_world_imu = config.T_imu_lidar.inverse();
    state.R_world_imu = T_world_imu.linear();
    state.p_world_imu = T_world_imu.translation();
    state.gravity_world = Eigen::Vector3d(0.0, 0.0, -9.80665);
    state.P = StateCov::Identity() * 1e-6;
    motion.Reset();
  }

  // The state at t_end from the constant-velocity model; biases, velocity and gravity are not
  // observed and stay fixed (their covariance tiny and uncorrelated, so updates leave them).
  void PredictConstantVelocity(double t_end, PoseTrace* trace) {
    // Before the map's first scan there is nothing to extrapolate: StartLidarOnly's pose stands.
    const Eigen::Isometry3d T = motion.has_pose() ? motion.Predict(t_end) : state.T_world_imu();
    *trace = motion.Trace();
    if (!motion.has_pose()) {
      trace->knots.front().R = T.linear();
      trace->knots.front().p = T.translation();
    }
    state.R_world_imu = T.linear();
    state.p_world_imu = T.translation();
    state.v_world = motion.velocity_world();
    state.stamp_s = t_end;
    gyro_at_scan_end = motion.angular_velocity();
    SetLidarOnlyPrior();
  }

  void SetLidarOnlyPrior() {
    const double rot = config.lidar_only.prior_rot_std;
    const double pos = config.lidar_only.prior_pos_std;
    state.P = StateCov::Identity() * 1e-6;
    state.P.block<3, 3>(kRot, kRot).diagonal().setConstant(rot * rot);
    state.P.block<3, 3>(kPos, kPos).diagonal().setConstant(pos * pos);
  }

  // The guesses of hypothesis_search.hpp around the model's prediction (state at t_end); the
  // best aligned one becomes the prediction of the update and of the skeleton tracker.
  // Moving start: the gyro measures the turn however fast it is (a hand-held sensor turns at
  // 150 deg/s); only the translation comes from the constant-velocity model. Gravity is not
  // needed for this, nor the bias (0.1 s of a few mrad/s).
  void PredictGyro(double t_end, PoseTrace* trace) {
    const double t0 = motion.stamp();
    const std::vector<ImuSample> samples(imu.begin(), imu.end());
    PoseTrace g;
    ImuKnot k;
    k.t = t0;
    k.R = motion.pose().linear();
    k.p = motion.pose().translation();
    k.v = motion.velocity_world();
    std::vector<double> times{t0};
    for (const ImuSample& s : samples) {
      if (s.stamp_s > t0 && s.stamp_s < t_end) times.push_back(s.stamp_s);
    }
    times.push_back(t_end);
    for (size_t i = 0; i + 1 < times.size(); ++i) {
      const double h = times[i + 1] - times[i];
      k.omega = 0.5 * (InterpolateImu(samples, times[i]).angular_velocity +
                       InterpolateImu(samples, times[i + 1]).angular_velocity);
      g.knots.push_back(k);
      k.t = times[i + 1];
      k.R = NormalizeRotation(k.R * SO3Exp(k.omega * h));
      k.p += k.v * h;
    }
    k.omega = InterpolateImu(samples, t_end).angular_velocity;
    g.knots.push_back(k);  // holds the last rate for points after t_end
    *trace = g;
    state.R_world_imu = k.R;
    state.p_world_imu = k.p;
    gyro_at_scan_end = k.omega;
    imu_prediction = true;
  }

  CoarseAlignment AlignGuesses(double t_end) {
    const Eigen::Isometry3d& T_il = config.T_imu_lidar;
    const double dt = t_end - motion.stamp();
    const Eigen::Isometry3d T_last = motion.pose();
    const Eigen::Isometry3d T_cv = motion.Predict(t_end);
    std::vector<MotionHypothesis> h;
    if (imu_prediction) h.push_back({"gyro", state.T_world_imu() * T_il});
    imu_prediction = false;
    h.push_back({"constant velocity", T_cv * T_il});
    h.push_back({"no motion", T_last * T_il});
    for (double scale : {0.5, 1.5}) {
      Eigen::Isometry3d d = motion.Delta(dt);
      d.linear() = SO3Exp(scale * SO3Log(d.linear()));
      std::ostringstream os;
      os << "turn x" << scale;
      h.push_back({os.str(), T_last * d * T_il});
    }
    const double a = config.lidar_only.offset_deg * M_PI / 180.0;
    auto turned = [&](const std::string& name, const Eigen::Vector3d& axis, double angle) {
      Eigen::Isometry3d R = Eigen::Isometry3d::Identity();
      R.linear() = SO3Exp(axis * angle);
      h.push_back({name, T_cv * T_il * R});
    };
    if (a > 0.0) {
      turned("turn z+", Eigen::Vector3d::UnitZ(), a);
      turned("turn z-", Eigen::Vector3d::UnitZ(), -a);
      turned("turn z++", Eigen::Vector3d::UnitZ(), 2 * a);
      turned("turn z--", Eigen::Vector3d::UnitZ(), -2 * a);
      turned("turn x+", Eigen::Vector3d::UnitX(), a);
      turned("turn x-", Eigen::Vector3d::UnitX(), -a);
      turned("turn y+", Eigen::Vector3d::UnitY(), a);
      turned("turn y-", Eigen::Vector3d::UnitY(), -a);
    }
    LidarOnlyOptions options = config.lidar_only;
    if (recent_fits.size() >= 3) {
      std::vector<double> sorted(recent_fits.begin(), recent_fits.end());
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      options.good_fit =
          std::min(options.good_fit, options.good_fit_relative * sorted[sorted.size() / 2]);
    }
    CoarseAlignment c = AlignHypotheses(frame, h, options, config.iekf, config.knn);
    recent_fits.push_back(c.fit);
    if (recent_fits.size() > 10) recent_fits.pop_front();
    const Eigen::Isometry3d T_world_imu = c.T_world_lidar * T_il.inverse();
    state.R_world_imu = T_world_imu.linear();
    state.p_world_imu = T_world_imu.translation();
    frame.T_world_lidar_predicted = c.T_world_lidar;
    SetLidarOnlyPrior();
    return c;
  }

  // Moving start: the scan just registered LiDAR-only (ProcessOne) joins the window. Once the
  // IMU has been refused for motion and the window spans moving_start_window_s, gravity,
  // velocity and gyro bias are estimated and the filter continues as LIO from this scan's pose,
  // in the map these scans built. Until then the results are kInitializing: their poses are in a
  // frame whose "up" is not known yet.
  void MovingInitStep(ScanResult* r) {
    if (!moving_init) return;  // the IMU initialized statically meanwhile
    if (r->status == Status::kReset || r->status == Status::kRejected) return;
    if (r->status == Status::kInitializing && !map_initialized) return;  // empty first scan
    const bool poor_fit = r->fit < config.lidar_only.min_fit;
    const bool skipped =
        r->knn_residuals + r->skeleton_residuals < static_cast<size_t>(config.iekf.min_rows);
    if (map_initialized && moving_scans > 0 && (poor_fit || skipped)) {
      // A scan the LiDAR-only registration could not place would bend every later equation.
      // (Directions the update flags as weak keep the gyro's and the motion model's values.)
      RestartMovingInit("scan at t=" + std::to_string(r->stamp_s) + " not registered (" +
                        r->reason + ")");
      SetMovingInitResult(r);
      return;
    }
    // Warm-up: the first scan built the map without knowing the motion (a sweep at 8 m/s is
    // smeared by 0.8 m) and the next ones were predicted and de-skewed from too little of it;
    // their poses jump against the later ones, which would read as velocity and tilt.
    if (++moving_scans <= kMovingWarmupScans) {
      SetMovingInitResult(r);
      return;
    }
    MovingStartPose pose;
    pose.t = state.stamp_s;
    pose.R = state.R_world_imu;
    pose.p = state.p_world_imu;
    moving_poses.push_back(pose);
    const double window = config.init.moving_start_window_s;
    while (moving_poses.size() > 2 && pose.t - moving_poses[1].t + 1e-6 >= window) {
      moving_poses.erase(moving_poses.begin());
    }
    if (!moving_refused || pose.t - moving_poses.front().t + 1e-6 < window) {
      SetMovingInitResult(r);
      return;
    }
    MovingStartOptions opt;
    opt.gravity = config.init.gravity > 0.0 ? config.init.gravity : 9.80665;
    opt.acc_scale = config.init.acc_scale;
    opt.max_gravity_error = config.init.moving_start_max_gravity_error;
    opt.max_gyro_bias = config.init.max_gyro_bias;
    const std::vector<ImuSample> samples(imu.begin(), imu.end());
    const MovingStartEstimate e = EstimateMovingStart(samples, moving_poses, opt);
    if (!e.ok) {
      RestartMovingInit(e.reason);
      SetMovingInitResult(r);
      return;
    }
    StartFilterMoving(e);
    // This scan's pose is the filter's first: report it in the now gravity-aligned world.
    r->status = Status::kOk;
    r->pose_valid = true;
    std::ostringstream os;
    os.precision(4);
    os << "moving-start initialization: |g| free " << e.gravity_norm_free << " m/s^2 (+-"
       << e.gravity_sigma << "), speed " << e.velocity_map.norm() << " m/s";
    r->reason = os.str();
    FillState(r);
  }

  void SetMovingInitResult(ScanResult* r) const {
    r->status = Status::kInitializing;
    r->pose_valid = false;
    if (!moving_refused) {
      // The IMU may still show rest: say what the static initialization says.
      r->reason = init.reason().empty() ? "waiting for IMU data" : init.reason();
      return;
    }
    std::ostringstream os;
    os.precision(3);
    const double span = moving_poses.empty() ? 0.0 : moving_poses.back().t - moving_poses.front().t;
    os << "moving-start initialization: LiDAR-only registration, " << span << " of "
       << config.init.moving_start_window_s << " s (" << init.reason() << ")";
    r->reason = os.str();
  }

  // Starts the window again from the next scan with a new map (its frame is that scan's).
  void RestartMovingInit(const std::string& why) {
    Log(LogLevel::kWarn, "moving-start initialization restarts: " + why);
    ClearMovingInit();
  }

  void ClearMovingInit() {
    moving_poses.clear();
    moving_scans = 0;
    map_initialized = false;
    map.clear();
    motion.Reset();
    recent_fits.clear();
    if (splitter) splitter->Reset();
    for (auto& p : extra) p->Reset();
    knn->Reset();
    scans_since_prune = 0;
    last_scan_end = -std::numeric_limits<double>::infinity();
  }

  void StartFilterMoving(const MovingStartEstimate& e) {
    // R and p stay the LiDAR-only registration's: the map is in that frame.
    state.v_world = e.velocity_map;
    state.gravity_world = e.gravity_map;
    state.gyro_bias = e.gyro_bias;
    state.acc_bias.setZero();
    acc_scale = e.acc_scale;
    state.P = StateCov::Zero();
    state.P.block<3, 3>(kRot, kRot).diagonal().setConstant(1e-4);
    state.P.block<3, 3>(kPos, kPos).diagonal().setConstant(1e-4);
    // The velocity comes from positions about 0.1 s apart registered to a few centimetres.
    state.P.block<3, 3>(kVel, kVel).diagonal().setConstant(1e-3);
    // The bias comes from LiDAR-only rotations over the window; on hand-held motion they are
    // off by up to ~1 deg, i.e. 0.01 rad/s over 1.5 s.
    const double bg_sigma = 0.01;
    state.P.block<3, 3>(kBg, kBg).diagonal().setConstant(bg_sigma * bg_sigma);
    state.P.block<3, 3>(kBa, kBa).diagonal().setConstant(1e-3);
    // Tilt: the accelerometer bias (as after a static start) and the estimate's own spread.
    const double g = e.gravity_map.norm();
    const double tilt_var = state.P(kBa, kBa) / (g * g) + std::pow(e.gravity_sigma / g, 2);
    state.P.block<2, 2>(kGrav, kGrav).diagonal().setConstant(tilt_var);
    while (imu.size() > 2 && imu[1].stamp_s <= state.stamp_s) imu.pop_front();
    moving_init = false;
    moving_refused = false;
    initialized = true;
    moving_poses.clear();
    moving_scans = 0;
    const Eigen::Vector3d up = -e.gravity_map.normalized();
    const Eigen::Vector3d up_first_imu = (state.R_world_imu.transpose() * up);
    std::ostringstream os;
    os.precision(5);
    os << "IMU initialized from a moving start at t=" << state.stamp_s << ": gravity in the map ["
       << e.gravity_map.transpose() << "] m/s^2 (free |g| " << e.gravity_norm_free << " +- "
       << e.gravity_sigma << ", position rms " << e.rms_residual << " m), up in the IMU frame ["
       << up_first_imu.transpose() << "], speed " << e.velocity_map.norm() << " m/s, gyro bias ["
       << e.gyro_bias.transpose() << "], acc_scale=" << acc_scale;
    Log(LogLevel::kInfo, os.str());
  }

  // The IMU did not measure the motion during a gap: integration across it assumed the samples on
  // either side held throughout. Allow a constant unmeasured acceleration and turn rate for its
  // length, so the registration of the next scan can move the pose as far as that explains.
  void WidenForGap(double gap_s) {
    const double rot = config.gap_gyro_std * gap_s;
    const double vel = config.gap_acc_std * gap_s;
    const double pos = 0.5 * config.gap_acc_std * gap_s * gap_s;
    state.P.block<3, 3>(kRot, kRot).diagonal().array() += rot * rot;
    state.P.block<3, 3>(kVel, kVel).diagonal().array() += vel * vel;
    state.P.block<3, 3>(kPos, kPos).diagonal().array() += pos * pos;
  }

  void InsertScattered(const ScanFrame& f, const Eigen::Isometry3d& T_world_lidar, ScanResult* r) {
    const Eigen::Isometry3f T = T_world_lidar.cast<float>();
    for (size_t i = 0; i < f.points_lidar.size(); ++i) {
      if (f.labels[i] != PointLabel::kScattered) continue;
      map.Insert(T * f.points_lidar[i]);
      ++r->map_inserted;
    }
  }

  Config config;
  TimeFieldDecoder decoder;
  ImuInitializer init;
  VoxelMap map;
  std::shared_ptr<KnnResidualProvider> knn;
  std::shared_ptr<ScanSplitter> splitter;
  std::shared_ptr<SkeletonTracker> ppf_tracker;  // PPF: built-in kPpf splitter (may be replaced)
  std::vector<std::shared_ptr<ResidualProvider>> extra;
  std::deque<ImuSample> imu;
  std::deque<QueuedScan> scans;
  std::vector<ScanResult> pending;
  struct BridgedGap {
    double begin_s;   // last IMU stamp before the gap
    double length_s;
  };
  std::deque<BridgedGap> bridged_gaps;  // not yet propagated across
  NavState state;
  ScanFrame frame;
  VoxelGridDownsampler downsampler;  // keeps its hash table between scans
  bool initialized = false;
  bool map_initialized = false;
  bool lidar_only = false;         // decided: no IMU (DecideImuMode)
  bool lio_decided = false;        // decided: the IMU predicts
  // Moving start (moving_start.hpp): scans are registered LiDAR-only until the window is full.
  bool moving_init = false;
  bool moving_refused = false;  // the IMU was refused for motion: the window decides
  bool imu_prediction = false;  // moving start: this scan's prediction is PredictGyro's
  std::vector<MovingStartPose> moving_poses;  // IMU poses of the window's registered scans
  int moving_scans = 0;  // registered since the window (re)started, warm-up included
  static constexpr int kMovingWarmupScans = 5;
  double acc_scale = 1.0;          // of the initialization in use
  ConstantVelocityModel motion;    // LiDAR-only prediction (IMU frame poses)
  std::deque<double> recent_fits;  // LiDAR-only: fits of the last scans (AlignGuesses)
  size_t ignored_imu = 0;
  double map_init_stamp_s = 0.0;
  double last_imu_stamp = -std::numeric_limits<double>::infinity();
  double last_scan_end = -std::numeric_limits<double>::infinity();
  size_t dropped_imu = 0;
  int scans_since_prune = 0;
  uint64_t last_input_id = 0;
  Eigen::Vector3d gyro_at_scan_end = Eigen::Vector3d::Zero();  // raw, of the scan in ProcessOne
};

LioPpf::LioPpf(const Config& config) : impl_(std::make_unique<Impl>(config)) {}
LioPpf::~LioPpf() = default;

void LioPpf::AddImu(const ImuSample& sample) { impl_->AddImu(sample); }
uint64_t LioPpf::AddScan(const CloudView& cloud) { return impl_->AddScan(cloud); }
std::vector<ScanResult> LioPpf::Process(bool flush) { return impl_->Process(flush); }

ScanResult LioPpf::ProcessScan(const CloudView& cloud) {
  AddScan(cloud);
  std::vector<ScanResult> results = Process(true);
  if (results.empty()) {
    ScanResult r;
    r.status = Status::kRejected;
    r.reason = "internal: no result";
    return r;
  }
  return results.back();
}

void LioPpf::SetScanSplitter(std::shared_ptr<ScanSplitter> splitter) {
  impl_->splitter = std::move(splitter);
}
void LioPpf::AddResidualProvider(std::shared_ptr<ResidualProvider> provider) {
  if (provider) impl_->extra.push_back(std::move(provider));
}
void LioPpf::Reset() {
  impl_->scans.clear();
  impl_->pending.clear();
  impl_->last_imu_stamp = -std::numeric_limits<double>::infinity();
  impl_->ResetFilter("");
  impl_->decoder.Reset();
}
const Config& LioPpf::config() const { return impl_->config; }
const VoxelMap& LioPpf::map() const { return impl_->map; }
const TimeFieldInfo& LioPpf::time_field_info() const { return impl_->decoder.info(); }
bool LioPpf::initialized() const { return impl_->initialized; }
bool LioPpf::lidar_only() const { return impl_->lidar_only; }

}  // namespace ppf
