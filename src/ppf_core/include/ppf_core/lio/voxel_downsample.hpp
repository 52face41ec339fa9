// Voxel-grid downsampling of plain points (no per-point time): one point per occupied voxel, in
// order of first appearance (deterministic). The scan pipeline's grid, which also averages point
// times, is VoxelGridDownsampler (preprocess.hpp); this one serves tools and tests, and is the
// reference that grid is tested against.
//
// kCentroid (default, as PCL's VoxelGrid in Faster-LIO) returns the mean of the voxel's points;
// kNearestToCentroid keeps the measured point closest to that mean, which always lies on a
// surface (no points floating between two planes at edges). The centroid is the default for its
// accuracy (docs/decisions.md, "Downsample to the centroid"). A non-positive or tiny voxel size
// returns the input unchanged.
#pragma once

#include <cstddef>
#include <limits>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/lio/voxel_key.hpp"

namespace ppf {

enum class DownsampleMode { kCentroid, kNearestToCentroid };

inline std::vector<Eigen::Vector3f> VoxelDownsample(
    const std::vector<Eigen::Vector3f>& points, double voxel_size,
    DownsampleMode mode = DownsampleMode::kCentroid) {
  if (!(voxel_size > 1e-3)) return points;
  const double inv = 1.0 / voxel_size;
  std::unordered_map<VoxelKey, size_t, VoxelKeyHash> slot;
  slot.reserve(points.size());
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> count;
  std::vector<size_t> point_slot(points.size(), static_cast<size_t>(-1));
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    if (!p.allFinite()) continue;
    const auto [it, inserted] = slot.emplace(ToVoxelKey(p, inv), sum.size());
    if (inserted) {
      sum.push_back(p.cast<double>());
      count.push_back(1);
    } else {
      sum[it->second] += p.cast<double>();
      ++count[it->second];
    }
    point_slot[i] = it->second;
  }
  std::vector<Eigen::Vector3f> out(sum.size());
  for (size_t i = 0; i < sum.size(); ++i) out[i] = (sum[i] / count[i]).cast<float>();
  if (mode == DownsampleMode::kCentroid) return out;
  std::vector<float> best(sum.size(), std::numeric_limits<float>::infinity());
  std::vector<Eigen::Vector3f> picked(sum.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const size_t s = point_slot[i];
    if (s == static_cast<size_t>(-1)) continue;
    const float d2 = (points[i] - out[s]).squaredNorm();
    if (d2 < best[s]) {
      best[s] = d2;
      picked[s] = points[i];
    }
  }
  return picked;
}

}  // namespace ppf
