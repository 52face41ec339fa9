#include "ppf_core/ppf/plane.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace ppf {

double Plane::Distance(const Eigen::Vector3d& p) const { return std::abs(SignedDistance(p)); }

std::optional<Plane> Plane::FromCoefficients(const Eigen::Vector4d& f) {
  if (!f.allFinite()) return std::nullopt;
  const double norm = f.head<3>().norm();
  // A normal this short cannot come from real geometry; dividing would amplify round-off.
  if (!(norm > 1e-12)) return std::nullopt;
  return Plane{f.head<3>() / norm, f[3] / norm};
}

std::optional<Plane> Plane::FromPoints(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                       const Eigen::Vector3d& p2, double min_cross_norm) {
  const Eigen::Vector3d cross = (p1 - p0).cross(p2 - p0);
  const double norm = cross.norm();
  if (!std::isfinite(norm) || norm < std::max(min_cross_norm, 1e-12)) return std::nullopt;
  const Eigen::Vector3d n = cross / norm;
  return Plane{n, -n.dot(p0)};
}

Plane TransformPlane(const Eigen::Isometry3d& T_to_from, const Plane& plane_from) {
  // (T^-1)^T = [R 0; -t^T R 1] for T = [R t; 0 1]; applying it to [n; d] gives the lines below.
  Plane out;
  out.n = T_to_from.linear() * plane_from.n;
  out.d = plane_from.d - out.n.dot(T_to_from.translation());
  return out;
}

PlaneMoments PlaneMoments::Transformed(const Eigen::Isometry3d& T_to_from) const {
  PlaneMoments out;
  out.count = count;
  out.centroid = T_to_from * centroid;
  out.scatter = T_to_from.linear() * scatter * T_to_from.linear().transpose();
  return out;
}

void PlaneMoments::Merge(const PlaneMoments& other) {
  if (other.count <= 0.0) return;
  if (count <= 0.0) {
    *this = other;
    return;
  }
  const double total = count + other.count;
  const Eigen::Vector3d c = (count * centroid + other.count * other.centroid) / total;
  const Eigen::Vector3d a = centroid - c, b = other.centroid - c;
  scatter += other.scatter + count * a * a.transpose() + other.count * b * b.transpose();
  centroid = c;
  count = total;
}

std::optional<Plane> PlaneMoments::FitPlane() const {
  if (count < 3.0 || !scatter.allFinite() || !centroid.allFinite()) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(scatter);
  const Eigen::Vector3d ev = es.eigenvalues();
  if (!(ev(1) > 1e-9 * std::max(1e-12, ev(2)))) return std::nullopt;
  const Eigen::Vector3d n = es.eigenvectors().col(0).normalized();
  return Plane{n, -n.dot(centroid)};
}

double PlaneAngle(const Plane& a, const Plane& b) {
  const double c = std::min(1.0, std::abs(a.n.dot(b.n)));
  return std::acos(c);
}

}  // namespace ppf
