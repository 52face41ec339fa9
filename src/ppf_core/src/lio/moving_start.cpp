#include "ppf_core/lio/moving_start.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/so3.hpp"

namespace ppf {

Preintegrated Preintegrate(const std::vector<ImuSample>& imu, double t0, double t1,
                           const Eigen::Vector3d& gyro_bias, double acc_scale) {
  Preintegrated d;
  if (imu.empty() || !(t1 > t0)) return d;
  std::vector<double> times{t0};
  for (const ImuSample& s : imu) {
    if (s.stamp_s > t0 && s.stamp_s < t1) times.push_back(s.stamp_s);
  }
  times.push_back(t1);
  ImuSample m0 = InterpolateImu(imu, t0);
  for (size_t k = 0; k + 1 < times.size(); ++k) {
    const double h = times[k + 1] - times[k];
    const ImuSample m1 = InterpolateImu(imu, times[k + 1]);
    if (h > 0.0) {
      const Eigen::Vector3d w = 0.5 * (m0.angular_velocity + m1.angular_velocity) - gyro_bias;
      const Eigen::Vector3d a = 0.5 * acc_scale * (m0.linear_acceleration + m1.linear_acceleration);
      // The specific force of the segment is applied at its mid rotation.
      const Eigen::Vector3d a0 = d.dR * SO3Exp(0.5 * h * w) * a;
      d.dp += d.dv * h + 0.5 * a0 * h * h;
      d.dv += a0 * h;
      d.dR = NormalizeRotation(d.dR * SO3Exp(w * h));
    }
    m0 = m1;
  }
  return d;
}

namespace {

// Rotation residuals of every pose against the gyro with bias bg (3 rows per pose after the
// first).
Eigen::VectorXd RotationResiduals(const std::vector<ImuSample>& imu,
                                  const std::vector<MovingStartPose>& poses,
                                  const Eigen::Vector3d& bg, double acc_scale) {
  Eigen::VectorXd r(3 * (poses.size() - 1));
  for (size_t j = 1; j < poses.size(); ++j) {
    const Preintegrated d = Preintegrate(imu, poses[0].t, poses[j].t, bg, acc_scale);
    r.segment<3>(3 * (j - 1)) = SO3Log(d.dR.transpose() * poses[0].R.transpose() * poses[j].R);
  }
  return r;
}

// Unit detection as in the static initializer: in motion the mean norm is still near g.
double DetectAccScale(const std::vector<ImuSample>& imu,
                      const std::vector<MovingStartPose>& poses) {
  double norm = 0.0;
  int n = 0;
  for (const ImuSample& s : imu) {
    if (s.stamp_s < poses.front().t || s.stamp_s > poses.back().t) continue;
    norm += s.linear_acceleration.norm();
    ++n;
  }
  norm /= std::max(n, 1);
  return (norm > 0.5 && norm < 1.5) ? 9.80665 : 1.0;
}

// Gyro bias: two Gauss-Newton steps with a numeric Jacobian (the preintegrated rotation is
// cheap, and its exact Jacobian would need the right Jacobians of every segment).
Eigen::Vector3d EstimateGyroBias(const std::vector<ImuSample>& imu,
                                 const std::vector<MovingStartPose>& poses, double acc_scale) {
  Eigen::Vector3d bg = Eigen::Vector3d::Zero();
  for (int it = 0; it < 2; ++it) {
    const Eigen::VectorXd r0 = RotationResiduals(imu, poses, bg, acc_scale);
    Eigen::MatrixXd J(r0.size(), 3);
    const double h = 1e-4;
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d b = bg;
      b[c] += h;
      J.col(c) = (RotationResiduals(imu, poses, b, acc_scale) - r0) / h;
    }
    bg -= (J.transpose() * J).ldlt().solve(J.transpose() * r0);
  }
  return bg;
}

// The linear system x = [v_0; g]: p_j - p_0 - R_0 dp_0j = v_0 dt + 1/2 g dt^2, one block row
// per pose after the first, and its least-squares solution with the covariance of g.
struct VelocityGravityFit {
  Eigen::VectorXd b;                 // the left-hand sides
  std::vector<Preintegrated> pre;    // IMU preintegrated from pose 0 to each pose
  Eigen::Matrix<double, 6, 1> x;
  double rms_residual = 0.0;
  double gravity_sigma = 0.0;
};

VelocityGravityFit FitVelocityAndGravity(const std::vector<ImuSample>& imu,
                                         const std::vector<MovingStartPose>& poses,
                                         const Eigen::Vector3d& bg, double acc_scale) {
  VelocityGravityFit f;
  const size_t m = poses.size() - 1;
  Eigen::MatrixXd A(3 * m, 6);
  f.b.resize(3 * m);
  f.pre.resize(poses.size());
  for (size_t j = 1; j < poses.size(); ++j) {
    f.pre[j] = Preintegrate(imu, poses[0].t, poses[j].t, bg, acc_scale);
    const double dt = poses[j].t - poses[0].t;
    A.block<3, 3>(3 * (j - 1), 0) = Eigen::Matrix3d::Identity() * dt;
    A.block<3, 3>(3 * (j - 1), 3) = Eigen::Matrix3d::Identity() * 0.5 * dt * dt;
    f.b.segment<3>(3 * (j - 1)) = poses[j].p - poses[0].p - poses[0].R * f.pre[j].dp;
  }
  const Eigen::Matrix<double, 6, 6> AtA = A.transpose() * A;
  f.x = AtA.ldlt().solve(A.transpose() * f.b);
  const Eigen::VectorXd res = A * f.x - f.b;
  const double dof = std::max<double>(1.0, static_cast<double>(res.size()) - 6.0);
  const double s2 = res.squaredNorm() / dof;
  const Eigen::Matrix<double, 6, 6> cov = s2 * AtA.inverse();
  f.rms_residual = std::sqrt(res.squaredNorm() / static_cast<double>(m));
  f.gravity_sigma = std::sqrt(cov.bottomRightCorner<3, 3>().eigenvalues().real().maxCoeff());
  return f;
}

// The velocity at the last pose, with g at its known magnitude (v_0 solved again from the same
// rows, then carried to the last pose by gravity and the preintegrated velocity).
Eigen::Vector3d VelocityAtLastPose(const std::vector<MovingStartPose>& poses,
                                   const VelocityGravityFit& f, const Eigen::Vector3d& g) {
  Eigen::Vector3d num = Eigen::Vector3d::Zero();
  double den = 0.0;
  for (size_t j = 1; j < poses.size(); ++j) {
    const double dt = poses[j].t - poses[0].t;
    num += dt * (f.b.segment<3>(3 * (j - 1)) - 0.5 * g * dt * dt);
    den += dt * dt;
  }
  const Eigen::Vector3d v0 = num / den;
  const double dt_last = poses.back().t - poses[0].t;
  return v0 + g * dt_last + poses[0].R * f.pre.back().dv;
}

// The first failed check's reason, or "" if the inputs can give an estimate.
std::string CheckInputs(const std::vector<ImuSample>& imu,
                        const std::vector<MovingStartPose>& poses) {
  if (poses.size() < 3 || poses.back().t - poses.front().t < 0.3) {
    return "too few registered scans";
  }
  if (imu.size() < 2 || imu.front().stamp_s > poses.front().t + 1e-3 ||
      imu.back().stamp_s < poses.back().t - 1e-3) {
    return "IMU does not cover the registered scans";
  }
  return "";
}

}  // namespace

MovingStartEstimate EstimateMovingStart(const std::vector<ImuSample>& imu,
                                        const std::vector<MovingStartPose>& poses,
                                        const MovingStartOptions& options) {
  MovingStartEstimate e;
  e.reason = CheckInputs(imu, poses);
  if (!e.reason.empty()) return e;
  e.acc_scale = options.acc_scale > 0.0 ? options.acc_scale : DetectAccScale(imu, poses);

  const Eigen::Vector3d bg = EstimateGyroBias(imu, poses, e.acc_scale);
  e.gyro_bias = bg;
  if (!bg.allFinite() || bg.norm() > options.max_gyro_bias) {
    std::ostringstream os;
    os << "gyro bias estimate " << bg.norm() << " rad/s > " << options.max_gyro_bias
       << " (LiDAR and gyro rotations disagree)";
    e.reason = os.str();
    return e;
  }

  const VelocityGravityFit fit = FitVelocityAndGravity(imu, poses, bg, e.acc_scale);
  e.rms_residual = fit.rms_residual;
  e.gravity_sigma = fit.gravity_sigma;
  const Eigen::Vector3d g_free = fit.x.tail<3>();
  e.gravity_norm_free = g_free.norm();
  if (!g_free.allFinite() ||
      std::abs(e.gravity_norm_free - options.gravity) > options.max_gravity_error) {
    std::ostringstream os;
    os << "gravity estimate |g| = " << e.gravity_norm_free << " m/s^2 differs from "
       << options.gravity << " by more than " << options.max_gravity_error;
    e.reason = os.str();
    return e;
  }
  if (e.rms_residual > options.max_rms_residual) {
    std::ostringstream os;
    os << "poses inconsistent with the IMU: position rms " << e.rms_residual << " m > "
       << options.max_rms_residual;
    e.reason = os.str();
    return e;
  }
  e.gravity_map = g_free.normalized() * options.gravity;
  e.velocity_map = VelocityAtLastPose(poses, fit, e.gravity_map);
  e.ok = e.velocity_map.allFinite();
  if (!e.ok) e.reason = "velocity estimate not finite";
  return e;
}

}  // namespace ppf
