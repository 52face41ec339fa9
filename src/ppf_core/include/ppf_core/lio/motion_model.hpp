// Constant-velocity motion model: the prediction of the LiDAR-only mode (imu.mode none),
// where no IMU says how the sensor moved since the last scan.
//
// The model keeps the last two registered poses and assumes the body-frame twist between them
// (rotation vector and translation per second, constant over the interval) continues. It also
// yields a PoseTrace over the new scan, so points with their own time are de-skewed exactly as
// with the IMU's trace (deskew.hpp), only from this coarser motion.
//
// Hand-held sensors break the assumption often (a turn that starts or stops between two scans):
// the prediction is only the first of the registration's guesses (hypothesis_search.hpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/lio/imu_propagation.hpp"

namespace ppf {

class ConstantVelocityModel {
 public:
  // Forget the motion (the next prediction is "no motion").
  void Reset();
  // Records the registered pose of the body at time t (strictly after the previous one, else the
  // pose replaces it and the twist is kept).
  void Update(const Eigen::Isometry3d& T_world_body, double t);
  // Starts from a pose and a known body-frame twist (per second) instead of two poses: the LIO
  // filter's own velocity and turn rate when its IMU stream is lost (docs/behaviour.md,
  // "IMU loss").
  void Seed(const Eigen::Isometry3d& T_world_body, double t, const Eigen::Vector3d& omega_body,
            const Eigen::Vector3d& v_body);

  bool has_pose() const { return has_pose_; }
  bool has_twist() const { return has_twist_; }
  double stamp() const { return t_; }
  const Eigen::Isometry3d& pose() const { return T_; }
  // Body frame, per second.
  const Eigen::Vector3d& angular_velocity() const { return omega_; }
  const Eigen::Vector3d& linear_velocity_body() const { return v_body_; }
  Eigen::Vector3d velocity_world() const { return T_.linear() * v_body_; }
  // The velocity at the last pose itself (the tangent of the path there), in the world frame.
  // velocity_world() is the chord of the last interval over its time, turned to the last pose:
  // the right step to extrapolate the same interval again, but on a turn not the direction of
  // motion at the pose, off by half the turn (17 degrees after 1.6 s through a 35-degree bend).
  // This one assumes the body twist was constant over the interval (a circular arc).
  Eigen::Vector3d TangentVelocityWorld() const;

  // The body motion from the last pose over dt seconds: Exp of (twist * dt), rotation and
  // translation integrated together (screw motion of a constant body twist, first order in the
  // translation: the rotation during one scan interval is small enough for a hand-held sensor
  // that the difference stays below the registration's reach).
  Eigen::Isometry3d Delta(double dt) const;
  // The predicted pose at t (the last pose if there is none to extrapolate from).
  Eigen::Isometry3d Predict(double t) const { return T_ * Delta(t - t_); }
  // One knot at the last pose with the constant twist: PoseAt(t) for any t after it (de-skew).
  PoseTrace Trace() const;

 private:
  bool has_pose_ = false;
  bool has_twist_ = false;
  double t_ = 0.0;
  double dt_ = 0.0;  // the interval the twist was measured over (0: seeded)
  Eigen::Isometry3d T_ = Eigen::Isometry3d::Identity();
  Eigen::Vector3d omega_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_body_ = Eigen::Vector3d::Zero();
};

}  // namespace ppf
