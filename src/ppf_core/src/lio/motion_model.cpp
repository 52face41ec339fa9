#include "ppf_core/lio/motion_model.hpp"

#include <cmath>

#include "ppf_core/lio/so3.hpp"

namespace ppf {

void ConstantVelocityModel::Reset() { *this = ConstantVelocityModel(); }

void ConstantVelocityModel::Update(const Eigen::Isometry3d& T_world_body, double t) {
  if (has_pose_ && t > t_ + 1e-6) {
    const Eigen::Isometry3d d = T_.inverse() * T_world_body;
    const double dt = t - t_;
    omega_ = SO3Log(d.linear()) / dt;
    v_body_ = d.translation() / dt;
    dt_ = dt;
    has_twist_ = true;
  }
  T_ = T_world_body;
  t_ = t;
  has_pose_ = true;
}

void ConstantVelocityModel::Seed(const Eigen::Isometry3d& T_world_body, double t,
                                 const Eigen::Vector3d& omega_body, const Eigen::Vector3d& v_body) {
  T_ = T_world_body;
  t_ = t;
  omega_ = omega_body;
  v_body_ = v_body;
  dt_ = 0.0;
  has_pose_ = true;
  has_twist_ = true;
}

Eigen::Vector3d ConstantVelocityModel::TangentVelocityWorld() const {
  // A constant body twist (w, v) moves the body by the chord J_l(w dt) v dt in the frame of the
  // interval's start (J_l: SO(3)'s left Jacobian), so v = J_l(w dt)^-1 chord / dt, and v stays
  // the body-frame velocity all along the arc.
  const Eigen::Vector3d theta = omega_ * dt_;
  const double a = theta.norm();
  // Near a half turn per interval the formula degenerates; no scan interval turns that far.
  if (a < 1e-6 || a > 3.0) return velocity_world();
  const Eigen::Matrix3d K = Skew(theta);
  const Eigen::Matrix3d J_inv =
      Eigen::Matrix3d::Identity() - 0.5 * K +
      (1.0 / (a * a) - (1.0 + std::cos(a)) / (2.0 * a * std::sin(a))) * K * K;
  return T_.linear() * (J_inv * v_body_);
}

Eigen::Isometry3d ConstantVelocityModel::Delta(double dt) const {
  Eigen::Isometry3d d = Eigen::Isometry3d::Identity();
  if (!has_twist_) return d;
  d.linear() = SO3Exp(omega_ * dt);
  d.translation() = v_body_ * dt;
  return d;
}

PoseTrace ConstantVelocityModel::Trace() const {
  PoseTrace trace;
  ImuKnot k;
  k.t = t_;
  k.R = T_.linear();
  k.p = T_.translation();
  k.v = velocity_world();
  k.omega = omega_;
  // Delta() translates along the start orientation's body axes, PoseAt() along k.v in the world:
  // the same vector, so the trace and Predict() agree at every time of the segment.
  trace.knots.push_back(k);
  return trace;
}

}  // namespace ppf
