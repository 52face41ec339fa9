#include "ppf_core/ppf/plane_patch_map.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "ppf_core/lio/voxel_key.hpp"

namespace ppf {

PlanePatchMap::PlanePatchMap(const PlanePatchMapOptions& options) : options_(options) {
  if (!(options_.cell_size > 0.05)) options_.cell_size = 0.05;
  options_.max_patches_per_cell = std::max(1, options_.max_patches_per_cell);
  options_.min_points = std::max(3, options_.min_points);
  if (!(options_.min_spread_ratio >= 0.0)) options_.min_spread_ratio = 0.0;
  options_.max_points = std::max(options_.min_points, options_.max_points);
  options_.max_cells = std::max<size_t>(1, options_.max_cells);
  inv_cell_ = 1.0 / options_.cell_size;
  same_surface_cos_ = std::cos(options_.same_surface_deg * M_PI / 180.0);
}

uint64_t PlanePatchMap::KeyOf(const Eigen::Vector3d& p) const {
  // 21 bits per axis: +-2^20 cells (+-2000 km at 2 m).
  constexpr double kBias = static_cast<double>(int64_t{1} << 20);
  constexpr uint64_t kMask = (uint64_t{1} << 21) - 1;
  // The cell's floor by BiasedFloor (voxel_key.hpp): a coordinate within 2^-33 cell below a face
  // joins the cell above.
  const auto axis = [&](double v) { return BiasedFloor(v * inv_cell_, kBias) & kMask; };
  return (axis(p.x()) << 42) | (axis(p.y()) << 21) | axis(p.z());
}

void PlanePatchMap::Insert(const Eigen::Vector3d& p_world, const Eigen::Vector3d& n_world) {
  InsertHint hint;
  Insert(p_world, n_world, &hint);
}

void PlanePatchMap::Insert(const Eigen::Vector3d& p_world, const Eigen::Vector3d& n_world,
                           InsertHint* hint) {
  if (!p_world.allFinite() || !n_world.allFinite()) return;
  const uint64_t key = KeyOf(p_world);
  if (hint->cell_ == nullptr || key != hint->key_) {
    hint->cell_ = &cells_[key];
    hint->key_ = key;
  }
  Cell& cell = *hint->cell_;
  cell.last_insert = generation_ + 1;
  const double min_cos = same_surface_cos_;
  Patch* patch = nullptr;
  for (Patch& candidate : cell.patches) {
    const Eigen::Vector3d& n = candidate.normal_dir;
    if (std::abs(n.dot(n_world)) >= min_cos &&
        std::abs(n.dot(p_world - candidate.moments.centroid)) < options_.same_surface_offset) {
      patch = &candidate;
      break;
    }
  }
  if (patch == nullptr) {
    if (static_cast<int>(cell.patches.size()) >= options_.max_patches_per_cell) return;
    cell.patches.emplace_back();
    ++num_patches_;
    patch = &cell.patches.back();
  }
  if (patch->moments.count >= options_.max_points) return;  // frozen: nothing to refit
  if (cell.changed != generation_ + 1) {
    cell.changed = generation_ + 1;
    touched_.push_back(key);
  }
  patch->changed = generation_ + 1;
  // Normals of one surface may arrive with either sign (planes are fitted per scan).
  patch->normal_sum += patch->normal_sum.dot(n_world) < 0.0 ? -n_world : n_world;
  patch->normal_dir = patch->normal_sum.normalized();
  PlaneMoments one;
  one.count = 1.0;
  one.centroid = p_world;
  patch->moments.Merge(one);
}

void PlanePatchMap::Refit(Patch* patch) const {
  const PlaneMoments& m = patch->moments;
  patch->usable = false;
  if (m.count < options_.min_points) return;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(m.scatter);
  const Eigen::Vector3d ev = es.eigenvalues();
  const double min_spread = options_.min_spread_ratio * options_.cell_size;
  if (ev(1) / m.count < min_spread * min_spread || !(ev(0) < 0.1 * ev(1))) return;
  const Eigen::Vector3d& n = patch->normal_dir;
  const Eigen::Vector3d pca = es.eigenvectors().col(0);
  if (std::abs(pca.dot(n)) < same_surface_cos_) return;
  patch->plane = Plane{pca, -pca.dot(m.centroid)};
  patch->usable = true;
}

void PlanePatchMap::FinishInsert() {
  for (uint64_t key : touched_) {
    auto it = cells_.find(key);
    if (it == cells_.end()) continue;
    // A patch no point changed since its last refit would come out the same.
    for (Patch& p : it->second.patches) {
      if (p.changed == generation_ + 1) Refit(&p);
    }
  }
  touched_.clear();
  ++generation_;
  if (cells_.size() > options_.max_cells) {
    // Drop the least recently fed cells down to 90 % of the bound (amortised: rarely runs).
    std::vector<std::pair<uint64_t, uint64_t>> age;  // last_insert, key
    age.reserve(cells_.size());
    for (const auto& [key, cell] : cells_) age.emplace_back(cell.last_insert, key);
    const size_t keep = options_.max_cells * 9 / 10;
    std::nth_element(age.begin(), age.begin() + static_cast<std::ptrdiff_t>(age.size() - keep),
                     age.end());
    for (size_t i = 0; i < age.size() - keep; ++i) {
      const auto it = cells_.find(age[i].second);
      num_patches_ -= it->second.patches.size();
      cells_.erase(it);
    }
  }
}

const PlanePatchMap::Patch* PlanePatchMap::Find(const Eigen::Vector3d& p_world,
                                                const Eigen::Vector3d& n_world,
                                                double min_cos) const {
  const auto it = cells_.find(KeyOf(p_world));
  if (it == cells_.end()) return nullptr;
  const Patch* best = nullptr;
  double best_distance = 0.0;
  for (const Patch& patch : it->second.patches) {
    if (!patch.usable) continue;
    if (std::abs(patch.plane.n.dot(n_world)) < min_cos) continue;
    const double distance = patch.plane.Distance(p_world);
    if (best == nullptr || distance < best_distance) {
      best = &patch;
      best_distance = distance;
    }
  }
  return best;
}

void PlanePatchMap::RemoveFarFrom(const Eigen::Vector3d& center, double radius) {
  const double r2 = radius * radius;
  for (auto it = cells_.begin(); it != cells_.end();) {
    if (it->second.patches.empty() ||
        (it->second.patches.front().moments.centroid - center).squaredNorm() > r2) {
      num_patches_ -= it->second.patches.size();
      it = cells_.erase(it);
    } else {
      ++it;
    }
  }
}

void PlanePatchMap::Clear() {
  cells_.clear();
  touched_.clear();
  num_patches_ = 0;
}

}  // namespace ppf
