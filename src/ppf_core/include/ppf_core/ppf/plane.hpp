// An infinite 3D plane f = [n; d] with unit normal n: a point p lies on it iff n.p + d = 0.
//
// Planes move between frames with Theorem 1 of the paper, f_to = (T_to_from^-1)^T f_from, which
// for a rigid transform keeps n unit length, so signed distances stay metric in every frame.
#pragma once

#include <optional>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/result_types.hpp"

namespace ppf {

// Theorem 1: the plane expressed in frame `to`, given T_to_from (p_to = T_to_from * p_from).
// Closed form of f_to = (T_to_from^-1)^T f_from for a rigid T: n_to = R n, d_to = d - n_to.t.
Plane TransformPlane(const Eigen::Isometry3d& T_to_from, const Plane& plane_from);

// Angle between the planes' normals in radians, ignoring orientation (in [0, pi/2]).
double PlaneAngle(const Plane& a, const Plane& b);

// First and second moments of a plane's inlier points: count, centroid and scatter
// sum (p - c)(p - c)^T. Moments of several point sets merge exactly, so a plane can be fitted to
// the inliers of several scans without keeping their points.
struct PlaneMoments {
  double count = 0.0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();

  // The same points seen in frame `to` (p_to = T_to_from * p_from).
  PlaneMoments Transformed(const Eigen::Isometry3d& T_to_from) const;
  // Adds another point set (parallel-axis theorem).
  void Merge(const PlaneMoments& other);
  // PCA plane: normal = eigenvector of the smallest scatter eigenvalue, through the centroid.
  // Empty for fewer than 3 points or a line-like set (middle eigenvalue ~ 0).
  std::optional<Plane> FitPlane() const;
};

}  // namespace ppf
