#include "ppf_core/ppf/skeleton_window.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>
#include <vector>

namespace ppf {

// `config` was validated once, by the facade (ValidateConfig in config.cpp).
SkeletonWindow::SkeletonWindow(const PpfConfig& config) : config_(config) {}

void SkeletonWindow::Clear() {
  planes_.clear();  // ids keep increasing: an id is never reused for another plane
}

std::vector<PlaneGuess> SkeletonWindow::GuessesInFrame(
    const Eigen::Isometry3d& T_world_lidar) const {
  const Eigen::Isometry3d T_lidar_world = T_world_lidar.inverse();
  std::vector<PlaneGuess> guesses;
  guesses.reserve(planes_.size());
  for (const SkeletonPlane& sp : planes_) {
    guesses.push_back(PlaneGuess{TransformPlane(T_lidar_world, sp.plane), sp.track_id});
  }
  return guesses;
}

std::vector<Plane> SkeletonWindow::WorldPlanes() const {
  std::vector<Plane> out;
  out.reserve(planes_.size());
  for (const SkeletonPlane& sp : planes_) out.push_back(sp.plane);
  return out;
}

namespace {

// The fitted planes and their inlier moments (centroid, scatter) in the world frame. New tracks
// face the sensor (sensor origin on the positive side): a convention users can rely on, and it
// makes the orientation independent of RANSAC's sample order.
void FittedInWorld(const std::vector<FittedPlane>& fitted, const Eigen::Isometry3d& T_world_lidar,
                   std::vector<Plane>* world, std::vector<PlaneMoments>* moments) {
  const size_t nf = fitted.size();
  world->resize(nf);
  moments->resize(nf);
  for (size_t i = 0; i < nf; ++i) {
    Plane pl = fitted[i].plane;
    if (pl.d < 0.0) pl = pl.Flipped();
    (*world)[i] = TransformPlane(T_world_lidar, pl);
    PlaneMoments m;
    m.count = fitted[i].num_inliers;
    m.centroid = fitted[i].centroid;
    m.scatter = fitted[i].scatter;
    (*moments)[i] = m.Transformed(T_world_lidar);
  }
}

// 1. Accepted guesses continue the track they were guessed from.
void ContinueGuessedTracks(const std::vector<FittedPlane>& fitted,
                           const std::vector<SkeletonPlane>& tracks, std::vector<int>* track_of,
                           std::vector<bool>* claimed) {
  for (size_t i = 0; i < fitted.size(); ++i) {
    if (!fitted[i].from_guess) continue;
    for (size_t j = 0; j < tracks.size(); ++j) {
      if (!(*claimed)[j] && tracks[j].track_id == fitted[i].guess_track_id) {
        (*claimed)[j] = true;
        (*track_of)[i] = static_cast<int>(j);
        break;
      }
    }
  }
}

// 2. Geometric association for the rest: greedy on a normalised angle + offset cost, which is
// enough for <= 5 planes per scan (an optimal assignment would not change realistic outcomes).
void AssociateByGeometry(const PpfConfig& config, const std::vector<Plane>& world,
                         const std::vector<PlaneMoments>& moments,
                         const std::vector<SkeletonPlane>& tracks, std::vector<int>* track_of,
                         std::vector<bool>* claimed) {
  const double max_angle = config.track_max_angle_deg * M_PI / 180.0;
  const double max_offset = config.track_max_offset;
  std::vector<std::tuple<double, int, int>> candidates;  // cost, fitted, track
  for (size_t i = 0; i < world.size(); ++i) {
    if ((*track_of)[i] >= 0) continue;
    for (size_t j = 0; j < tracks.size(); ++j) {
      if ((*claimed)[j]) continue;
      const double angle = PlaneAngle(world[i], tracks[j].plane);
      const double offset = tracks[j].plane.Distance(moments[i].centroid);
      if (angle > max_angle || offset > max_offset) continue;
      const double cost =
          (max_angle > 0 ? angle / max_angle : 0.0) + (max_offset > 0 ? offset / max_offset : 0.0);
      candidates.emplace_back(cost, static_cast<int>(i), static_cast<int>(j));
    }
  }
  std::sort(candidates.begin(), candidates.end());
  for (const auto& [cost, i, j] : candidates) {
    (void)cost;
    if ((*track_of)[i] >= 0 || (*claimed)[j]) continue;
    (*track_of)[i] = j;
    (*claimed)[j] = true;
  }
}

}  // namespace

std::vector<int64_t> SkeletonWindow::Update(const std::vector<FittedPlane>& fitted,
                                            const Eigen::Isometry3d& T_world_lidar) {
  const size_t nf = fitted.size();
  std::vector<Plane> world;
  std::vector<PlaneMoments> moments;
  FittedInWorld(fitted, T_world_lidar, &world, &moments);
  std::vector<int> track_of(nf, -1);  // fitted -> index in planes_
  std::vector<bool> claimed(planes_.size(), false);
  ContinueGuessedTracks(fitted, planes_, &track_of, &claimed);
  AssociateByGeometry(config_, world, moments, planes_, &track_of, &claimed);

  // 3. Apply: continue matched tracks, age the rest, start new tracks.
  std::vector<int64_t> ids(nf, -1);
  std::vector<SkeletonPlane> next;
  next.reserve(planes_.size() + nf);
  for (size_t j = 0; j < planes_.size(); ++j) {
    SkeletonPlane sp = planes_[j];
    ++sp.age;
    sp.incremental = false;
    if (!claimed[j]) {
      ++sp.missed_scans;
      if (sp.missed_scans <= config_.window_max_missed_scans) next.push_back(sp);
      continue;
    }
    next.push_back(sp);  // updated below once we know which fitted plane claimed it
  }
  for (size_t i = 0; i < nf; ++i) {
    if (track_of[i] >= 0) {
      const int64_t id = planes_[track_of[i]].track_id;
      for (SkeletonPlane& sp : next) {
        if (sp.track_id != id) continue;
        Plane pl = world[i];
        if (pl.n.dot(sp.plane.n) < 0.0) pl = pl.Flipped();  // keep the track's orientation
        sp.plane = pl;
        sp.centroid = moments[i].centroid;
        sp.scatter = moments[i].scatter;
        sp.incremental = fitted[i].from_guess;
        sp.num_inliers = fitted[i].num_inliers;
        ++sp.hits;
        sp.missed_scans = 0;
        break;
      }
      ids[i] = id;
    } else {
      SkeletonPlane sp;
      sp.track_id = next_track_id_++;
      sp.plane = world[i];
      sp.centroid = moments[i].centroid;
      sp.scatter = moments[i].scatter;
      sp.num_inliers = fitted[i].num_inliers;
      sp.hits = 1;
      next.push_back(sp);
      ids[i] = sp.track_id;
    }
  }

  // Guess order: fresh first, then larger (more support), ties by id for determinism.
  std::stable_sort(next.begin(), next.end(), [](const SkeletonPlane& a, const SkeletonPlane& b) {
    if (a.missed_scans != b.missed_scans) return a.missed_scans < b.missed_scans;
    if (a.num_inliers != b.num_inliers) return a.num_inliers > b.num_inliers;
    return a.track_id < b.track_id;
  });
  if (static_cast<int>(next.size()) > config_.window_size) next.resize(config_.window_size);
  planes_.swap(next);
  return ids;
}

}  // namespace ppf
