// The ground-truth motion: a C2 function of time with exact first and second derivatives.
//
// Position and the Z-Y-X Euler angles are uniform cubic B-splines (C2 by construction, and
// constant wherever four consecutive control points are equal, which gives the static start).
// Hand-held shake is added as sinusoids faded in by a quintic envelope, still C2. The IMU is
// synthesized from these derivatives, so ground truth and IMU agree to floating-point precision.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace ppf::sim {

struct TrajectoryState {
  double t = 0.0;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();      // IMU origin in the world frame
  Eigen::Vector3d v = Eigen::Vector3d::Zero();      // world velocity
  Eigen::Vector3d a = Eigen::Vector3d::Zero();      // world acceleration (no gravity)
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // R_world_imu
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();  // body (IMU frame) angular velocity
  Eigen::Vector3d euler = Eigen::Vector3d::Zero();  // roll, pitch, yaw (rad)
};

// A step of the true path at time t that no IMU sample contains: after t, the rest of the path
// is turned by yaw about the vertical through the position at t and moved by dx along the
// heading there. A turn about the vertical leaves the specific force and the body rate unchanged
// (gravity is vertical), so an IMU synthesized from the stepped path equals the undisturbed one:
// what a gyro saturating on a bump, a packet lost in a sharp turn or a slipping mount leave.
struct Jolt {
  double t = 0.0;
  double yaw_rad = 0.0;
  double dx_m = 0.0;
};

// One additive sinusoid, amp * sin(2 pi freq t + phase), multiplied by the fade-in envelope.
struct Shake {
  int channel = 0;  // 0..2: roll, pitch, yaw; 3..5: world x, y, z
  double amp = 0.0;
  double freq_hz = 0.0;
  double phase = 0.0;
};

class Trajectory {
 public:
  Trajectory() = default;
  // Control point i belongs to time (i - 1) * knot_dt; the curve is defined on
  // [0, (n - 3) * knot_dt]. euler_ctrl holds (roll, pitch, yaw) with yaw unwrapped.
  Trajectory(double knot_dt, std::vector<Eigen::Vector3d> pos_ctrl,
             std::vector<Eigen::Vector3d> euler_ctrl);

  // Shakes fade in over [start, start + ramp] so the static start stays exactly static.
  void SetShakes(std::vector<Shake> shakes, double start, double ramp);

  // Moves time zero to t0 of the current curve (a multiple of knot_dt, rounded to one), so a
  // sequence can begin in the middle of the motion. Dropping whole control points keeps the
  // curve, its derivatives and the shakes exactly those of the original at t + t0.
  void StartAt(double t0);

  // Steps of the path (Jolt), in any order; replaces earlier ones.
  void SetJolts(std::vector<Jolt> jolts);

  TrajectoryState Evaluate(double t) const;
  // T_world_imu at time t (cheaper than Evaluate: no derivatives).
  Eigen::Isometry3d Pose(double t) const;

  double end_time() const { return end_time_; }
  double knot_dt() const { return dt_; }

 private:
  void EvalChannels(double t, int order, double val[6], double d1[6], double d2[6]) const;
  // The world transform of the jolts up to t (identity before the first).
  const Eigen::Isometry3d* JoltAt(double t) const;

  double dt_ = 0.1;
  double end_time_ = 0.0;
  std::vector<Eigen::Vector3d> pos_;
  std::vector<Eigen::Vector3d> euler_;
  std::vector<Shake> shakes_;
  double shake_start_ = 0.0;
  double shake_ramp_ = 1.0;
  std::vector<double> jolt_times_;                 // ascending
  std::vector<Eigen::Isometry3d> jolt_transforms_;  // all jolts up to jolt_times_[i], composed
  std::vector<double> jolt_yaw_;                    // their summed yaw (radians)
};

// Z-Y-X (yaw, pitch, roll) rotation and the body rate for given Euler rates.
Eigen::Matrix3d EulerToRotation(const Eigen::Vector3d& roll_pitch_yaw);
Eigen::Vector3d EulerRatesToBodyRate(const Eigen::Vector3d& roll_pitch_yaw,
                                     const Eigen::Vector3d& rates);

}  // namespace ppf::sim
