// Incremental voxel-hash map for k-nearest-neighbour queries (the iVox idea of Faster-LIO,
// written from its description): points live in a hash map of voxels, a query looks only into the
// voxel of the query point and its neighbours, and insertion never rebuilds anything.
//
// Memory is bounded by construction: voxels sit in an LRU list ordered by their last insertion;
// when more than `max_voxels` exist, the least recently fed voxel is dropped, and each voxel keeps
// at most `max_points_per_voxel` points. So size() <= max_voxels * max_points_per_voxel forever,
// whatever the trajectory length. RemoveFarFrom() additionally drops voxels far from the sensor.
//
// Exactness: with kNearby27 and max_range <= resolution, GetClosest() returns exactly the k
// nearest stored points within max_range (every such point lies in one of the 27 voxels). Smaller
// neighbourhoods (7, 19) are approximations that trade recall at voxel corners for speed.
//
// Thread safety: const methods (queries) may run concurrently; Insert/Remove need exclusivity.
// The key -> voxel table is detail/voxel_index.hpp; the code is src/lio/voxel_map.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <list>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/config.hpp"  // this stage's options
#include "ppf_core/lio/detail/voxel_index.hpp"
#include "ppf_core/lio/voxel_key.hpp"

namespace ppf {

class VoxelMap {
 public:
  using Point = Eigen::Vector3f;

  explicit VoxelMap(const VoxelMapOptions& options = VoxelMapOptions());

  const VoxelMapOptions& options() const { return options_; }

  // Adds a point to its voxel (the voxel becomes the most recently fed; a full voxel or a point
  // within min_point_distance of one already stored ignores it). Non-finite points are ignored.
  void Insert(const Point& p);
  void Insert(const std::vector<Point>& points);

  // Up to k nearest stored points within max_range of `query`, nearest first (equal distances in
  // the order the voxels are visited). Returns the count.
  size_t GetClosest(const Point& query, size_t k, double max_range, std::vector<Point>* out) const;

  // Drops every voxel whose centre is farther than `radius` from `center` (distance-based bound
  // on top of the LRU one; the facade calls it with the sensor position).
  void RemoveFarFrom(const Eigen::Vector3d& center, double radius);

  void clear();

  // Calls fn(point) for every stored point, most recently fed voxel first (read-only: a map
  // export, not a query path).
  template <typename Fn>
  void ForEachPoint(Fn&& fn) const {
    for (const Voxel& v : lru_) {
      for (const Point& p : v.points) fn(p);
    }
  }

  size_t size() const { return num_points_; }  // stored points
  size_t num_voxels() const { return index_.size(); }
  // The bound size() can never exceed.
  size_t capacity_points() const { return options_.max_voxels * options_.max_points_per_voxel; }

 private:
  static constexpr size_t kMaxStackK = 16;

  struct Voxel {
    VoxelKey key;
    std::vector<Point> points;
  };
  using VoxelIt = std::list<Voxel>::iterator;
  // What the index holds of a voxel: its place in lru_, and where its points are (the vector's
  // buffer and size, renewed by every insertion into it). A query reads the slot, then the
  // points: the list node between them was one more dependent load per voxel visited, and a
  // query waits on those loads far more than it computes.
  struct Entry {
    VoxelIt it;
    const Point* points = nullptr;
    uint32_t count = 0;
  };

  // Squared distance from a query (at f in voxel units within its voxel) to the nearest point of
  // the neighbour voxel at offset o, in metres squared, less a margin of 1e-4 voxel per axis:
  // each axis's squared gap to the voxel below, its own and the one above, taken once per query.
  struct NeighbourBounds {
    double gap2[3][3];  // [axis][offset + 1]
    double LowerBound2(const VoxelKey& o, double resolution) const {
      const double sum = gap2[0][o.x + 1] + gap2[1][o.y + 1] + gap2[2][o.z + 1];
      return sum * resolution * resolution;
    }
  };
  static NeighbourBounds BoundsAt(const Eigen::Vector3d& f);
  void EvictOldest();
  void BuildOffsets();

  VoxelMapOptions options_;
  double inv_resolution_ = 2.0;
  std::list<Voxel> lru_;  // front = most recently fed
  detail::VoxelIndex<Entry> index_;
  std::vector<VoxelKey> offsets_;
  size_t num_points_ = 0;
};

}  // namespace ppf
