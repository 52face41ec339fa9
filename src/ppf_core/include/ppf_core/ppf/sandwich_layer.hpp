// The sandwich layer (paper Sec. IV-C): the "remove" step of fit-remove-fit.
//
// Around a refined plane, points are split by |n.p + d|:
//   < delta                        strict inliers -> skeleton points (Omega) of this plane
//   [delta, semi_factor * delta)   semi-inliers   -> discarded: no residual, not in the map
//   >= semi_factor * delta         outliers       -> stay for the next fitting round
// Why discard semi-inliers: a point just outside the strict band may belong to a second surface
// meeting this one at a small angle (a slope rising from flat ground). If it stayed, a later
// plane fitted through it would hand skeleton points that lie within eps of this plane, and
// the nearest-plane search (Eq. 10) would match them to the wrong plane. With the semi band at
// least eps + delta thick, every point left for later is > eps from this plane.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/ppf/plane.hpp"

namespace ppf {

enum class SandwichClass : uint8_t { kStrict = 0, kSemi = 1, kOutlier = 2 };

struct SandwichSplit {
  std::vector<int> strict;    // positions (into the input vector) of strict inliers
  std::vector<int> semi;      // positions of discarded semi-inliers
  std::vector<int> outliers;  // positions of points kept for the next round
};

// Classifies one signed distance.
inline SandwichClass ClassifySandwich(double signed_distance, double delta, double semi_factor) {
  const double a = signed_distance < 0 ? -signed_distance : signed_distance;
  if (a < delta) return SandwichClass::kStrict;
  if (a < semi_factor * delta) return SandwichClass::kSemi;
  return SandwichClass::kOutlier;  // also NaN-free inputs far away
}

// Splits all `points` around `plane`; positions keep ascending order in each list.
// semi_factor <= 1 disables the semi layer (for ablation only). OpenMP-parallel classification.
void SplitSandwich(const std::vector<Eigen::Vector3f>& points, const Plane& plane, double delta,
                   double semi_factor, SandwichSplit* split);

// SplitSandwich in two steps, for a caller that tests the strict inliers before it needs the rest
// (a plane refused for its shape never needs its semi-inlier and outlier lists, which hold most of
// the points): LabelSandwich classifies every point into `labels` (SandwichClass values) and fills
// split->strict only, clearing the other lists; CompleteSandwich then fills split->semi and
// split->outliers from those labels. Together they give SplitSandwich's lists.
void LabelSandwich(const std::vector<Eigen::Vector3f>& points, const Plane& plane, double delta,
                   double semi_factor, std::vector<uint8_t>* labels, SandwichSplit* split);
void CompleteSandwich(const std::vector<uint8_t>& labels, SandwichSplit* split);

}  // namespace ppf
