#include "ppf_core/lio/voxel_map.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <utility>

namespace ppf {

VoxelMap::VoxelMap(const VoxelMapOptions& options) : options_(options) {
  if (!(options_.resolution > 1e-3)) options_.resolution = 1e-3;  // guards tiny/NaN voxel sizes
  if (options_.max_voxels == 0) options_.max_voxels = 1;
  if (options_.max_points_per_voxel == 0) options_.max_points_per_voxel = 1;
  inv_resolution_ = 1.0 / options_.resolution;
  BuildOffsets();
}

void VoxelMap::Insert(const Point& p) {
  if (!p.allFinite()) return;
  const VoxelKey key = ToVoxelKey(p, inv_resolution_);
  Entry* e = index_.Find(key);
  if (e == nullptr) {
    lru_.push_front(Voxel{key, {}});
    lru_.front().points.reserve(std::min<size_t>(options_.max_points_per_voxel, 8));
    e = index_.Insert(key, Entry{lru_.begin()});
    if (index_.size() > options_.max_voxels) {
      EvictOldest();
      e = index_.Find(key);  // the erasure moves slots
    }
  } else if (e->it != lru_.begin()) {
    lru_.splice(lru_.begin(), lru_, e->it);  // O(1), iterators stay valid
  }
  std::vector<Point>& pts = e->it->points;
  if (pts.size() >= options_.max_points_per_voxel) return;
  const float min_d2 =
      static_cast<float>(options_.min_point_distance * options_.min_point_distance);
  if (min_d2 > 0.f) {
    for (const Point& q : pts) {
      if ((q - p).squaredNorm() < min_d2) return;
    }
  }
  pts.push_back(p);
  e->points = pts.data();
  e->count = static_cast<uint32_t>(pts.size());
  ++num_points_;
}

void VoxelMap::Insert(const std::vector<Point>& points) {
  for (const Point& p : points) Insert(p);
}

size_t VoxelMap::GetClosest(const Point& query, size_t k, double max_range,
                            std::vector<Point>* out) const {
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
    const NeighbourBounds bounds = BoundsAt(f);
    // Three passes over the voxels within reach, so that their cache misses overlap: the slots'
    // loads are issued, then the slots read and their points' loads issued, then the points
    // scanned in the same order and with the same skips as a single pass would make.
    VoxelKey keys[27];
    double lower2[27];  // each voxel's bound, for the third pass's skip
    const Entry* entries[27];
    size_t m = 0;
    for (const VoxelKey& o : offsets_) {
      // A neighbour voxel that lies wholly beyond the search radius, or beyond the k-th best
      // distance once k points are held (third pass), cannot change the result: it is skipped.
      // The bound is a lower bound with a margin for the rounding of the point distances and of
      // the voxel keys, so no point it could hold is ever left out.
      lower2[m] = bounds.LowerBound2(o, options_.resolution);
      if ((o.x != 0 || o.y != 0 || o.z != 0) && lower2[m] > max_d2 * (1.0 + 1e-4)) continue;
      keys[m] = VoxelKey{c.x + o.x, c.y + o.y, c.z + o.z};
      index_.Prefetch(keys[m]);
      ++m;
    }
    for (size_t i = 0; i < m; ++i) {
      entries[i] = index_.Find(keys[i]);
      if (entries[i] != nullptr) __builtin_prefetch(entries[i]->points);
    }
    for (size_t i = 0; i < m; ++i) {
      const Entry* e = entries[i];
      if (e == nullptr) continue;
      if (i != 0 && n == k &&
          lower2[i] > std::min<double>(best_d2[k - 1], max_d2) * (1.0 + 1e-4)) {
        continue;
      }
      for (uint32_t j = 0; j < e->count; ++j) {
        const Point& p = e->points[j];
        const float d2 = (p - query).squaredNorm();
        if (!(d2 <= max_d2)) continue;
        if (n == k && !(d2 < best_d2[k - 1])) continue;
        size_t s = n < k ? n++ : k - 1;
        for (; s > 0 && best_d2[s - 1] > d2; --s) {
          best_d2[s] = best_d2[s - 1];
          best[s] = best[s - 1];
        }
        best_d2[s] = d2;
        best[s] = p;
      }
    }
    out->assign(best, best + n);
    return n;
  }
  std::vector<std::pair<float, Point>> cand;
  cand.reserve(64);
  for (const VoxelKey& o : offsets_) {
    const Entry* e = index_.Find(VoxelKey{c.x + o.x, c.y + o.y, c.z + o.z});
    if (e == nullptr) continue;
    for (uint32_t i = 0; i < e->count; ++i) {
      const Point& p = e->points[i];
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

void VoxelMap::RemoveFarFrom(const Eigen::Vector3d& center, double radius) {
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

void VoxelMap::clear() {
  lru_.clear();
  index_.clear();
  num_points_ = 0;
}

VoxelMap::NeighbourBounds VoxelMap::BoundsAt(const Eigen::Vector3d& f) {
  constexpr double kMargin = 1e-4;
  NeighbourBounds b;
  for (int a = 0; a < 3; ++a) {
    const double below = std::max(0.0, f[a] - kMargin);
    const double above = std::max(0.0, 1.0 - f[a] - kMargin);
    b.gap2[a][0] = below * below;
    b.gap2[a][1] = 0.0;
    b.gap2[a][2] = above * above;
  }
  return b;
}

void VoxelMap::EvictOldest() {
  num_points_ -= lru_.back().points.size();
  index_.Erase(lru_.back().key);
  lru_.pop_back();
}

void VoxelMap::BuildOffsets() {
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
  // Faces, then edges, then corners: a neighbour across more faces is farther by its lower bound,
  // so the k best fill from the nearer voxels first and more of the farther ones are skipped.
  std::stable_sort(offsets_.begin(), offsets_.end(), [](const VoxelKey& a, const VoxelKey& b) {
    return std::abs(a.x) + std::abs(a.y) + std::abs(a.z) <
           std::abs(b.x) + std::abs(b.y) + std::abs(b.z);
  });
}

}  // namespace ppf
