// Iterative PCA plane refinement (paper Sec. IV-A2).
//
// A RANSAC plane comes from 3 noisy points; iPCA lets all strict inliers vote: PCA of the points
// within delta, normal = eigenvector of the smallest eigenvalue, d = -n.centroid, re-select,
// repeat. It stops when the inlier count stops changing. A count sequence a,b,a,b means the
// refinement jumps between two inlier sets (two near-coincident surfaces, a step in the ground):
// the plane is ambiguous and the refinement reports failure.
//
// The reference shrinks the inlier band with a median-based robust scale; on real scans it stays
// ~delta, so a fixed delta is used (one fewer pass over the points, identical in practice).
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/ppf/plane.hpp"

namespace ppf {

struct IpcaResult {
  bool success = false;  // converged or ran out of iterations without oscillating, enough inliers
  bool oscillated = false;         // inlier counts alternated (a,b,a,b)
  Plane plane;                     // refined plane; normal oriented like the initial plane's
  int iterations = 0;              // PCA solves performed
  int num_inliers = 0;             // strict inliers of `plane`
  std::vector<int> inlier_counts;  // count history: [initial, after 1st solve, ...]
};

// True if the last four counts alternate a,b,a,b with a != b.
bool IpcaCountsOscillate(const std::vector<int>& counts);

// Refines `initial` against `points` for at most `max_iterations` PCA solves. Fails when fewer
// than max(3, min_inliers) strict inliers remain, on oscillation, or on a degenerate (line-like)
// inlier set. OpenMP-parallel accumulation for full-resolution scans. `max_norm`, if positive,
// bounds |p| over `points`: then passes whose plane moved little visit only the points near the
// last full pass's plane. The result does not depend on it.
IpcaResult RefinePlaneIpca(const std::vector<Eigen::Vector3f>& points, const Plane& initial,
                           double delta, int max_iterations, int min_inliers,
                           double max_norm = 0.0);

// One least-squares (PCA) plane through all `points`; empty for < 3 points or a line-like set.
// The baseline iPCA is compared against.
std::optional<Plane> FitPlaneLeastSquares(const std::vector<Eigen::Vector3f>& points);

}  // namespace ppf
