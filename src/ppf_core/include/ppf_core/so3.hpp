// SO(3) helpers shared by propagation, the filter and evaluation.
//
// Error-state convention used throughout the core: R = R_hat * Exp(dtheta) (right, body-frame
// perturbation), so rotation errors and covariances are expressed in the IMU body frame.
#pragma once

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ppf {

inline Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

inline Eigen::Matrix3d SO3Exp(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  if (theta < 1e-10) return Eigen::Matrix3d::Identity() + Skew(w);
  return Eigen::AngleAxisd(theta, w / theta).toRotationMatrix();
}

inline Eigen::Vector3d SO3Log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

// Re-orthonormalises a rotation that accumulated rounding over many small updates.
inline Eigen::Matrix3d NormalizeRotation(const Eigen::Matrix3d& R) {
  return Eigen::Quaterniond(R).normalized().toRotationMatrix();
}

}  // namespace ppf
