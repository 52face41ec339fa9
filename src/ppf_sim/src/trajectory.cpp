#include "ppf_sim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace ppf::sim {

Trajectory::Trajectory(double knot_dt, std::vector<Eigen::Vector3d> pos_ctrl,
                       std::vector<Eigen::Vector3d> euler_ctrl)
    : dt_(knot_dt), pos_(std::move(pos_ctrl)), euler_(std::move(euler_ctrl)) {
  if (pos_.size() < 4 || pos_.size() != euler_.size() || !(dt_ > 0.0)) {
    throw std::invalid_argument("Trajectory: need >= 4 matching control points and dt > 0");
  }
  end_time_ = static_cast<double>(pos_.size() - 3) * dt_;
}

void Trajectory::SetShakes(std::vector<Shake> shakes, double start, double ramp) {
  shakes_ = std::move(shakes);
  shake_start_ = start;
  shake_ramp_ = std::max(ramp, 1e-3);
}

void Trajectory::StartAt(double t0) {
  const long k = std::lround(t0 / dt_);
  if (k <= 0) return;
  if (static_cast<size_t>(k) + 4 > pos_.size()) {
    throw std::invalid_argument("Trajectory::StartAt: start beyond the end of the curve");
  }
  pos_.erase(pos_.begin(), pos_.begin() + k);
  euler_.erase(euler_.begin(), euler_.begin() + k);
  end_time_ = static_cast<double>(pos_.size() - 3) * dt_;
  const double shift = static_cast<double>(k) * dt_;
  for (Shake& sh : shakes_) sh.phase += 2.0 * M_PI * sh.freq_hz * shift;
  shake_start_ -= shift;
}

void Trajectory::EvalChannels(double t, int order, double val[6], double d1[6],
                              double d2[6]) const {
  const int n_seg = static_cast<int>(pos_.size()) - 3;
  double s = std::clamp(t, 0.0, end_time_) / dt_;
  int k = static_cast<int>(std::floor(s));
  if (k >= n_seg) k = n_seg - 1;
  if (k < 0) k = 0;
  const double u = s - k;
  const double u2 = u * u, u3 = u2 * u, w = 1.0 - u;
  const double b[4] = {w * w * w / 6.0, (3 * u3 - 6 * u2 + 4) / 6.0,
                       (-3 * u3 + 3 * u2 + 3 * u + 1) / 6.0, u3 / 6.0};
  const double db[4] = {-0.5 * w * w, 1.5 * u2 - 2 * u, -1.5 * u2 + u + 0.5, 0.5 * u2};
  const double ddb[4] = {w, 3 * u - 2, -3 * u + 1, u};
  // Outside [0, end] the curve is held constant: derivatives are zero there.
  const bool inside = t >= 0.0 && t <= end_time_;
  for (int c = 0; c < 6; ++c) {
    val[c] = d1[c] = d2[c] = 0.0;
  }
  for (int j = 0; j < 4; ++j) {
    const Eigen::Vector3d& e = euler_[k + j];
    const Eigen::Vector3d& p = pos_[k + j];
    for (int c = 0; c < 3; ++c) {
      val[c] += b[j] * e[c];
      val[3 + c] += b[j] * p[c];
      if (inside && order >= 1) {
        d1[c] += db[j] * e[c];
        d1[3 + c] += db[j] * p[c];
      }
      if (inside && order >= 2) {
        d2[c] += ddb[j] * e[c];
        d2[3 + c] += ddb[j] * p[c];
      }
    }
  }
  for (int c = 0; c < 6; ++c) {
    d1[c] /= dt_;
    d2[c] /= dt_ * dt_;
  }
  if (shakes_.empty() || t <= shake_start_) return;
  // Quintic smootherstep envelope: value, first and second derivative are continuous.
  const double x = std::min((t - shake_start_) / shake_ramp_, 1.0);
  double env = x * x * x * (x * (6 * x - 15) + 10);
  double env1 = 0.0, env2 = 0.0;
  if (x < 1.0) {
    env1 = 30 * x * x * (x - 1) * (x - 1) / shake_ramp_;
    env2 = 60 * x * (2 * x * x - 3 * x + 1) / (shake_ramp_ * shake_ramp_);
  }
  for (const Shake& sh : shakes_) {
    const double w0 = 2.0 * M_PI * sh.freq_hz;
    const double ph = w0 * t + sh.phase;
    const double f = sh.amp * std::sin(ph);
    const double f1 = sh.amp * w0 * std::cos(ph);
    const double f2 = -sh.amp * w0 * w0 * std::sin(ph);
    val[sh.channel] += env * f;
    d1[sh.channel] += env1 * f + env * f1;
    d2[sh.channel] += env2 * f + 2 * env1 * f1 + env * f2;
  }
}

Eigen::Matrix3d EulerToRotation(const Eigen::Vector3d& e) {
  return (Eigen::AngleAxisd(e[2], Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(e[1], Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(e[0], Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d EulerRatesToBodyRate(const Eigen::Vector3d& e, const Eigen::Vector3d& r) {
  const double sr = std::sin(e[0]), cr = std::cos(e[0]);
  const double sp = std::sin(e[1]), cp = std::cos(e[1]);
  return {r[0] - r[2] * sp, r[1] * cr + r[2] * sr * cp, -r[1] * sr + r[2] * cr * cp};
}

void Trajectory::SetJolts(std::vector<Jolt> jolts) {
  std::sort(jolts.begin(), jolts.end(), [](const Jolt& a, const Jolt& b) { return a.t < b.t; });
  jolt_times_.clear();
  jolt_transforms_.clear();
  jolt_yaw_.clear();
  for (const Jolt& j : jolts) {
    // Anchored on the path as the earlier jolts already moved it.
    const Eigen::Isometry3d T = Pose(j.t);
    const Eigen::Vector3d c = T.translation();
    Eigen::Vector3d heading = T.linear().col(0);
    heading.z() = 0.0;
    heading = heading.norm() > 1e-9 ? heading.normalized() : Eigen::Vector3d::UnitX();
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.linear() = Eigen::AngleAxisd(j.yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    step.translation() = c - step.linear() * c + j.dx_m * heading;
    const Eigen::Isometry3d before =
        jolt_transforms_.empty() ? Eigen::Isometry3d::Identity() : jolt_transforms_.back();
    const double yaw_before = jolt_yaw_.empty() ? 0.0 : jolt_yaw_.back();
    jolt_times_.push_back(j.t);
    jolt_transforms_.push_back(step * before);
    jolt_yaw_.push_back(yaw_before + j.yaw_rad);
  }
}

const Eigen::Isometry3d* Trajectory::JoltAt(double t) const {
  // Strictly after the jolt's time: the IMU sample (and the scan column) at t_j is the old path's.
  const auto it = std::lower_bound(jolt_times_.begin(), jolt_times_.end(), t);
  if (it == jolt_times_.begin()) return nullptr;
  return &jolt_transforms_[static_cast<size_t>(it - jolt_times_.begin()) - 1];
}

TrajectoryState Trajectory::Evaluate(double t) const {
  double val[6], d1[6], d2[6];
  EvalChannels(t, 2, val, d1, d2);
  TrajectoryState s;
  s.t = t;
  s.euler = {val[0], val[1], val[2]};
  s.p = {val[3], val[4], val[5]};
  s.v = {d1[3], d1[4], d1[5]};
  s.a = {d2[3], d2[4], d2[5]};
  s.R = EulerToRotation(s.euler);
  s.omega = EulerRatesToBodyRate(s.euler, {d1[0], d1[1], d1[2]});
  if (const Eigen::Isometry3d* J = JoltAt(t)) {
    // A turn about the vertical: body rate unchanged, world vectors turned, yaw shifted.
    const size_t i = static_cast<size_t>(J - jolt_transforms_.data());
    s.p = *J * s.p;
    s.v = J->linear() * s.v;
    s.a = J->linear() * s.a;
    s.R = J->linear() * s.R;
    s.euler.z() += jolt_yaw_[i];
  }
  return s;
}

Eigen::Isometry3d Trajectory::Pose(double t) const {
  double val[6], d1[6], d2[6];
  EvalChannels(t, 0, val, d1, d2);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = EulerToRotation({val[0], val[1], val[2]});
  T.translation() = Eigen::Vector3d(val[3], val[4], val[5]);
  if (const Eigen::Isometry3d* J = JoltAt(t)) T = *J * T;
  return T;
}

}  // namespace ppf::sim
