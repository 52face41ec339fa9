// Filter state and IMU propagation (paper Eqs. 3-7, midpoint integration) with error-state
// covariance propagation.
//
// State x = (R_world_imu, p_world_imu, v_world, b_gyro, b_acc, g_world) on
// SO(3) x R^12 x S2: gravity keeps the magnitude measured at initialization and only its direction
// is estimated. Error state (17): [dtheta(0..2), dp(3..5), dv(6..8), dbg(9..11), dba(12..14),
// dg(15..16)] with R = R_hat Exp(dtheta) (body frame), g = Exp(B(g_hat) dg) g_hat (so3.hpp) and
// additive errors for the rest.
//
// "world" here is the frame the map is built in: z is the measured "up" at initialization, where a
// static accelerometer cannot tell its bias from tilt. The gravity direction in it is therefore a
// state, not a constant: once the motion separates bias and tilt (turns), g_world leans by the
// initialization error and the facade reports poses in the frame where the estimated gravity is
// straight down (ScanResult::T_world_map, lio_ppf.hpp).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/config.hpp"  // this stage's options
#include "ppf_core/imu_sample.hpp"
#include "ppf_core/result_types.hpp"

namespace ppf {

struct NavState {
  double stamp_s = 0.0;
  Eigen::Matrix3d R_world_imu = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_world_imu = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d acc_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d gravity_world = Eigen::Vector3d(0, 0, -9.80665);
  StateCov P = StateCov::Identity() * 1e-4;

  Eigen::Isometry3d T_world_imu() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R_world_imu;
    T.translation() = p_world_imu;
    return T;
  }
};

// Pose of the IMU at an integration knot, plus the constant (bias-corrected) body rate and world
// acceleration of the segment that starts there: enough to evaluate the pose at any time inside.
struct ImuKnot {
  double t = 0.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();      // body, bias corrected
  Eigen::Vector3d acc_world = Eigen::Vector3d::Zero();  // incl. gravity
};

// The propagated IMU trajectory over one scan; PoseAt() extrapolates outside [front, back].
struct PoseTrace {
  std::vector<ImuKnot> knots;
  Eigen::Isometry3d PoseAt(double t) const;
};

// Raw sample interpolated linearly at time t (clamped to the first/last sample).
ImuSample InterpolateImu(const std::vector<ImuSample>& samples, double t);

// Propagates *state from state->stamp_s to t_end using `samples` (sorted by time; should bracket
// the interval; outside it the nearest sample is held). acc_scale multiplies raw accelerations.
// Appends knots to *trace (if non-null), the first at the start time. Midpoint rule per segment:
//   w = (w_k + w_k+1)/2 - bg, R_k+1 = R_k Exp(w dt),
//   a = (R_k (a_k - ba) + R_k+1 (a_k+1 - ba))/2 + g, p += v dt + a dt^2/2, v += a dt.
// What a saturated gyro left unmeasured over one propagation. The true rate lies beyond the
// reading, in its direction, by an unknown amount that holds through the episode.
struct GyroSaturation {
  double seconds = 0.0;  // time during which some axis read at saturation
  // Column 2 * axis + (reading > 0 ? 0 : 1): the world-frame rotation (rad) that 1 rad/s more than
  // the reading, in the reading's direction, would have added by the end of the propagation.
  Eigen::Matrix<double, 3, 6> turn_per_rate = Eigen::Matrix<double, 3, 6>::Zero();
  Eigen::Matrix<double, 6, 1> reading = Eigen::Matrix<double, 6, 1>::Zero();  // |reading|, rad/s
};

// Gyro axes at saturation (ImuNoise::gyro_range) get their unmeasured turn added to the rotation
// covariance (one sigma: half the reading); *saturation (if non-null) says what was unmeasured.
void PropagateImu(const std::vector<ImuSample>& samples, double t_end, double acc_scale,
                  const ImuNoise& noise, NavState* state, PoseTrace* trace,
                  GyroSaturation* saturation = nullptr);

// The error-state transition of one propagation segment (first order, error order
// [th p v bg ba g(2)]): the identity but for these blocks.
struct ImuTransition {
  Eigen::Matrix3d rot_rot = Eigen::Matrix3d::Identity();  // Exp(-w dt)
  double dt = 0.0;  // rot <- bg: -I dt; pos <- vel: I dt
  Eigen::Matrix3d vel_rot = Eigen::Matrix3d::Zero();  // -R [a]x dt
  Eigen::Matrix3d vel_ba = Eigen::Matrix3d::Zero();   // -R dt
  Eigen::Matrix<double, 3, 2> vel_grav = Eigen::Matrix<double, 3, 2>::Zero();  // S2 Jacobian dt

  // The full 17x17 matrix (for tests and reference).
  StateCov Dense() const;
  // F P F^T, using the blocks only: a dense 17x17 product pair, per IMU sample, cost more than the
  // rest of the propagation.
  StateCov Apply(const StateCov& P) const;
};

// Per sample, a bit per gyro axis (1 << axis) that reads at saturation (ImuNoise::gyro_range).
std::vector<uint8_t> SaturatedGyroAxes(const std::vector<ImuSample>& samples, double gyro_range);

// Adds excess(c) rad/s, in the reading's direction, to every saturated reading of column c
// (GyroSaturation's order): the rate the gyro could not report, once something else measured it.
void AddUnmeasuredRate(const Eigen::Matrix<double, 6, 1>& excess, double gyro_range,
                       std::vector<ImuSample>* samples);

}  // namespace ppf
