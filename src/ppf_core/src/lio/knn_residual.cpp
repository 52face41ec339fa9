#include "ppf_core/lio/knn_residual.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ppf {

bool FitPlane(const std::vector<Eigen::Vector3f>& pts, double threshold, Eigen::Vector3d* n,
              double* d, double min_spread) {
  if (pts.size() < 3) return false;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : pts) c += p.cast<double>();
  c /= static_cast<double>(pts.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : pts) {
    const Eigen::Vector3d q = p.cast<double>() - c;
    cov += q * q.transpose();
  }
  // The closed-form 3x3 solution, a third of the iterative solver's work on every kNN row: the
  // points are centred, and where a plane is accepted its normal's eigenvalue lies far below the
  // other two, the case the closed form resolves to rounding; the collinear test below compares
  // with a margin far above its error.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  // Collinear neighbours (a single scan line) span no plane: the middle eigenvalue vanishes.
  if (es.eigenvalues()(1) < 1e-6 * std::max(1e-12, es.eigenvalues()(2))) return false;
  if (es.eigenvalues()(1) < min_spread * min_spread * static_cast<double>(pts.size())) return false;
  *n = es.eigenvectors().col(0).normalized();
  *d = -n->dot(c);
  for (const auto& p : pts) {
    if (std::abs(n->dot(p.cast<double>()) + *d) > threshold) return false;
  }
  return true;
}

void KnnResidualProvider::BeginScan(const ScanFrame& frame) {
  frame_ = &frame;
  indices_.clear();
  for (size_t i = 0; i < frame.points_lidar.size(); ++i) {
    if ((i >= frame.labels.size() || frame.labels[i] == PointLabel::kScattered) &&
        frame.GivesResidual(frame.points_lidar[i])) {
      indices_.push_back(i);
    }
  }
  fits_.assign(indices_.size(), CachedFit());
  // The searches Prefetch made on this frame (at most once: the map changes after the scan).
  prefetched_ = prefetched_scattered_ = 0;
  if (prefetch_frame_ == &frame && prefetch_.size() == frame.points_lidar.size()) {
    for (const CachedFit& f : prefetch_) prefetched_ += f.searched ? 1 : 0;
    if (fits_.size() == indices_.size()) {
      for (size_t j = 0; j < indices_.size(); ++j) {
        const CachedFit& f = prefetch_[indices_[j]];
        if (!f.searched) continue;
        fits_[j] = f;
        ++prefetched_scattered_;
      }
    }
  }
  prefetch_frame_ = nullptr;
}

void KnnResidualProvider::SearchAndFit(const VoxelMap& map, const Eigen::Vector3f& q_w, size_t k,
                                       std::vector<Eigen::Vector3f>* nn, CachedFit* fit) const {
  const bool found = map.GetClosest(q_w, k, options_.max_neighbor_distance, nn) >= k;
  fit->searched = true;
  fit->found = found;
  fit->searched_at = q_w;
  if (!found) return;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double d = 0.0;
  fit->ok = FitPlane(*nn, options_.plane_threshold, &normal, &d, options_.min_plane_spread);
  std::copy(nn->begin(), nn->end(), fit->nn);
  fit->count = nn->size();
  fit->normal = normal;
  fit->d = d;
}

const std::vector<size_t>& KnnResidualProvider::PrefetchOrder(
    const ScanFrame& frame, const std::vector<Plane>& likely_planes, double band) {
  order_.clear();
  order_.reserve(frame.points_lidar.size());
  later_.clear();
  const float fband = static_cast<float>(band);
  for (size_t i = 0; i < frame.points_lidar.size(); ++i) {
    const Eigen::Vector3f& p = frame.points_lidar[i];
    if (!frame.GivesResidual(p)) continue;
    bool near = false;
    for (const Plane& pl : likely_planes) {
      const float dist = static_cast<float>(pl.n.x()) * p.x() +
                         static_cast<float>(pl.n.y()) * p.y() +
                         static_cast<float>(pl.n.z()) * p.z() + static_cast<float>(pl.d);
      if (std::abs(dist) < fband) {
        near = true;
        break;
      }
    }
    (near ? later_ : order_).push_back(i);
  }
  order_.insert(order_.end(), later_.begin(), later_.end());
  return order_;
}

void KnnResidualProvider::Prefetch(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
                                   const std::vector<Plane>& likely_planes, double band,
                                   const std::atomic<bool>& stop) {
  prefetch_frame_ = nullptr;
  const size_t k = static_cast<size_t>(std::max(3, options_.k));
  if (frame.map == nullptr || frame.map->size() == 0 || k > kMaxCachedK) return;
  prefetch_.assign(frame.points_lidar.size(), CachedFit());
  PrefetchOrder(frame, likely_planes, band);
  std::vector<Eigen::Vector3f> nn;
  for (size_t i : order_) {
    if (stop.load(std::memory_order_acquire)) break;
    // The query exactly as ComputeRows forms it.
    const Eigen::Vector3d p_w = T_world_lidar * frame.points_lidar[i].cast<double>();
    SearchAndFit(*frame.map, p_w.cast<float>(), k, &nn, &prefetch_[i]);
  }
  prefetch_frame_ = &frame;
}

void KnnResidualProvider::ComputeRows(const Eigen::Isometry3d& T_world_lidar,
                                      std::vector<PointPlaneRow>* rows) {
  const TeamWork work = PrepareRows(T_world_lidar);
  if (work.points > work.team_above) {
#pragma omp parallel num_threads(work.threads)
    RowsInTeam();
  }
  FinishRows(T_world_lidar, rows);
}

ResidualProvider::TeamWork KnnResidualProvider::PrepareRows(
    const Eigen::Isometry3d& T_world_lidar) {
  team_ready_ = false;
  if (frame_ == nullptr || frame_->map == nullptr || frame_->map->size() == 0) return {};
  team_ready_ = true;
  team_T_ = T_world_lidar;
  tmp_.resize(indices_.size());
  ok_.assign(indices_.size(), 0);
  TeamWork work;
  work.points = indices_.size();
#ifdef _OPENMP
  work.threads = options_.num_threads > 0 ? options_.num_threads : omp_get_max_threads();
#endif
  return work;
}

void KnnResidualProvider::RowsInTeam() {
  if (!team_ready_) return;
  const VoxelMap& map = *frame_->map;
  const Eigen::Isometry3d& T_world_lidar = team_T_;
  const long n = static_cast<long>(indices_.size());
  std::vector<PointPlaneRow>& tmp = tmp_;
  std::vector<char>& ok = ok_;
  const size_t k = static_cast<size_t>(std::max(3, options_.k));
  const bool cache = k <= kMaxCachedK && fits_.size() == indices_.size();
  const float keep2 =
      static_cast<float>(options_.search_again_distance * options_.search_again_distance);
  const bool keep = cache && keep_neighbours_ && options_.search_again_distance > 0.0;
  std::vector<Eigen::Vector3f> nn;
#pragma omp for schedule(dynamic, 256) nowait
  for (long j = 0; j < n; ++j) {
    const Eigen::Vector3d p_l =
        frame_->points_lidar[indices_[static_cast<size_t>(j)]].cast<double>();
    const Eigen::Vector3d p_w = T_world_lidar * p_l;
    const Eigen::Vector3f q_w = p_w.cast<float>();
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    double d = 0.0;
    CachedFit* fit = cache ? &fits_[static_cast<size_t>(j)] : nullptr;
    // The last search's neighbours while the point stays near where it was made: a later
    // iteration moves most points by far less than the map's point spacing.
    if (keep && fit->searched && (q_w - fit->searched_at).squaredNorm() < keep2) {
      if (!fit->found || !fit->ok) continue;
      normal = fit->normal;
      d = fit->d;
    } else if (fit != nullptr && fit->searched && fit->searched_at == q_w) {
      // Searched at this very point already (Prefetch, or an iteration that did not move):
      // the search would find the same neighbours, the fit the same plane.
      if (!fit->found || !fit->ok) continue;
      normal = fit->normal;
      d = fit->d;
    } else {
      const bool found = map.GetClosest(q_w, k, options_.max_neighbor_distance, &nn) >= k;
      if (fit != nullptr) {
        fit->searched = true;
        fit->found = found;
        fit->searched_at = q_w;
      }
      if (!found) continue;
      if (fit != nullptr && fit->count == nn.size() && std::equal(nn.begin(), nn.end(), fit->nn)) {
        if (!fit->ok) continue;
        normal = fit->normal;
        d = fit->d;
      } else {
        const bool ok_fit =
            FitPlane(nn, options_.plane_threshold, &normal, &d, options_.min_plane_spread);
        if (fit != nullptr) {
          std::copy(nn.begin(), nn.end(), fit->nn);
          fit->count = nn.size();
          fit->ok = ok_fit;
          fit->normal = normal;
          fit->d = d;
        }
        if (!ok_fit) continue;
      }
    }
    const double r = normal.dot(p_w) + d;
    if (!(std::abs(r) < options_.max_residual)) continue;
    PointPlaneRow& row = tmp[static_cast<size_t>(j)];
    row.point_lidar = p_l;
    row.normal_world = normal;
    row.offset = d;
    row.weight = 1.0;
    ok[static_cast<size_t>(j)] = 1;
  }
}

void KnnResidualProvider::FinishRows(const Eigen::Isometry3d& /*T_world_lidar*/,
                                     std::vector<PointPlaneRow>* rows) {
  if (!team_ready_) return;
  team_ready_ = false;
  for (size_t j = 0; j < tmp_.size(); ++j) {
    if (ok_[j]) rows->push_back(tmp_[j]);
  }
}

bool KnnResidualProvider::Associations(std::vector<AssociatedPoint>* out) const {
  out->clear();
  if (frame_ == nullptr || fits_.size() != indices_.size()) return false;
  if (static_cast<size_t>(std::max(3, options_.k)) > kMaxCachedK) return false;
  out->reserve(indices_.size());
  for (size_t j = 0; j < indices_.size(); ++j) {
    const CachedFit& fit = fits_[j];
    if (!fit.searched) return false;  // no search since BeginScan
    AssociatedPoint a;
    a.point_lidar = frame_->points_lidar[indices_[j]];
    a.covered = fit.found;
    // A plane is cached only for the neighbours it was fitted to, which a search that found
    // fewer than k did not replace: it counts only when this search found k.
    a.has_plane = fit.found && fit.ok;
    a.normal = fit.normal;
    a.d = fit.d;
    out->push_back(a);
  }
  return true;
}

}  // namespace ppf
