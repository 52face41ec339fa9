#include "ppf_sim/scene_distance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ppf::sim {

double DistanceToPrimitive(const Primitive& p, const Eigen::Vector3d& x) {
  const Eigen::Vector3d d = x - p.c;
  switch (p.kind) {
    case PrimKind::kQuad: {
      const double a = std::max(std::abs(d.dot(p.u)) - p.half.x(), 0.0);
      const double b = std::max(std::abs(d.dot(p.v)) - p.half.y(), 0.0);
      const double h = d.dot(p.n);
      return std::sqrt(a * a + b * b + h * h);
    }
    case PrimKind::kBox: {
      const Eigen::Vector3d local(d.dot(p.u), d.dot(p.v), d.z());
      const Eigen::Vector3d q = local.cwiseAbs() - p.half;
      return q.maxCoeff() > 0.0 ? q.cwiseMax(0.0).norm() : -q.maxCoeff();
    }
    case PrimKind::kCylinder: {
      const Eigen::Vector2d q(d.head<2>().norm() - p.half.x(), std::abs(d.z()) - p.half.z());
      return q.maxCoeff() > 0.0 ? q.cwiseMax(0.0).norm() : -q.maxCoeff();
    }
    case PrimKind::kBlob: {
      const double k = d.cwiseQuotient(p.half).norm();
      return k <= 1.0 ? 0.0 : d.norm() * (1.0 - 1.0 / k);
    }
  }
  return std::numeric_limits<double>::infinity();
}

double DistanceToScene(const Scene& scene, const Eigen::Vector3d& x) {
  double best = std::numeric_limits<double>::infinity();
  if (scene.has_ground() && scene.ground().Contains(x.x(), x.y())) {
    best = std::abs(x.z() - scene.GroundHeight(x.x(), x.y()));
  }
  for (const Primitive& p : scene.primitives()) best = std::min(best, DistanceToPrimitive(p, x));
  return best;
}

}  // namespace ppf::sim
