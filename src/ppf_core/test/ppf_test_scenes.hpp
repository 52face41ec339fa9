// Synthetic point sets for the PPF tests: noisy planar patches and clutter, seeded.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/ppf/plane.hpp"

namespace ppf::test {

// n points uniformly on the rectangle origin + s*u + t*v (s in [0,su], t in [0,sv]), displaced
// along u x v by N(0, noise).
inline void AddPatch(const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                     const Eigen::Vector3d& v, double su, double sv, int n, double noise,
                     std::mt19937* rng, std::vector<Eigen::Vector3f>* out) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, noise > 0 ? noise : 1.0);
  const Eigen::Vector3d nrm = u.cross(v).normalized();
  for (int i = 0; i < n; ++i) {
    const double e = noise > 0 ? gauss(*rng) : 0.0;
    const Eigen::Vector3d p = origin + uni(*rng) * su * u + uni(*rng) * sv * v + e * nrm;
    out->push_back(p.cast<float>());
  }
}

// n points uniformly in an axis-aligned box (clutter: vegetation, poles, people).
inline void AddClutter(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int n,
                       std::mt19937* rng, std::vector<Eigen::Vector3f>* out) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d r(uni(*rng), uni(*rng), uni(*rng));
    out->push_back((lo + (hi - lo).cwiseProduct(r)).cast<float>());
  }
}

inline double NormalErrorDeg(const Plane& a, const Plane& b) {
  return PlaneAngle(a, b) * 180.0 / M_PI;
}

// Offset difference after aligning orientations.
inline double OffsetError(const Plane& est, const Plane& truth) {
  const double s = est.n.dot(truth.n) >= 0 ? 1.0 : -1.0;
  return std::abs(s * est.d - truth.d);
}

// A street-corner scene in the sensor frame: ground (z = -1.5), wall x = 8, wall y = -6, and
// clutter. Points per patch scale with `density`.
struct CornerScene {
  std::vector<Eigen::Vector3f> points;
  std::vector<Plane> planes;  // ground, wall_x, wall_y
};

inline CornerScene MakeCornerScene(double noise, int density, unsigned seed) {
  CornerScene s;
  std::mt19937 rng(seed);
  const Eigen::Vector3d ex = Eigen::Vector3d::UnitX(), ey = Eigen::Vector3d::UnitY(),
                        ez = Eigen::Vector3d::UnitZ();
  AddPatch({-20, -20, -1.5}, ex, ey, 28, 40, 6 * density, noise, &rng, &s.points);  // ground
  AddPatch({8, -20, -1.5}, ey, ez, 40, 8, 3 * density, noise, &rng, &s.points);     // wall x=8
  AddPatch({-20, -6, -1.5}, ez, ex, 8, 28, 3 * density, noise, &rng, &s.points);    // wall y=-6
  AddClutter({-10, -3, -1.2}, {6, 15, 3}, density, &rng, &s.points);
  s.planes.push_back(Plane{ez, 1.5});
  s.planes.push_back(Plane{ex, -8.0});
  s.planes.push_back(Plane{ey, 6.0});
  return s;
}

}  // namespace ppf::test
