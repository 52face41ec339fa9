// The filter's start: after a static IMU initialization (StartFilter) or from a moving start,
// whose window of scans is registered LiDAR-only (moving_start.hpp) while ProcessOne runs.
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "lio_ppf_impl.hpp"

namespace ppf {

void LioPpf::Impl::StartFilter() {
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

// Moving start: the scan just registered LiDAR-only (ProcessOne) joins the window. Once the
// IMU has been refused for motion and the window spans moving_start_window_s, gravity,
// velocity and gyro bias are estimated and the filter continues as LIO from this scan's pose,
// in the map these scans built. Until then the results are kInitializing: their poses are in a
// frame whose "up" is not known yet.
void LioPpf::Impl::MovingInitStep(ScanResult* r) {
  if (!moving_init) return;  // the IMU initialized statically meanwhile
  if (r->status == Status::kReset || r->status == Status::kRejected) return;
  if (r->status == Status::kInitializing && !map_initialized) return;  // empty first scan
  // Late IMU: a scan that began before the first sample (the core behind the IMU stream, its
  // queued scans older than the samples fed meanwhile) has no IMU for its motion, and a window
  // starting with it would fail ("IMU does not cover the registered scans") and start again.
  if (late_imu && r->scan_begin_s < late_imu_from_s) {
    SetMovingInitResult(r);
    return;
  }
  const bool poor_fit = r->fit < config.lidar_only.min_fit;
  const bool skipped =
      r->knn_residuals + r->skeleton_residuals < static_cast<size_t>(config.iekf.min_rows);
  if (map_initialized && moving_scans > 0 && (poor_fit || skipped)) {
    // A scan the LiDAR-only registration could not place would bend every later equation.
    // (Directions the update flags as weak keep the gyro's and the motion model's values.)
    RestartMovingInit("scan at t=" + std::to_string(r->stamp_s) + " not registered (" + r->reason +
                      ")");
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
  const double window = config.imu.init.moving_start_window_s;
  while (moving_poses.size() > 2 && pose.t - moving_poses[1].t + 1e-6 >= window) {
    moving_poses.erase(moving_poses.begin());
  }
  // Late IMU: the window slides over a map that lives on; keep only the samples it spans.
  while (late_imu && imu.size() > 2 && imu[1].stamp_s <= moving_poses.front().t) imu.pop_front();
  if (!moving_refused || pose.t - moving_poses.front().t + 1e-6 < window) {
    SetMovingInitResult(r);
    return;
  }
  MovingStartOptions opt;
  opt.gravity = config.imu.init.gravity > 0.0 ? config.imu.init.gravity : 9.80665;
  opt.acc_scale = config.imu.init.acc_scale;
  opt.max_gravity_error = config.imu.init.moving_start_max_gravity_error;
  opt.max_gyro_bias = config.imu.init.max_gyro_bias;
  const std::vector<ImuSample> samples(imu.begin(), imu.end());
  const MovingStartEstimate e = EstimateMovingStart(samples, moving_poses, opt);
  if (!e.ok) {
    RestartMovingInit(e.reason);
    SetMovingInitResult(r);
    return;
  }
  const bool late = late_imu;
  StartFilterMoving(e);
  std::ostringstream os;
  os.precision(4);
  os << "moving-start initialization: |g| free " << e.gravity_norm_free << " m/s^2 (+-"
     << e.gravity_sigma << "), speed " << e.velocity_map.norm() << " m/s";
  if (late) {
    // The scan was registered LiDAR-only and reported so; its pose stands, in the same world.
    r->lidar_only = false;
    r->lio_started_late = true;
    Append(&r->reason, "IMU after a LiDAR-only start: LIO from here, " + os.str());
    FillState(r);
    return;
  }
  // This scan's pose is the filter's first: report it in the now gravity-aligned world.
  r->status = Status::kOk;
  r->pose_valid = true;
  r->reason = os.str();
  FillState(r);
}

void LioPpf::Impl::SetMovingInitResult(ScanResult* r) const {
  if (late_imu) {
    // A valid LiDAR-only pose in the world it always had: it stays one.
    std::ostringstream os;
    os.precision(3);
    const double span =
        moving_poses.empty() ? 0.0 : moving_poses.back().t - moving_poses.front().t;
    os << "IMU after a LiDAR-only start: estimating gravity, " << span << " of "
       << config.imu.init.moving_start_window_s << " s";
    Append(&r->reason, os.str());
    return;
  }
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
     << config.imu.init.moving_start_window_s << " s (" << init.reason() << ")";
  r->reason = os.str();
}

// Starts the window again from the next scan with a new map (its frame is that scan's).
void LioPpf::Impl::RestartMovingInit(const std::string& why) {
  Log(LogLevel::kWarn, "moving-start initialization restarts: " + why);
  if (late_imu) {
    // The LiDAR-only map and world stay: only the window starts again.
    moving_poses.clear();
    moving_scans = kMovingWarmupScans - 1;
    return;
  }
  ClearMovingInit();
}

void LioPpf::Impl::ClearMovingInit() {
  moving_poses.clear();
  moving_scans = 0;
  map_initialized = false;
  map.clear();
  motion.Reset();
  recent_fits.clear();
  lio_baseline.Clear();
  lio_steps_rot.clear();
  if (tracker) tracker->Reset();
  knn->Reset();
  scans_since_prune = 0;
  last_scan_end = -std::numeric_limits<double>::infinity();
}

void LioPpf::Impl::StartFilterMoving(const MovingStartEstimate& e) {
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
  if (late_imu) {
    late_imu = false;
    world_is_map = true;
  }
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

}  // namespace ppf
