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
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <list>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/config.hpp"  // this stage's options

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

class VoxelMap {
 public:
  using Point = Eigen::Vector3f;

  explicit VoxelMap(const VoxelMapOptions& options = VoxelMapOptions()) : options_(options) {
    if (!(options_.resolution > 1e-3)) options_.resolution = 1e-3;  // guards tiny/NaN voxel sizes
    if (options_.max_voxels == 0) options_.max_voxels = 1;
    if (options_.max_points_per_voxel == 0) options_.max_points_per_voxel = 1;
    inv_resolution_ = 1.0 / options_.resolution;
    BuildOffsets();
  }

  const VoxelMapOptions& options() const { return options_; }

  void Insert(const Point& p) {
    if (!p.allFinite()) return;
    const VoxelKey key = ToVoxelKey(p, inv_resolution_);
    const VoxelIt* found = index_.Find(key);
    VoxelIt it;
    if (found == nullptr) {
      lru_.push_front(Voxel{key, {}});
      lru_.front().points.reserve(std::min<size_t>(options_.max_points_per_voxel, 8));
      it = lru_.begin();
      index_.Insert(key, it);
      if (index_.size() > options_.max_voxels) EvictOldest();
    } else {
      it = *found;
      if (it != lru_.begin()) lru_.splice(lru_.begin(), lru_, it);  // O(1), iterators stay valid
    }
    std::vector<Point>& pts = it->points;
    if (pts.size() >= options_.max_points_per_voxel) return;
    const float min_d2 =
        static_cast<float>(options_.min_point_distance * options_.min_point_distance);
    if (min_d2 > 0.f) {
      for (const Point& q : pts) {
        if ((q - p).squaredNorm() < min_d2) return;
      }
    }
    pts.push_back(p);
    ++num_points_;
  }

  void Insert(const std::vector<Point>& points) {
    for (const Point& p : points) Insert(p);
  }

  // Up to k nearest stored points within max_range of `query`, nearest first (equal distances in
  // the order the voxels are visited). Returns the count.
  size_t GetClosest(const Point& query, size_t k, double max_range, std::vector<Point>* out) const {
    out->clear();
    if (k == 0 || !query.allFinite()) return 0;
    const float max_d2 = static_cast<float>(max_range * max_range);
    const VoxelKey c = ToVoxelKey(query, inv_resolution_);
    // k is tiny (5) in every use: an insertion-sorted array on the stack keeps the k best so far.
    // A per-query candidate vector and a partial sort cost a heap allocation and a heap sort per
    // query, the bulk of the kNN residual stage (docs/decisions.md, "kNN search on the stack").
    if (k <= kMaxStackK) {
      float best_d2[kMaxStackK];
      Point best[kMaxStackK];
      size_t n = 0;
      // The query's position inside its voxel, in voxel units: a neighbour voxel's nearest face
      // lies (1 - f) or f away along each axis where it differs.
      const Eigen::Vector3d f =
          query.cast<double>() * inv_resolution_ - Eigen::Vector3d(c.x, c.y, c.z);
      for (const VoxelKey& o : offsets_) {
        // A neighbour voxel that lies wholly beyond the search radius, or beyond the k-th best
        // distance once k points are held, cannot change the result: its hash lookup (the cost of
        // a query) is skipped. The bound is a lower bound with a margin for the rounding of the
        // point distances and of the voxel keys, so no point it could hold is ever left out.
        if (o.x != 0 || o.y != 0 || o.z != 0) {
          const double limit = n == k ? std::min<double>(best_d2[k - 1], max_d2) : max_d2;
          if (NeighbourLowerBound2(f, o) > limit * (1.0 + 1e-4)) continue;
        }
        const VoxelIt* it = index_.Find(VoxelKey{c.x + o.x, c.y + o.y, c.z + o.z});
        if (it == nullptr) continue;
        for (const Point& p : (*it)->points) {
          const float d2 = (p - query).squaredNorm();
          if (!(d2 <= max_d2)) continue;
          if (n == k && !(d2 < best_d2[k - 1])) continue;
          size_t j = n < k ? n++ : k - 1;
          for (; j > 0 && best_d2[j - 1] > d2; --j) {
            best_d2[j] = best_d2[j - 1];
            best[j] = best[j - 1];
          }
          best_d2[j] = d2;
          best[j] = p;
        }
      }
      out->assign(best, best + n);
      return n;
    }
    std::vector<std::pair<float, Point>> cand;
    cand.reserve(64);
    for (const VoxelKey& o : offsets_) {
      const VoxelIt* it = index_.Find(VoxelKey{c.x + o.x, c.y + o.y, c.z + o.z});
      if (it == nullptr) continue;
      for (const Point& p : (*it)->points) {
        const float d2 = (p - query).squaredNorm();
        if (d2 <= max_d2) cand.emplace_back(d2, p);
      }
    }
    const size_t n = std::min(k, cand.size());
    std::partial_sort(cand.begin(), cand.begin() + static_cast<std::ptrdiff_t>(n), cand.end(),
                      [](const auto& a, const auto& b) { return a.first < b.first; });
    out->reserve(n);
    for (size_t i = 0; i < n; ++i) out->push_back(cand[i].second);
    return n;
  }

  // Drops every voxel whose centre is farther than `radius` from `center` (distance-based bound
  // on top of the LRU one; the facade calls it with the sensor position).
  void RemoveFarFrom(const Eigen::Vector3d& center, double radius) {
    const double r2 = radius * radius;
    for (auto it = lru_.begin(); it != lru_.end();) {
      const Eigen::Vector3d vc((it->key.x + 0.5) * options_.resolution,
                               (it->key.y + 0.5) * options_.resolution,
                               (it->key.z + 0.5) * options_.resolution);
      if ((vc - center).squaredNorm() > r2) {
        num_points_ -= it->points.size();
        index_.Erase(it->key);
        it = lru_.erase(it);
      } else {
        ++it;
      }
    }
  }

  void clear() {
    lru_.clear();
    index_.clear();
    num_points_ = 0;
  }

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

  // Squared distance from a query (at f in voxel units within its voxel) to the nearest point of
  // the neighbour voxel at offset o, in metres squared, less a margin of 1e-4 voxel per axis.
  double NeighbourLowerBound2(const Eigen::Vector3d& f, const VoxelKey& o) const {
    constexpr double kMargin = 1e-4;
    double sum = 0.0;
    const int off[3] = {o.x, o.y, o.z};
    for (int a = 0; a < 3; ++a) {
      double gap = off[a] > 0 ? 1.0 - f[a] : (off[a] < 0 ? f[a] : 0.0);
      gap = std::max(0.0, gap - kMargin);
      sum += gap * gap;
    }
    return sum * options_.resolution * options_.resolution;
  }

  struct Voxel {
    VoxelKey key;
    std::vector<Point> points;
  };
  using VoxelIt = std::list<Voxel>::iterator;

  // Key -> voxel, open addressing with linear probing (power-of-two capacity, at most half full,
  // backward-shift deletion). A query looks up 7-27 voxels, most of them empty; std::unordered_map
  // went through a bucket and a node for each, here a lookup reads one slot, or a few adjacent
  // ones. Only lookups depend on it: nothing iterates over it, so its order changes no result.
  class Index {
   public:
    const VoxelIt* Find(const VoxelKey& k) const {
      if (size_ == 0) return nullptr;
      for (size_t i = Home(k);; i = (i + 1) & mask_) {
        const Slot& s = slots_[i];
        if (!s.used) return nullptr;
        if (s.key == k) return &s.voxel;
      }
    }
    void Insert(const VoxelKey& k, VoxelIt v) {  // k must not be present
      if (2 * (size_ + 1) > slots_.size()) Grow();
      size_t i = Home(k);
      while (slots_[i].used) i = (i + 1) & mask_;
      slots_[i] = Slot{k, true, v};
      ++size_;
    }
    void Erase(const VoxelKey& k) {
      if (size_ == 0) return;
      size_t i = Home(k);
      for (;; i = (i + 1) & mask_) {
        if (!slots_[i].used) return;
        if (slots_[i].key == k) break;
      }
      // Backward shift: a later entry of the run moves into the hole when the hole lies on its
      // probe path (its distance from home is at least the hole's distance behind it).
      for (size_t j = (i + 1) & mask_; slots_[j].used; j = (j + 1) & mask_) {
        if (((j - Home(slots_[j].key)) & mask_) >= ((j - i) & mask_)) {
          slots_[i] = slots_[j];
          i = j;
        }
      }
      slots_[i] = Slot{};
      --size_;
    }
    size_t size() const { return size_; }
    void clear() {
      slots_.clear();
      mask_ = 0;
      size_ = 0;
    }

   private:
    struct Slot {
      VoxelKey key;
      bool used = false;
      VoxelIt voxel;
    };
    size_t Home(const VoxelKey& k) const {
      uint64_t h = static_cast<uint64_t>(static_cast<uint32_t>(k.x)) * 0x9E3779B97F4A7C15ULL ^
                   static_cast<uint64_t>(static_cast<uint32_t>(k.y)) * 0xC2B2AE3D27D4EB4FULL ^
                   static_cast<uint64_t>(static_cast<uint32_t>(k.z)) * 0x165667B19E3779F9ULL;
      h ^= h >> 32;
      return static_cast<size_t>(h) & mask_;
    }
    void Grow() {
      std::vector<Slot> old;
      old.swap(slots_);
      slots_.resize(std::max<size_t>(64, old.size() * 2));
      mask_ = slots_.size() - 1;
      size_ = 0;
      for (const Slot& s : old) {
        if (s.used) Insert(s.key, s.voxel);
      }
    }
    std::vector<Slot> slots_;
    size_t mask_ = 0;
    size_t size_ = 0;
  };

  void EvictOldest() {
    num_points_ -= lru_.back().points.size();
    index_.Erase(lru_.back().key);
    lru_.pop_back();
  }

  void BuildOffsets() {
    offsets_.clear();
    offsets_.push_back({0, 0, 0});
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const int manhattan = std::abs(dx) + std::abs(dy) + std::abs(dz);
          if (manhattan == 0) continue;
          const bool take = (options_.nearby == NearbyType::kNearby7 && manhattan == 1) ||
                            (options_.nearby == NearbyType::kNearby19 && manhattan <= 2) ||
                            (options_.nearby == NearbyType::kNearby27);
          if (take) offsets_.push_back({dx, dy, dz});
        }
      }
    }
  }

  VoxelMapOptions options_;
  double inv_resolution_ = 2.0;
  std::list<Voxel> lru_;  // front = most recently fed
  Index index_;
  std::vector<VoxelKey> offsets_;
  size_t num_points_ = 0;
};

// Voxel-grid downsampling: one point per occupied voxel, in order of first appearance
// (deterministic). kCentroid (default, as PCL's VoxelGrid in Faster-LIO) returns the mean of the
// voxel's points; kNearestToCentroid keeps the measured point closest to that mean, which always
// lies on a surface (no points floating between two planes at edges). The centroid is the
// default for its accuracy (docs/decisions.md, "Downsample to the centroid").
// A non-positive or tiny voxel size returns the input unchanged.
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
