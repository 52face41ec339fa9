// Integer voxel coordinates of a point: the key of the kNN map (voxel_map.hpp) and of the plain
// voxel grid (voxel_downsample.hpp).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

namespace ppf {

struct VoxelKey {
  int32_t x = 0, y = 0, z = 0;
  bool operator==(const VoxelKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

struct VoxelKeyHash {
  size_t operator()(const VoxelKey& k) const {
    // Large primes (Teschner et al. spatial hashing); collisions only cost a bucket scan.
    return static_cast<size_t>((static_cast<int64_t>(k.x) * 73856093) ^
                               (static_cast<int64_t>(k.y) * 471943) ^
                               (static_cast<int64_t>(k.z) * 83492791));
  }
};

inline VoxelKey ToVoxelKey(const Eigen::Vector3f& p, double inv_resolution) {
  return VoxelKey{static_cast<int32_t>(std::floor(p.x() * inv_resolution)),
                  static_cast<int32_t>(std::floor(p.y() * inv_resolution)),
                  static_cast<int32_t>(std::floor(p.z() * inv_resolution))};
}

// floor(v) + bias for a cell coordinate v >= -bias, by one truncation of the double v + bias
// (non-negative in that range), where std::floor is a library call on the x86-64 baseline. It is
// the same integer except where the sum rounds up to one: v within half an ulp of v + bias below a
// face (at most bias * 2^-53 cell: a float or double artefact of a point on the face), which then
// joins the cell above. The packed keys of the voxel grid and of the plane patch map use it.
inline uint64_t BiasedFloor(double v, double bias) {
  return static_cast<uint64_t>(static_cast<int64_t>(v + bias));
}

}  // namespace ppf
