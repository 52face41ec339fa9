#include <map>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "ppf_core/ppf/plane_prefitter.hpp"
#include "ppf_core/ppf/skeleton_window.hpp"
#include "ppf_test_scenes.hpp"

namespace ppf {
namespace {

Eigen::Isometry3d Pose(double yaw, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// World-frame index of the true plane a fitted world plane corresponds to, -1 if none.
int TruthOf(const Plane& world, const std::vector<Plane>& truth) {
  for (size_t k = 0; k < truth.size(); ++k) {
    if (test::NormalErrorDeg(world, truth[k]) < 2.0 && test::OffsetError(world, truth[k]) < 0.1) {
      return static_cast<int>(k);
    }
  }
  return -1;
}

// Drives prefitter + window over a moving sensor in a static corner scene; checks that every
// physical plane keeps one track id for the whole run.
void RunTrackingScenario(bool incremental) {
  PpfConfig cfg;
  cfg.plane_least_inliers = 150;
  cfg.incremental_fitting = incremental;
  cfg.min_remaining_ratio = 0.05;
  PlanePrefitter prefitter(cfg);
  SkeletonWindow window(cfg);
  std::map<int, int64_t> id_of_truth;  // true plane -> track id
  std::map<int64_t, int> first_scan_of;
  int accepted_guesses = 0;
  for (int scan = 0; scan < 8; ++scan) {
    const Eigen::Isometry3d T_world_lidar =
        Pose(0.03 * scan, Eigen::Vector3d(0.8 * scan, 0.1 * scan, 0.0));
    const test::CornerScene world_scene = test::MakeCornerScene(0.02, 500, 100 + scan);
    std::vector<Eigen::Vector3f> pts;
    for (const auto& p : world_scene.points) {
      pts.push_back((T_world_lidar.inverse() * p.cast<double>()).cast<float>());
    }
    // IMU prediction: a few cm and 0.3 degrees off.
    const Eigen::Isometry3d T_pred = T_world_lidar * Pose(0.005, Eigen::Vector3d(0.03, -0.02, 0));
    PrefitResult r;
    prefitter.Fit(pts, window.GuessesInFrame(T_pred), &r);
    accepted_guesses += r.guesses_accepted;
    const std::vector<int64_t> ids = window.Update(r.planes, T_world_lidar);
    ASSERT_EQ(ids.size(), r.planes.size());
    for (size_t i = 0; i < r.planes.size(); ++i) {
      const int truth =
          TruthOf(TransformPlane(T_world_lidar, r.planes[i].plane), world_scene.planes);
      ASSERT_GE(truth, 0);
      auto it = id_of_truth.find(truth);
      if (it == id_of_truth.end()) {
        id_of_truth[truth] = ids[i];
        first_scan_of[ids[i]] = scan;
      } else {
        EXPECT_EQ(it->second, ids[i]) << "plane " << truth << " changed id at scan " << scan;
      }
    }
    // Ages count scans since creation; hits count fits (every scan here).
    for (const SkeletonPlane& sp : window.planes()) {
      ASSERT_TRUE(first_scan_of.count(sp.track_id));
      EXPECT_EQ(sp.age, scan - first_scan_of[sp.track_id]);
      EXPECT_EQ(sp.hits, sp.age + 1);
      EXPECT_EQ(sp.missed_scans, 0);
      // Published with the plane: was this scan's fit the track's own guess?
      EXPECT_EQ(sp.incremental, incremental && scan > 0) << "track " << sp.track_id;
      // The inlier scatter is in the world frame: its flattest direction is the world normal.
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(sp.scatter);
      EXPECT_GT(std::abs(es.eigenvectors().col(0).dot(sp.plane.n)), std::cos(2.0 * M_PI / 180.0));
      EXPECT_GT(es.eigenvalues()(1), 100.0 * es.eigenvalues()(0)) << "a plane, not a blob";
    }
  }
  EXPECT_EQ(id_of_truth.size(), 3u);
  if (incremental) {
    EXPECT_GE(accepted_guesses, 7 * 3);  // after scan 0, every plane via its guess
  }
}

TEST(PpfWindow, TrackIdsStableAcrossScansWithIncrementalFitting) { RunTrackingScenario(true); }
TEST(PpfWindow, TrackIdsStableAcrossScansWithRansacOnly) { RunTrackingScenario(false); }

TEST(PpfWindow, WindowPlanesTransformCorrectlyBetweenFrames) {
  PpfConfig cfg;
  SkeletonWindow window(cfg);
  const Eigen::Isometry3d T_world_lidar =
      Pose(0.9, Eigen::Vector3d(5, -2, 0.3)) *
      Eigen::Isometry3d(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()));
  FittedPlane f;
  f.plane = *Plane::FromCoefficients(Eigen::Vector4d(0.2, 0.1, 1.0, 1.7));
  f.centroid = -f.plane.d * f.plane.n + Eigen::Vector3d(0.1, 0.2, 0).cross(f.plane.n);
  f.num_inliers = 500;
  window.Update({f}, T_world_lidar);
  ASSERT_EQ(window.planes().size(), 1u);
  const Plane& w = window.planes()[0].plane;
  // A point on the LiDAR-frame plane lands on the world plane.
  EXPECT_NEAR(w.SignedDistance(T_world_lidar * f.centroid), 0.0, 1e-9);
  EXPECT_NEAR(window.planes()[0].centroid.x(), (T_world_lidar * f.centroid).x(), 1e-9);
  // Guessing in the same frame returns the original plane (Theorem 1 round trip).
  const auto g = window.GuessesInFrame(T_world_lidar);
  ASSERT_EQ(g.size(), 1u);
  EXPECT_LT((g[0].plane.Coefficients() - f.plane.Coefficients()).norm(), 1e-12);
  EXPECT_EQ(g[0].track_id, window.planes()[0].track_id);
  // In another frame: points of the world plane map onto the guess.
  const Eigen::Isometry3d T_world_other = Pose(-0.4, Eigen::Vector3d(1, 1, 1));
  const auto g2 = window.GuessesInFrame(T_world_other);
  const Eigen::Vector3d p_world = T_world_lidar * f.centroid;
  EXPECT_NEAR(g2[0].plane.SignedDistance(T_world_other.inverse() * p_world), 0.0, 1e-9);
  EXPECT_NEAR(g2[0].plane.n.norm(), 1.0, 1e-12);
}

TEST(PpfWindow, NewTracksFaceTheSensorAndKeepOrientation) {
  SkeletonWindow window(PpfConfig{});
  FittedPlane f;
  f.plane = Plane{Eigen::Vector3d::UnitZ(), -2.0};  // z = 2 seen from below, normal away
  f.centroid = Eigen::Vector3d(0, 0, 2);
  window.Update({f}, Eigen::Isometry3d::Identity());
  EXPECT_GT(window.planes()[0].plane.d, 0.0);  // flipped: sensor on the positive side
  const int64_t id = window.planes()[0].track_id;
  f.plane = Plane{Eigen::Vector3d::UnitZ(), -2.01};
  window.Update({f}, Eigen::Isometry3d::Identity());
  ASSERT_EQ(window.planes().size(), 1u);
  EXPECT_EQ(window.planes()[0].track_id, id);
  EXPECT_LT(window.planes()[0].plane.n.z(), 0.0);
}

TEST(PpfWindow, UnseenTracksAgeOutAndSizeIsBounded) {
  PpfConfig cfg;
  cfg.window_size = 3;
  cfg.window_max_missed_scans = 1;
  SkeletonWindow window(cfg);
  std::vector<FittedPlane> fitted;
  for (int i = 0; i < 5; ++i) {
    FittedPlane f;
    f.plane = Plane{Eigen::Vector3d::UnitX(), -2.0 * (i + 1)};  // parallel walls 2 m apart
    f.centroid = Eigen::Vector3d(2.0 * (i + 1), 0, 0);
    f.num_inliers = 100 * (i + 1);
    fitted.push_back(f);
  }
  const auto ids = window.Update(fitted, Eigen::Isometry3d::Identity());
  EXPECT_EQ(ids.size(), 5u);
  ASSERT_EQ(window.planes().size(), 3u);  // the 3 largest
  EXPECT_EQ(window.planes()[0].num_inliers, 500);
  window.Update({}, Eigen::Isometry3d::Identity());
  EXPECT_EQ(window.planes().size(), 3u);  // missed once: kept
  EXPECT_EQ(window.planes()[0].missed_scans, 1);
  window.Update({}, Eigen::Isometry3d::Identity());
  EXPECT_TRUE(window.empty());  // missed twice: gone
  // Ids are never reused.
  const auto ids2 = window.Update({fitted[0]}, Eigen::Isometry3d::Identity());
  EXPECT_GT(ids2[0], ids[4]);
}

}  // namespace
}  // namespace ppf
