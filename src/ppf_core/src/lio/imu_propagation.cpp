#include "ppf_core/lio/imu_propagation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "ppf_core/lio/so3.hpp"

namespace ppf {

Eigen::Isometry3d PoseTrace::PoseAt(double t) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (knots.empty()) return T;
  // Last knot whose time is <= t (the first knot if t precedes it: extrapolate backwards).
  auto it = std::upper_bound(knots.begin(), knots.end(), t,
                             [](double v, const ImuKnot& k) { return v < k.t; });
  const ImuKnot& k = (it == knots.begin()) ? knots.front() : *(it - 1);
  const double tau = t - k.t;
  T.linear() = k.R * SO3Exp(k.omega * tau);
  T.translation() = k.p + k.v * tau + 0.5 * k.acc_world * tau * tau;
  return T;
}

StateCov ImuTransition::Dense() const {
  StateCov F = StateCov::Identity();
  F.block<3, 3>(kRot, kRot) = rot_rot;
  F.block<3, 3>(kRot, kBg) = -Eigen::Matrix3d::Identity() * dt;
  F.block<3, 3>(kPos, kVel) = Eigen::Matrix3d::Identity() * dt;
  F.block<3, 3>(kVel, kRot) = vel_rot;
  F.block<3, 3>(kVel, kBa) = vel_ba;
  F.block<3, 2>(kVel, kGrav) = vel_grav;
  return F;
}

StateCov ImuTransition::Apply(const StateCov& P) const {
  // M = F P: only the rotation, position and velocity rows differ from P's.
  StateCov M = P;
  M.middleRows<3>(kRot) = rot_rot * P.middleRows<3>(kRot) - dt * P.middleRows<3>(kBg);
  M.middleRows<3>(kPos) += dt * P.middleRows<3>(kVel);
  M.middleRows<3>(kVel) += vel_rot * P.middleRows<3>(kRot) + vel_ba * P.middleRows<3>(kBa) +
                           vel_grav * P.middleRows<2>(kGrav);
  // M F^T: the same for the columns.
  StateCov out = M;
  out.middleCols<3>(kRot) = M.middleCols<3>(kRot) * rot_rot.transpose() - dt * M.middleCols<3>(kBg);
  out.middleCols<3>(kPos) += dt * M.middleCols<3>(kVel);
  out.middleCols<3>(kVel) += M.middleCols<3>(kRot) * vel_rot.transpose() +
                             M.middleCols<3>(kBa) * vel_ba.transpose() +
                             M.middleCols<2>(kGrav) * vel_grav.transpose();
  return out;
}

ImuSample InterpolateImu(const std::vector<ImuSample>& samples, double t) {
  if (samples.empty()) return ImuSample{t, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  if (t <= samples.front().stamp_s) {
    ImuSample s = samples.front();
    s.stamp_s = t;
    return s;
  }
  if (t >= samples.back().stamp_s) {
    ImuSample s = samples.back();
    s.stamp_s = t;
    return s;
  }
  auto it = std::upper_bound(samples.begin(), samples.end(), t,
                             [](double v, const ImuSample& s) { return v < s.stamp_s; });
  const ImuSample& b = *it;
  const ImuSample& a = *(it - 1);
  const double span = b.stamp_s - a.stamp_s;
  const double w = span > 1e-12 ? (t - a.stamp_s) / span : 0.0;
  ImuSample s;
  s.stamp_s = t;
  s.angular_velocity = (1.0 - w) * a.angular_velocity + w * b.angular_velocity;
  s.linear_acceleration = (1.0 - w) * a.linear_acceleration + w * b.linear_acceleration;
  return s;
}

std::vector<uint8_t> SaturatedGyroAxes(const std::vector<ImuSample>& samples, double gyro_range) {
  std::vector<uint8_t> axes(samples.size(), 0);
  if (!(gyro_range > 0.0)) return axes;
  // A reading converted from the top code of the sensor's ADC may sit a hair below full scale.
  const double at = gyro_range * (1.0 - 1e-3);
  for (size_t i = 0; i < samples.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      if (std::abs(samples[i].angular_velocity[k]) >= at) axes[i] |= 1u << k;
    }
  }
  return axes;
}

void AddUnmeasuredRate(const Eigen::Matrix<double, 6, 1>& excess, double gyro_range,
                       std::vector<ImuSample>* samples) {
  const std::vector<uint8_t> saturated = SaturatedGyroAxes(*samples, gyro_range);
  for (size_t i = 0; i < samples->size(); ++i) {
    for (int j = 0; j < 3; ++j) {
      if (!(saturated[i] & (1u << j))) continue;
      double& w = (*samples)[i].angular_velocity[j];
      w += w > 0.0 ? excess(2 * j) : -excess(2 * j + 1);
    }
  }
}

void PropagateImu(const std::vector<ImuSample>& samples, double t_end, double acc_scale,
                  const ImuNoise& noise, NavState* state, PoseTrace* trace,
                  GyroSaturation* saturation) {
  const double t0 = state->stamp_s;
  // Gyro saturation: the true rate lies beyond the reading by an unknown amount of the same sign
  // for the whole episode, so its rotation error adds up coherently rather than like white noise.
  // Summed per axis and sign in the world frame (the body turns meanwhile) and added to the
  // rotation covariance at the end: the registration of this scan may then turn the pose as far
  // as a rate up to 1.5x the reading explains (one sigma: half the reading).
  const std::vector<uint8_t> saturated = SaturatedGyroAxes(samples, noise.gyro_range);
  GyroSaturation sat;
  std::vector<double> times;
  times.push_back(t0);
  for (const ImuSample& s : samples) {
    if (s.stamp_s > t0 && s.stamp_s < t_end) times.push_back(s.stamp_s);
  }
  if (t_end > t0) times.push_back(t_end);

  ImuKnot knot;
  ImuSample m0 = InterpolateImu(samples, t0);
  for (size_t k = 0; k + 1 < times.size(); ++k) {
    const double dt = times[k + 1] - times[k];
    if (dt <= 0.0) continue;
    const ImuSample m1 = InterpolateImu(samples, times[k + 1]);
    const Eigen::Vector3d w =
        0.5 * (m0.angular_velocity + m1.angular_velocity) - state->gyro_bias;
    const Eigen::Vector3d a0 = acc_scale * m0.linear_acceleration - state->acc_bias;
    const Eigen::Vector3d a1 = acc_scale * m1.linear_acceleration - state->acc_bias;
    const Eigen::Matrix3d R0 = state->R_world_imu;
    const Eigen::Matrix3d R1 = NormalizeRotation(R0 * SO3Exp(w * dt));
    const Eigen::Vector3d a_world = 0.5 * (R0 * a0 + R1 * a1) + state->gravity_world;
    if (noise.gyro_range > 0.0 && !samples.empty()) {
      // The samples the segment interpolates between (or holds beyond the ends).
      const double tm = 0.5 * (times[k] + times[k + 1]);
      const size_t ib = std::upper_bound(samples.begin(), samples.end(), tm,
                                         [](double v, const ImuSample& s) { return v < s.stamp_s; }) -
                        samples.begin();
      const size_t ia = ib == 0 ? 0 : ib - 1;
      const size_t ic = std::min(ib, samples.size() - 1);
      const uint8_t axes = saturated[ia] | saturated[ic];
      if (axes) sat.seconds += dt;
      for (int j = 0; j < 3; ++j) {
        if (!(axes & (1u << j))) continue;
        const double w = samples[(saturated[ia] & (1u << j)) ? ia : ic].angular_velocity[j];
        const int c = 2 * j + (w > 0.0 ? 0 : 1);
        sat.turn_per_rate.col(c) += R0.col(j) * (w > 0.0 ? dt : -dt);
        sat.reading(c) = std::max(sat.reading(c), std::abs(w));
      }
    }

    if (trace) {
      knot.t = times[k];
      knot.R = R0;
      knot.p = state->p_world_imu;
      knot.v = state->v_world;
      knot.omega = w;
      knot.acc_world = a_world;
      trace->knots.push_back(knot);
    }

    ImuTransition F;
    F.rot_rot = SO3Exp(-w * dt);
    F.dt = dt;
    F.vel_rot = -R0 * Skew(0.5 * (a0 + a1)) * dt;
    F.vel_ba = -R0 * dt;
    F.vel_grav = S2Jacobian(state->gravity_world) * dt;
    StateCov P = F.Apply(state->P);
    P.block<3, 3>(kRot, kRot).diagonal().array() += noise.gyro * noise.gyro * dt;
    P.block<3, 3>(kVel, kVel).diagonal().array() += noise.acc * noise.acc * dt;
    P.block<3, 3>(kBg, kBg).diagonal().array() += noise.gyro_bias * noise.gyro_bias * dt;
    P.block<3, 3>(kBa, kBa).diagonal().array() += noise.acc_bias * noise.acc_bias * dt;
    P.block<2, 2>(kGrav, kGrav).diagonal().array() += noise.gravity_dir * noise.gravity_dir * dt;
    state->P = 0.5 * (P + P.transpose());

    state->p_world_imu += state->v_world * dt + 0.5 * a_world * dt * dt;
    state->v_world += a_world * dt;
    state->R_world_imu = R1;
    m0 = m1;
  }
  if (sat.seconds > 0.0) {
    const Eigen::Matrix<double, 3, 6> body = state->R_world_imu.transpose() * sat.turn_per_rate *
                                             (0.5 * sat.reading).asDiagonal();
    state->P.block<3, 3>(kRot, kRot) += body * body.transpose();
  }
  if (saturation) *saturation = sat;
  if (t_end > t0) state->stamp_s = t_end;
  if (trace) {
    // Closing knot: extrapolation past the end keeps the last segment's rate and acceleration.
    knot.t = state->stamp_s;
    knot.R = state->R_world_imu;
    knot.p = state->p_world_imu;
    knot.v = state->v_world;
    trace->knots.push_back(knot);
  }
}

}  // namespace ppf
