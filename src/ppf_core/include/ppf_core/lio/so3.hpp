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

// Rodrigues: Exp(w) = I + a [w]x + b [w]x^2 = (1 - b |w|^2) I + a [w]x + b w w^T, with
// a = sin(t)/t and b = (1 - cos(t))/t^2 for t = |w|, given t^2. De-skewing evaluates it once per
// point, almost always for a few milliradians: there the two coefficients' series, cut after t^8
// (the first term left out is below 1e-17 for t < 0.1), are exact in double precision and cost
// no sin/cos. Above, both come from one sincos of t/2 (1 - cos(t) = 2 sin^2(t/2), without its
// cancellation).
inline void SO3ExpCoefficients(double t2, double* a, double* b) {
  if (t2 < 0.01) {
    *a = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0)));
    *b = 0.5 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0 * (1.0 - t2 / 90.0))));
  } else {
    const double t = std::sqrt(t2);
    const double s = std::sin(0.5 * t), c = std::cos(0.5 * t);
    *a = 2.0 * s * c / t;
    *b = 2.0 * s * s / t2;
  }
}

inline Eigen::Matrix3d SO3Exp(const Eigen::Vector3d& w) {
  const double t2 = w.squaredNorm();
  double a, b;
  SO3ExpCoefficients(t2, &a, &b);
  const double x = w.x(), y = w.y(), z = w.z();
  const double d = 1.0 - b * t2;
  Eigen::Matrix3d R;
  R << d + b * x * x, b * x * y - a * z, b * x * z + a * y,  //
      b * x * y + a * z, d + b * y * y, b * y * z - a * x,   //
      b * x * z - a * y, b * y * z + a * x, d + b * z * z;
  return R;
}

// Exp(w) q without the matrix: q + a (w x q) + b (w x (w x q)).
inline Eigen::Vector3d SO3ExpApply(const Eigen::Vector3d& w, const Eigen::Vector3d& q) {
  double a, b;
  SO3ExpCoefficients(w.squaredNorm(), &a, &b);
  const Eigen::Vector3d wq = w.cross(q);
  return q + a * wq + b * w.cross(wq);
}

inline Eigen::Vector3d SO3Log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

// Re-orthonormalises a rotation that accumulated rounding over many small updates.
inline Eigen::Matrix3d NormalizeRotation(const Eigen::Matrix3d& R) {
  return Eigen::Quaterniond(R).normalized().toRotationMatrix();
}

// Gravity of fixed magnitude lives on the sphere S2: two error coordinates, in the tangent plane
// of the current estimate, g = Exp(B(g) dg) g. B(g) is a fixed function of g (continuous around
// its usual direction, straight down), so the same g always has the same tangent coordinates.
inline Eigen::Matrix<double, 3, 2> S2Basis(const Eigen::Vector3d& g) {
  const Eigen::Vector3d u = g.normalized();
  // Any axis far from u works; world x unless gravity points (nearly) along it.
  const Eigen::Vector3d ref =
      std::abs(u.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  Eigen::Matrix<double, 3, 2> B;
  B.col(0) = u.cross(ref).normalized();
  B.col(1) = u.cross(B.col(0));
  return B;
}

inline Eigen::Vector3d S2BoxPlus(const Eigen::Vector3d& g, const Eigen::Vector2d& dg) {
  return SO3Exp(S2Basis(g) * dg) * g;
}

// Tangent coordinates at g0 of the rotation taking g0's direction to g's: S2BoxPlus(g0, result)
// has g's direction (and g0's magnitude).
inline Eigen::Vector2d S2BoxMinus(const Eigen::Vector3d& g, const Eigen::Vector3d& g0) {
  const Eigen::Vector3d a = g0.normalized(), b = g.normalized();
  const Eigen::Vector3d axis = a.cross(b);
  const double s = axis.norm();
  const double angle = std::atan2(s, a.dot(b));
  const Eigen::Vector3d w = s > 1e-12 ? Eigen::Vector3d(axis * (angle / s)) : Eigen::Vector3d(axis);
  return S2Basis(g0).transpose() * w;
}

// d(Exp(B dg) g)/d dg at dg = 0.
inline Eigen::Matrix<double, 3, 2> S2Jacobian(const Eigen::Vector3d& g) {
  return -Skew(g) * S2Basis(g);
}

}  // namespace ppf
