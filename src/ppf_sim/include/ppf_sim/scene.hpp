// Analytic scene primitives, a height-field ground, and a uniform 2-D grid for ray casting.
//
// Why a 2-D (x-y) grid: outdoor and indoor scenes are 2.5-D, so a column grid has few empty
// cells along a ray and needs no tuning in z. Primitives that cover most of the scene go into a
// small "global" list tested by every ray instead.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "ppf_sim/height_field.hpp"

namespace ppf::sim {

struct Ray {
  Eigen::Vector3d o = Eigen::Vector3d::Zero();
  Eigen::Vector3d d = Eigen::Vector3d::UnitX();  // unit length
  double tmin = 0.0;
  double tmax = 1e9;
  uint64_t key = 0;  // per-ray random key (foliage scatter)
};

struct Hit {
  double t = 0.0;
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  // unit surface normal (either side)
  float reflectivity = 0.0f;                     // 0..1, diffuse
  int32_t prim = -1;                             // -1 = ground
};

enum class PrimKind : uint8_t { kQuad, kBox, kCylinder, kBlob };

struct Primitive {
  PrimKind kind = PrimKind::kQuad;
  float reflectivity = 0.3f;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();  // centre
  // quad: (half length along u, half length along v, -); box: half extents in its yaw frame;
  // cylinder: (radius, -, half height); blob: ellipsoid radii.
  Eigen::Vector3d half = Eigen::Vector3d::Ones();
  Eigen::Vector3d u = Eigen::Vector3d::UnitX();  // quad axis 1 / box local x (yaw only)
  Eigen::Vector3d v = Eigen::Vector3d::UnitY();  // quad axis 2
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  // quad normal
  // Blobs (tree canopies, bushes): a ray that enters is stopped after an exponential depth
  // with this mean, or passes through a gap with probability `gap`.
  float scatter_depth = 0.5f;
  float gap = 0.2f;
};

Primitive MakeQuad(const Eigen::Vector3d& center, const Eigen::Vector3d& axis_u, double half_u,
                   const Eigen::Vector3d& axis_v, double half_v, float reflectivity);
// Box with vertical z axis rotated by yaw; z range [z0, z1].
Primitive MakeBox(double cx, double cy, double yaw, double half_x, double half_y, double z0,
                  double z1, float reflectivity);
Primitive MakeCylinder(double cx, double cy, double radius, double z0, double z1,
                       float reflectivity);
Primitive MakeBlob(const Eigen::Vector3d& center, const Eigen::Vector3d& radii, float reflectivity,
                   float scatter_depth, float gap);

// Closest hit of one primitive with t in (ray.tmin, tmax). Exposed for tests.
bool IntersectPrimitive(const Primitive& p, const Ray& ray, double tmax, uint32_t salt, Hit* hit);

class Scene {
 public:
  void Add(const Primitive& p) { prims_.push_back(p); }
  void SetGround(HeightField ground) { ground_ = std::move(ground); has_ground_ = true; }
  // Builds the grid; call after the last Add and before Intersect.
  void Build(double cell_size = 4.0);

  bool Intersect(const Ray& ray, Hit* hit) const;

  const std::vector<Primitive>& primitives() const { return prims_; }
  bool has_ground() const { return has_ground_; }
  const HeightField& ground() const { return ground_; }
  // Ground height (or 0 without a height field).
  double GroundHeight(double x, double y) const;

 private:
  std::vector<Primitive> prims_;
  HeightField ground_;
  bool has_ground_ = false;

  double cell_ = 4.0;
  double x0_ = 0, y0_ = 0;
  int nx_ = 0, ny_ = 0;
  std::vector<uint32_t> cell_start_;  // CSR layout: nx*ny + 1 offsets
  std::vector<uint32_t> cell_items_;
  std::vector<uint32_t> global_;
};

}  // namespace ppf::sim
