#include "ppf_core/ppf/skeleton_residual.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "ppf_core/lio/knn_residual.hpp"
#include "ppf_core/ppf/plane_prefitter.hpp"
#include "ppf_core/ppf/skeleton_window.hpp"

namespace ppf {

// The matching of the skeleton points at one pose in three steps (ResidualProvider::PrepareRows):
// Prepare on the calling thread, Point for each skeleton point on any thread (each writes only
// its own slots), Collect on the calling thread. own_normals may be empty (no gate, no patches);
// otherwise parallel to skeleton_indices. lookups, found: nullptr = not kept.
struct SkeletonMatchLoop {
  const std::vector<Eigen::Vector3f>& points_lidar;
  const std::vector<int>& skeleton_indices;
  const std::vector<Eigen::Vector3d>& own_normals;
  double normal_gate_deg;
  const Eigen::Isometry3d& T_world_lidar;
  const std::vector<Plane>& window_world;
  double eps;
  const PlanePatchMap* patches;
  bool window_fallback;
  std::vector<PatchLookup>* lookups;
  float keep_distance;
  std::vector<const PlanePatchMap::Patch*>* found;
  std::vector<Plane>* local;              // the window in the LiDAR frame (scratch)
  std::vector<SkeletonMatch>* per_point;  // per skeleton point (scratch)

  bool use_patches() const {
    return patches != nullptr && own_normals.size() == skeleton_indices.size() &&
           patches->num_cells() > 0;
  }

  // Sizes what Point writes; false: no point can match (then Point must not be called).
  bool Prepare() const {
    if (found != nullptr) found->assign(skeleton_indices.size(), nullptr);
    if ((window_world.empty() && !use_patches()) || skeleton_indices.empty() || !(eps > 0.0)) {
      per_point->clear();
      return false;
    }
    // Fold the pose into the planes once: f_L = (T_lidar_world^-1)^T f_W (Theorem 1), so each
    // point costs one dot product per plane and the signed distance is unchanged (rigid motion).
    const Eigen::Isometry3d T_lidar_world = T_world_lidar.inverse();
    local->resize(window_world.size());
    for (size_t j = 0; j < window_world.size(); ++j) {
      (*local)[j] = TransformPlane(T_lidar_world, window_world[j]);
    }
    per_point->resize(skeleton_indices.size());  // Point writes every slot
    if (lookups != nullptr && lookups->size() != skeleton_indices.size()) {
      lookups->assign(skeleton_indices.size(), PatchLookup());
    }
    return true;
  }

  // The constants of Point, made once per thread and call; the buffers' data as plain pointers,
  // which the loop need not reload through their vectors after each store.
  struct Constants {
    bool use_patches, gate;
    double patch_min_cos, min_cos;
    float keep2;
    const Plane* local;
    int np;
    SkeletonMatch* per_point;
    PatchLookup* lookups;
    const PlanePatchMap::Patch** found;
  };
  Constants MakeConstants() const {
    Constants c;
    c.use_patches = use_patches();
    c.gate = normal_gate_deg > 0.0 && own_normals.size() == skeleton_indices.size();
    // Patches are chosen by their own surface orientation; the window gate's angle, or 10 degrees.
    c.patch_min_cos =
        std::cos((normal_gate_deg > 0.0 ? std::min(normal_gate_deg, 90.0) : 10.0) * M_PI / 180.0);
    c.min_cos = std::cos(std::min(normal_gate_deg, 90.0) * M_PI / 180.0);
    c.keep2 = lookups != nullptr ? keep_distance * keep_distance : 0.0f;
    c.local = local->data();
    c.np = static_cast<int>(local->size());
    c.per_point = per_point->data();
    c.lookups = lookups != nullptr ? lookups->data() : nullptr;
    c.found = found != nullptr ? found->data() : nullptr;
    return c;
  }

  void Point(const Constants& c, long i) const {
    SkeletonMatch m;
    const int idx = skeleton_indices[i];
    if (idx >= 0 && idx < static_cast<int>(points_lidar.size())) {
      const Eigen::Vector3d p = points_lidar[idx].cast<double>();
      if (c.use_patches) {
        const Eigen::Vector3d p_w = T_world_lidar * p;
        const Eigen::Vector3f q_w = p_w.cast<float>();
        PatchLookup* last = c.lookups != nullptr ? &c.lookups[i] : nullptr;
        const PlanePatchMap::Patch* patch;
        // The last lookup's patch while the point stays near where it was made (as the kNN rows
        // keep their neighbours): a later iteration moves it by millimetres in a 2 m cell.
        if (last != nullptr && last->done && (q_w - last->at).squaredNorm() < c.keep2) {
          patch = last->patch;
        } else {
          patch = patches->Find(p_w, T_world_lidar.linear() * own_normals[i], c.patch_min_cos);
          if (last != nullptr) {
            last->done = true;
            last->at = q_w;
            last->patch = patch;
          }
        }
        if (patch != nullptr) {
          if (c.found != nullptr) c.found[i] = patch;
          const double s = patch->plane.SignedDistance(p_w);
          if (std::abs(s) < eps) {
            m.point_index = idx;
            m.signed_distance = s;
            m.plane = patch->plane;
          }
          c.per_point[i] = m;
          return;  // a patch of its own surface exists: the window is not consulted
        }
        if (!window_fallback) {  // no patch of its surface here yet: no residual
          c.per_point[i] = m;
          return;
        }
      }
      double best = std::numeric_limits<double>::infinity();
      int best_plane = -1;
      for (int j = 0; j < c.np; ++j) {
        if (c.gate && std::abs(own_normals[i].dot(c.local[j].n)) < c.min_cos) continue;
        const double s = c.local[j].SignedDistance(p);
        if (std::abs(s) < std::abs(best)) {
          best = s;
          best_plane = j;
        }
      }
      if (best_plane >= 0 && std::abs(best) < eps) {
        m.point_index = idx;
        m.plane_index = best_plane;
        m.signed_distance = best;
        m.plane = window_world[best_plane];
      }
    }
    c.per_point[i] = m;
  }

  // Every point of the team's share (an orphaned worksharing loop: alone outside a team).
  void Share() const {
    const Constants c = MakeConstants();
    const long n = static_cast<long>(skeleton_indices.size());
#pragma omp for schedule(dynamic, 256) nowait
    for (long i = 0; i < n; ++i) Point(c, i);
  }

  void Collect(std::vector<SkeletonMatch>* matches) const {
    matches->clear();
    for (const SkeletonMatch& m : *per_point) {
      if (m.point_index >= 0) matches->push_back(m);
    }
  }
};

namespace {

// Each point is a hash lookup and a few dot products: a team of its own only above a few
// thousand points, where it pays for the fork/join (docs/decisions.md, "Parallel skeleton
// matching"); results are identical (each point writes its own slot).
constexpr size_t kMatchTeamAbove = 2048;

void MatchSkeleton(const std::vector<Eigen::Vector3f>& points_lidar,
                   const std::vector<int>& skeleton_indices,
                   const std::vector<Eigen::Vector3d>& own_normals, double normal_gate_deg,
                   const Eigen::Isometry3d& T_world_lidar, const std::vector<Plane>& window_world,
                   double eps, std::vector<SkeletonMatch>* matches) {
  std::vector<Plane> local;
  std::vector<SkeletonMatch> per_point;
  const SkeletonMatchLoop loop{points_lidar,  skeleton_indices, own_normals, normal_gate_deg,
                               T_world_lidar, window_world,     eps,         nullptr,
                               true,          nullptr,          0.0f,        nullptr,
                               &local,        &per_point};
  if (loop.Prepare()) {
#pragma omp parallel if (skeleton_indices.size() > kMatchTeamAbove)
    loop.Share();
  }
  loop.Collect(matches);
}

}  // namespace

void ComputeSkeletonMatches(const std::vector<Eigen::Vector3f>& points_lidar,
                            const std::vector<int>& skeleton_indices,
                            const Eigen::Isometry3d& T_world_lidar,
                            const std::vector<Plane>& window_world, double eps,
                            std::vector<SkeletonMatch>* matches) {
  MatchSkeleton(points_lidar, skeleton_indices, {}, 0.0, T_world_lidar, window_world, eps, matches);
}

void ComputeSkeletonMatches(const std::vector<Eigen::Vector3f>& points_lidar,
                            const std::vector<int>& skeleton_indices,
                            const std::vector<Eigen::Vector3d>& own_normals_lidar,
                            double normal_gate_deg, const Eigen::Isometry3d& T_world_lidar,
                            const std::vector<Plane>& window_world, double eps,
                            std::vector<SkeletonMatch>* matches) {
  MatchSkeleton(points_lidar, skeleton_indices, own_normals_lidar, normal_gate_deg, T_world_lidar,
                window_world, eps, matches);
}

SkeletonResidualProvider::SkeletonResidualProvider(const SkeletonWindow* window, double eps)
    : window_(window), eps_(eps) {}

void SkeletonResidualProvider::SetPrefitSource(const PrefitResult* prefit, double normal_gate_deg) {
  prefit_ = prefit;
  normal_gate_deg_ = normal_gate_deg;
}

void SkeletonResidualProvider::Reset() {
  frame_ = nullptr;
  planes_world_.clear();
  skeleton_indices_.clear();
  matches_.clear();
  lookups_.clear();
  found_.clear();
  team_ready_ = false;
}

void SkeletonResidualProvider::BeginScan(const ScanFrame& frame) {
  frame_ = &frame;
  planes_world_ = window_ ? window_->WorldPlanes() : std::vector<Plane>{};
  skeleton_indices_.clear();
  const size_t n = std::min(frame.labels.size(), frame.points_lidar.size());
  for (size_t i = 0; i < n; ++i) {
    if (frame.labels[i] == PointLabel::kSkeleton && frame.GivesResidual(frame.points_lidar[i])) {
      skeleton_indices_.push_back(static_cast<int>(i));
    }
  }
  matches_.clear();
  lookups_.clear();
  found_.clear();
  own_normals_.clear();
  row_weights_.clear();
  const bool need_normals = normal_gate_deg_ > 0.0 || patches_ != nullptr;
  if (prefit_ == nullptr || !(need_normals || rows_per_plane_ > 0)) return;
  // The pre-fit plane of each skeleton point; -1 where labels and pre-fit disagree (a custom
  // splitter changed the labels): then neither the gate nor the row cap is applied.
  plane_of_.assign(frame.points_lidar.size(), -1);
  for (size_t k = 0; k < prefit_->skeleton_indices.size(); ++k) {
    const int idx = prefit_->skeleton_indices[k];
    const int pl = prefit_->skeleton_plane[k];
    if (idx >= 0 && idx < static_cast<int>(plane_of_.size()) && pl >= 0 &&
        pl < static_cast<int>(prefit_->planes.size())) {
      plane_of_[idx] = pl;
    }
  }
  const bool consistent = std::all_of(skeleton_indices_.begin(), skeleton_indices_.end(),
                                      [&](int idx) { return plane_of_[idx] >= 0; });
  if (!consistent) return;
  if (rows_per_plane_ > 0) KeepRowsPerPlane();
  if (need_normals) {
    for (int idx : skeleton_indices_) {
      own_normals_.push_back(prefit_->planes[plane_of_[idx]].plane.n);
    }
  }
}

// A plane's points in scan order are spread over the whole surface the LiDAR saw; every
// (count / cap)-th of them keeps that spread, and the weight count / cap keeps the plane's
// information what its full set gave, so the balance against the IMU prediction is unchanged.
void SkeletonResidualProvider::KeepRowsPerPlane() {
  const size_t cap = static_cast<size_t>(rows_per_plane_);
  per_plane_count_.assign(prefit_->planes.size(), 0);
  for (int idx : skeleton_indices_) ++per_plane_count_[plane_of_[idx]];
  if (std::none_of(per_plane_count_.begin(), per_plane_count_.end(),
                   [&](size_t c) { return c > cap; })) {
    return;
  }
  per_plane_rank_.assign(prefit_->planes.size(), 0);
  row_weights_.assign(frame_->points_lidar.size(), 1.0);
  size_t kept = 0;
  for (int idx : skeleton_indices_) {
    const int pl = plane_of_[idx];
    const size_t c = per_plane_count_[pl];
    const size_t r = per_plane_rank_[pl]++;
    // Rank r is kept when floor(r cap / c) steps: exactly cap of the c ranks, evenly spaced.
    if (c > cap && (r * cap) / c == ((r + 1) * cap) / c) continue;
    row_weights_[idx] = c > cap ? static_cast<double>(c) / static_cast<double>(cap) : 1.0;
    skeleton_indices_[kept++] = idx;
  }
  skeleton_indices_.resize(kept);
}

SkeletonMatchLoop SkeletonResidualProvider::Loop() {
  return SkeletonMatchLoop{frame_->points_lidar,
                           skeleton_indices_,
                           own_normals_,
                           normal_gate_deg_,
                           team_T_,
                           planes_world_,
                           eps_,
                           patches_,
                           window_fallback_,
                           keep_distance_ > 0.0 ? &lookups_ : nullptr,
                           static_cast<float>(keep_distance_),
                           &found_,
                           &local_planes_,
                           &per_point_};
}

void SkeletonResidualProvider::ComputeRows(const Eigen::Isometry3d& T_world_lidar,
                                           std::vector<PointPlaneRow>* rows) {
  const TeamWork work = PrepareRows(T_world_lidar);
  if (work.points > work.team_above) {
#pragma omp parallel num_threads(work.threads)
    RowsInTeam();
  } else if (work.points > 0) {
    RowsInTeam();
  }
  FinishRows(T_world_lidar, rows);
}

ResidualProvider::TeamWork SkeletonResidualProvider::PrepareRows(
    const Eigen::Isometry3d& T_world_lidar) {
  team_ready_ = false;
  if (frame_ == nullptr) return {};
  team_ready_ = true;
  team_T_ = T_world_lidar;
  TeamWork work;
  if (Loop().Prepare()) work.points = skeleton_indices_.size();
  work.team_above = kMatchTeamAbove;
  // The configured thread count, as the other stages use: without it this loop ran on the
  // OpenMP default (all cores) even in a run configured for one thread.
#ifdef _OPENMP
  work.threads = num_threads_ > 0 ? num_threads_ : omp_get_max_threads();
#endif
  return work;
}

void SkeletonResidualProvider::RowsInTeam() {
  if (team_ready_ && !per_point_.empty()) Loop().Share();
}

void SkeletonResidualProvider::FinishRows(const Eigen::Isometry3d& /*T_world_lidar*/,
                                          std::vector<PointPlaneRow>* rows) {
  if (!team_ready_) return;
  team_ready_ = false;
  Loop().Collect(&matches_);
  rows->reserve(rows->size() + matches_.size());
  for (const SkeletonMatch& m : matches_) {
    PointPlaneRow row;
    row.point_lidar = frame_->points_lidar[m.point_index].cast<double>();
    row.normal_world = m.plane.n;
    row.offset = m.plane.d;
    if (!row_weights_.empty()) row.weight = row_weights_[m.point_index];
    rows->push_back(row);
  }
}

bool SkeletonResidualProvider::AppendAssociations(std::vector<AssociatedPoint>* out) const {
  if (frame_ == nullptr || patches_ == nullptr || found_.size() != skeleton_indices_.size()) {
    return false;
  }
  out->reserve(out->size() + found_.size());
  for (size_t j = 0; j < found_.size(); ++j) {
    AssociatedPoint a;
    a.point_lidar = frame_->points_lidar[static_cast<size_t>(skeleton_indices_[j])];
    if (const PlanePatchMap::Patch* patch = found_[j]) {
      a.covered = true;
      a.has_plane = true;
      a.normal = patch->plane.n;
      a.d = patch->plane.d;
    }
    out->push_back(a);
  }
  return true;
}

}  // namespace ppf
