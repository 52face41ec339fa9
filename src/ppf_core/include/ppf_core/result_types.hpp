// The value types a ScanResult carries (lio_ppf.hpp), public so that the facade needs none of
// the stages' headers: the filter's error-state layout, the label of each point, the skeleton
// planes (the PPF stages fit and track them, ppf/), what the time-field decoder found (lio/).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/cloud_view.hpp"

namespace ppf {

// Error state of the filter (lio/imu_propagation.hpp says what each block is).
constexpr int kStateDim = 17;
using StateCov = Eigen::Matrix<double, kStateDim, kStateDim>;
enum StateIndex { kRot = 0, kPos = 3, kVel = 6, kBg = 9, kBa = 12, kGrav = 15 };

enum class PointLabel : uint8_t {
  kScattered = 0,  // Theta: kNN residual, inserted into the map
  kSkeleton = 1,   // Omega: residual against pre-fitted planes, not inserted
  kDiscarded = 2,  // semi-inliers of the sandwich layer: no residual, not inserted
};

// An infinite 3D plane f = [n; d] with unit normal n: a point p lies on it iff n.p + d = 0
// (ppf/plane.hpp: moving planes between frames, fitting them).
struct Plane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  // unit normal
  double d = 0.0;                                // offset: n.p + d = 0 on the plane

  Eigen::Vector4d Coefficients() const { return Eigen::Vector4d(n.x(), n.y(), n.z(), d); }

  // Signed point-to-plane distance (metres, positive on the side n points to).
  double SignedDistance(const Eigen::Vector3d& p) const { return n.dot(p) + d; }
  float SignedDistance(const Eigen::Vector3f& p) const {
    return static_cast<float>(n.x()) * p.x() + static_cast<float>(n.y()) * p.y() +
           static_cast<float>(n.z()) * p.z() + static_cast<float>(d);
  }
  double Distance(const Eigen::Vector3d& p) const;

  // The same plane with the opposite normal (n, d) -> (-n, -d).
  Plane Flipped() const { return Plane{-n, -d}; }

  // Normalises f = [a b c e] to a unit normal. Empty for a (near-)zero or non-finite normal.
  static std::optional<Plane> FromCoefficients(const Eigen::Vector4d& f);

  // Plane through three points. Empty if |(p1-p0)x(p2-p0)| < min_cross_norm (collinear or
  // coincident samples): the normal would be numerically meaningless or a division by zero.
  static std::optional<Plane> FromPoints(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                         const Eigen::Vector3d& p2, double min_cross_norm);
};

// A tracked skeleton plane (ppf/skeleton_window.hpp).
struct SkeletonPlane {
  int64_t track_id = -1;
  Plane plane;                                         // world frame
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // world, of the latest strict inliers
  int num_inliers = 0;                                 // strict inliers at the latest fit
  // World-frame scatter of the latest fit's strict inliers about `centroid` (extent, thickness).
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  bool incremental = false;  // this scan's fit came from the IMU-predicted guess of this track
  int age = 0;           // scans since the track was created (0 in its first scan)
  int hits = 0;          // scans in which the plane was fitted
  int missed_scans = 0;  // consecutive scans without a fit
};

// The per-point time field as the decoder found it (lio/time_field.hpp).
// What detection concluded; stable after the first scan.
struct TimeFieldInfo {
  bool detected = false;
  bool present = false;
  std::string name;
  FieldType type = FieldType::kFloat32;
  uint32_t offset = 0;
  double unit_scale_s = 1.0;
  bool absolute = false;
  bool stamp_at_end = false;
  std::string Describe() const;
};

}  // namespace ppf
