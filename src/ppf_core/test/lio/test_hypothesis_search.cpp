// The coarse alignment from several motion guesses (hypothesis_search.hpp): a turn the model
// missed is recovered, and a guess that fits ends the search; the scan alone measures the velocity
// it was taken at; in kPpf the probes also meet the skeleton's patches. The facade's LiDAR-only
// runs are in test_end_to_end (synthetic room) and ppf_tools' test_lidar_only_real / test_accuracy.
// The consistency check's memory of the recent scores (fit_baseline.hpp) is at the end.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "ppf_core/config.hpp"
#include "ppf_core/lio/fit_baseline.hpp"
#include "ppf_core/lio/hypothesis_search.hpp"
#include "ppf_core/lio/so3.hpp"
#include "ppf_core/lio/voxel_map.hpp"
#include "ppf_core/ppf/plane_patch_map.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

using test::Deg;
using test::Pose;

struct RoomFixture {
  test::Scene scene = test::MakeRoomScene();
  test::LidarModel lidar;
  VoxelMap map{VoxelMapOptions()};
  ScanFrame frame;

  RoomFixture() { lidar.rings = 32; }

  std::vector<Eigen::Vector3f> Scan(const Eigen::Isometry3d& T_world_lidar) const {
    const test::PoseFn pose = [&](double) { return T_world_lidar; };
    std::vector<Eigen::Vector3f> out;
    for (const auto& sp :
         test::SimulateScan(scene, pose, Eigen::Isometry3d::Identity(), 0.0, lidar)) {
      out.push_back(sp.p);
    }
    return out;
  }
  // The map from a scan at the origin; frame = a scan at T_world_lidar, thinned like a 0.5 m grid.
  void Build(const Eigen::Isometry3d& T_world_lidar) {
    for (const Eigen::Vector3f& p : Scan(Eigen::Isometry3d::Identity())) map.Insert(p);
    const std::vector<Eigen::Vector3f> pts = Scan(T_world_lidar);
    for (size_t i = 0; i < pts.size(); i += 4) frame.points_lidar.push_back(pts[i]);
    frame.labels.assign(frame.points_lidar.size(), PointLabel::kScattered);
    frame.map = &map;
  }
};

// The sensor turned 30 degrees more than the model said: aligned from the model's guess alone,
// registration stays far off (the turn exceeds the kNN reach); with the turned guesses it finds
// the true pose, and the fit tells the two apart.
TEST(AlignHypotheses, RecoversATurnTheModelMissed) {
  RoomFixture f;
  const Eigen::Isometry3d truth =
      Pose(Eigen::Vector3d(0.3, -0.2, 0.05), Eigen::Vector3d(0, 0, 0.52));
  f.Build(truth);
  const Eigen::Isometry3d model =
      Pose(Eigen::Vector3d(0.3, -0.2, 0.05), Eigen::Vector3d(0, 0, 0.0));
  LidarOnlyOptions options;
  const IekfOptions iekf;
  const KnnOptions knn;

  const CoarseAlignment alone = AlignHypotheses(f.frame, {{"model", model}}, options, iekf, knn);
  EXPECT_EQ(alone.tried, 1);
  EXPECT_GT(Deg(alone.T_world_lidar.linear().transpose() * truth.linear()), 5.0);
  EXPECT_LT(alone.fit, options.min_fit);

  std::vector<MotionHypothesis> guesses = {{"model", model}};
  for (double deg : {15.0, -15.0, 30.0, -30.0}) {
    Eigen::Isometry3d turned = model;
    turned.linear() = model.linear() * SO3Exp(Eigen::Vector3d(0, 0, deg * M_PI / 180.0));
    guesses.push_back({"turn " + std::to_string(static_cast<int>(deg)), turned});
  }
  const CoarseAlignment c = AlignHypotheses(f.frame, guesses, options, iekf, knn);
  EXPECT_LT(Deg(c.T_world_lidar.linear().transpose() * truth.linear()), 0.2) << c.name;
  EXPECT_LT((c.T_world_lidar.translation() - truth.translation()).norm(), 0.02) << c.name;
  EXPECT_GE(c.fit, options.good_fit) << c.name;
  EXPECT_GT(c.tried, 1);
}

// A guess that already fits ends the search: the others cost nothing.
TEST(AlignHypotheses, AGoodFirstGuessEndsTheSearch) {
  RoomFixture f;
  const Eigen::Isometry3d truth = Pose(Eigen::Vector3d(0.4, 0.1, 0.0), Eigen::Vector3d(0, 0, 0.1));
  f.Build(truth);
  const Eigen::Isometry3d near =
      Pose(Eigen::Vector3d(0.35, 0.12, 0.0), Eigen::Vector3d(0, 0, 0.08));
  const CoarseAlignment c =
      AlignHypotheses(f.frame, {{"model", near}, {"no motion", Eigen::Isometry3d::Identity()}},
                      LidarOnlyOptions(), IekfOptions(), KnnOptions());
  EXPECT_EQ(c.tried, 1);
  EXPECT_EQ(c.name, "model");
  EXPECT_LT((c.T_world_lidar.translation() - truth.translation()).norm(), 0.02);
}

// A scan taken at 6 m/s but de-skewed as if at 2 m/s (a re-localization after a gap in which the
// vehicle sped up): the walls it saw early are smeared against the late ones by 0.4 m. The scan
// alone measures its velocity with its pose; the vertical one, fixed, takes no step.
TEST(ProbePoseAndVelocity, MeasuresTheSpeedTheScanWasTakenAt) {
  RoomFixture f;
  for (const Eigen::Vector3f& p : f.Scan(Eigen::Isometry3d::Identity())) f.map.Insert(p);
  const Eigen::Vector3d v_true(6.0, 1.0, 0.0), v_model(2.0, 0.0, 0.3);
  const Eigen::Vector3d c_end(1.0, 0.5, 0.0);
  const double t_end = 0.1;
  const test::PoseFn pose = [&](double t) {
    return Pose(c_end + v_true * (t - t_end), Eigen::Vector3d::Zero());
  };
  std::vector<float> dt;
  const auto pts = test::SimulateScan(f.scene, pose, Eigen::Isometry3d::Identity(), 0.0, f.lidar);
  for (size_t i = 0; i < pts.size(); i += 4) {
    const float d = static_cast<float>(pts[i].t - t_end);
    // De-skewed to the scan end with the model's velocity (no rotation).
    f.frame.points_lidar.push_back(pts[i].p + d * v_model.cast<float>());
    dt.push_back(d);
  }
  f.frame.labels.assign(f.frame.points_lidar.size(), PointLabel::kScattered);
  f.frame.map = &f.map;

  Eigen::Isometry3d T = Pose(c_end + Eigen::Vector3d(0.1, -0.1, 0.05), Eigen::Vector3d(0, 0, 0.02));
  Eigen::Vector3d v = v_model;
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  for (int k = 0; k < 8; ++k) {
    const PoseProbe p = ProbePoseAndVelocity(f.frame, dt, up, T, LidarOnlyOptions(), KnnOptions(),
                                             IekfOptions(), 1.0);
    ASSERT_GT(p.rows, 100u);
    EXPECT_EQ(p.step_vel.z(), 0.0);
    T.linear() = SO3Exp(p.step_rot) * T.linear();
    T.translation() += p.step_pos;
    v += p.step_vel;
    const Eigen::Vector3f shift = (T.linear().transpose() * p.step_vel).cast<float>();
    for (size_t i = 0; i < dt.size(); ++i) f.frame.points_lidar[i] += dt[i] * shift;
  }
  EXPECT_LT((v - v_true).head<2>().norm(), 0.3) << v.transpose();
  EXPECT_EQ(v.z(), v_model.z());
  EXPECT_LT((T.translation() - c_end).norm(), 0.03) << T.translation().transpose();
  EXPECT_LT(Deg(T.linear()), 0.2);
  // The pose-only probe leaves the smear: its fit stays below the one with the velocity.
  f.frame.points_lidar.clear();
  for (size_t i = 0, j = 0; i < pts.size(); i += 4, ++j) {
    f.frame.points_lidar.push_back(pts[i].p + dt[j] * v_model.cast<float>());
  }
  const PoseProbe smeared = ProbePose(f.frame, T, LidarOnlyOptions(), KnnOptions(), IekfOptions(), 0.0);
  for (size_t i = 0, j = 0; i < pts.size(); i += 4, ++j) {
    f.frame.points_lidar[j] = pts[i].p + dt[j] * v.cast<float>();
  }
  const PoseProbe sharp = ProbePose(f.frame, T, LidarOnlyOptions(), KnnOptions(), IekfOptions(), 0.0);
  EXPECT_GT(sharp.score.fit, smeared.score.fit + 0.1)
      << sharp.score.fit << " vs " << smeared.score.fit;
}

// kPpf's kNN map holds the scattered points only: here the room's vertical faces, while its
// floor and ceiling are skeleton patches. A scan 0.1 m too high: on the kNN map alone nothing pins
// the height and the probe leaves it; with the patches (ScanFrame::patches) the step takes it
// back, and the points on them count in the fit.
TEST(ProbePose, PointsTheKnnMapLacksMeetTheSkeletonPatches) {
  RoomFixture f;
  PlanePatchMap patches;
  auto horizontal = [](float z) {
    for (float h : {-2.0f, 4.0f, 1.0f, 0.5f, 2.0f}) {
      if (std::abs(z - h) < 0.05f) return true;
    }
    return false;
  };
  for (const Eigen::Vector3f& p : f.Scan(Eigen::Isometry3d::Identity())) {
    if (!horizontal(p.z())) {
      f.map.Insert(p);
    } else if (std::abs(p.z() + 2.0f) < 0.05f || std::abs(p.z() - 4.0f) < 0.05f) {
      patches.Insert(p.cast<double>(), Eigen::Vector3d::UnitZ());
    }
  }
  patches.FinishInsert();
  ASSERT_GT(patches.num_patches(), 10u);
  const Eigen::Isometry3d truth = Pose(Eigen::Vector3d(0.5, 0.3, 0.0), Eigen::Vector3d(0, 0, 0.1));
  for (const Eigen::Vector3f& p : f.Scan(truth)) f.frame.points_lidar.push_back(p);
  f.frame.labels.assign(f.frame.points_lidar.size(), PointLabel::kScattered);
  f.frame.map = &f.map;
  Eigen::Isometry3d high = truth;
  high.translation().z() += 0.1;

  // Neighbours along one scan line fit no plane (their normal could point anywhere about it).
  KnnOptions knn;
  knn.min_plane_spread = 0.1;
  const PoseProbe alone = ProbePose(f.frame, high, LidarOnlyOptions(), knn, IekfOptions(), 1.0);
  f.frame.patches = &patches;
  const PoseProbe both = ProbePose(f.frame, high, LidarOnlyOptions(), knn, IekfOptions(), 1.0);
  EXPECT_LT(std::abs(alone.step_pos.z()), 0.01) << alone.step_pos.transpose();
  EXPECT_NEAR(both.step_pos.z(), -0.1, 0.02) << both.step_pos.transpose();
  EXPECT_GT(both.score.covered, alone.score.covered + alone.score.covered / 10);
  // The sample a probe works on keeps the patches.
  EXPECT_EQ(SampleFrame(f.frame, 100).patches, &patches);
}

// The room seen from `truth`, its kNN rows computed once at a pose `off` it: the associations the
// IEKF's last iteration leaves for the consistency check.
struct AssociatedRoom {
  AssociatedRoom() : provider(Knn()) {
    f.Build(truth);
    provider.BeginScan(f.frame);
    had_associations_before_rows = provider.Associations(&associated);
    std::vector<PointPlaneRow> rows;
    provider.ComputeRows(off, &rows);
    has_associations = provider.Associations(&associated);
  }
  static KnnOptions Knn() {
    KnnOptions knn;
    knn.max_residual = 1.0;
    return knn;
  }
  RoomFixture f;
  const Eigen::Isometry3d truth = Pose(Eigen::Vector3d(0.4, 0.1, 0.05), Eigen::Vector3d(0, 0, 0.1));
  const Eigen::Isometry3d off =
      Pose(Eigen::Vector3d(0.45, 0.05, 0.08), Eigen::Vector3d(0.005, 0.0, 0.12));
  KnnResidualProvider provider;
  std::vector<AssociatedPoint> associated;
  bool had_associations_before_rows = false;
  bool has_associations = false;
};

// The consistency check's probe from the IEKF's own kNN search (KnnResidualProvider::Associations)
// says what a fresh search at the same pose says: the same points met the map, the same fit, the
// same step; before a search since BeginScan there is nothing to reuse.
TEST(ProbePoseAssociated, SaysWhatAFreshSearchAtThatPoseSays) {
  AssociatedRoom room;
  const RoomFixture& f = room.f;
  const Eigen::Isometry3d& truth = room.truth;
  const Eigen::Isometry3d& off = room.off;
  const KnnOptions knn = AssociatedRoom::Knn();
  const std::vector<AssociatedPoint>& associated = room.associated;
  EXPECT_FALSE(room.had_associations_before_rows);
  ASSERT_TRUE(room.has_associations);
  ASSERT_EQ(associated.size(), f.frame.points_lidar.size());

  const PoseProbe reused =
      ProbePoseAssociated(associated, off, LidarOnlyOptions(), IekfOptions(), 1.0);
  const PoseProbe fresh = ProbePose(f.frame, off, LidarOnlyOptions(), knn, IekfOptions(), 1.0);
  EXPECT_EQ(reused.score.covered, fresh.score.covered);
  EXPECT_EQ(reused.score.inliers, fresh.score.inliers);
  EXPECT_EQ(reused.rows, fresh.rows);
  EXPECT_GT(reused.rows, 1000u);
  EXPECT_LT((reused.step_pos - fresh.step_pos).norm(), 1e-6);
  EXPECT_LT((reused.step_rot - fresh.step_rot).norm(), 1e-6);
  // The step is the scan's own: toward the truth.
  EXPECT_LT((off.translation() + reused.step_pos - truth.translation()).norm(),
            0.5 * (off.translation() - truth.translation()).norm());
}

// kPpf's check scores the kNN associations and the skeleton points' patches together, but takes
// the step from the kNN rows alone (step_points): the points beyond it count in the fit only.
TEST(ProbePoseAssociated, PointsBeyondStepPointsCountInTheFitOnly) {
  AssociatedRoom room;
  const Eigen::Isometry3d& off = room.off;
  const std::vector<AssociatedPoint>& associated = room.associated;
  ASSERT_TRUE(room.has_associations);
  const size_t half = associated.size() / 2;
  std::vector<AssociatedPoint> first(associated.begin(), associated.begin() + half);

  const PoseProbe all =
      ProbePoseAssociated(associated, off, LidarOnlyOptions(), IekfOptions(), 1.0);
  const PoseProbe split =
      ProbePoseAssociated(associated, off, LidarOnlyOptions(), IekfOptions(), 1.0, half);
  const PoseProbe alone = ProbePoseAssociated(first, off, LidarOnlyOptions(), IekfOptions(), 1.0);
  // The score of every point, the rows and the step of the first half.
  EXPECT_EQ(split.score.covered, all.score.covered);
  EXPECT_EQ(split.score.inliers, all.score.inliers);
  EXPECT_DOUBLE_EQ(split.score.fit, all.score.fit);
  EXPECT_EQ(split.rows, alone.rows);
  EXPECT_LT(split.rows, all.rows);
  EXPECT_LT((split.step_pos - alone.step_pos).norm(), 1e-9);
  EXPECT_LT((split.step_rot - alone.step_rot).norm(), 1e-9);
  EXPECT_GT((all.step_pos - alone.step_pos).norm(), 1e-6);
}

// Associations on the walls and the floor of a 10 m room, seen from its middle: each point is
// the true surface point moved by `offset` (the pose error a step should undo) plus noise of
// `noise` m along the surface normal.
std::vector<AssociatedPoint> RoomAssociations(size_t n, const Eigen::Vector3d& offset, double noise,
                                              unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-4.5, 4.5);
  std::normal_distribution<double> e(0.0, 1.0);
  const Eigen::Vector3d normals[] = {Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitX(),
                                     Eigen::Vector3d::UnitY(), -Eigen::Vector3d::UnitY(),
                                     Eigen::Vector3d::UnitZ()};
  std::vector<AssociatedPoint> out;
  for (size_t i = 0; i < n; ++i) {
    AssociatedPoint a;
    a.normal = normals[i % 5];
    a.d = i % 5 == 4 ? 1.5 : 5.0;  // floor at z = -1.5, walls at +-5 m
    // A point on the plane n . x + d = 0, spread over it.
    Eigen::Vector3d p(u(rng), u(rng), u(rng) * 0.3);
    p -= (a.normal.dot(p) + a.d) * a.normal;
    p += offset + noise * e(rng) * a.normal;
    a.point_lidar = p.cast<float>();
    a.covered = true;
    a.has_plane = true;
    out.push_back(a);
  }
  return out;
}

// The consistency check's step trigger reads the step in standard deviations of its own estimate
// (PoseProbe::step_pos_sigmas): a pose error every row agrees on stands far out of the rows'
// scatter, a step that is the scatter of a hundred noisy rows does not, and the measure does not
// depend on the size of the residuals, only on how well they agree.
TEST(ProbePoseAssociated, StepInSigmasSeparatesAnOffsetFromScatter) {
  const Eigen::Isometry3d at = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d offset(0.3, -0.2, 0.05);
  const PoseProbe moved = ProbePoseAssociated(RoomAssociations(600, offset, 0.01, 1), at,
                                              LidarOnlyOptions(), IekfOptions(), 1.0);
  ASSERT_GT(moved.rows, 500u);
  EXPECT_LT((moved.step_pos + offset).norm(), 0.02);  // the step undoes the offset
  EXPECT_GT(moved.step_pos_sigmas, 100.0);

  // A hundred rows of 0.1 m noise and no offset: the step is what the noise leaves, and in its
  // own sigmas the norm of a 3-D normal sample (below 4 in 99.9 % of draws).
  const PoseProbe scattered =
      ProbePoseAssociated(RoomAssociations(100, Eigen::Vector3d::Zero(), 0.1, 2), at,
                          LidarOnlyOptions(), IekfOptions(), 1.0);
  ASSERT_EQ(scattered.rows, 100u);
  EXPECT_GT(scattered.step_pos.norm(), 0.0);
  EXPECT_GT(scattered.step_pos_sigmas, 0.0);
  EXPECT_LT(scattered.step_pos_sigmas, 4.0);

  // The same rows with ten times the residuals: ten times the step, the same sigmas.
  const PoseProbe ten = ProbePoseAssociated(RoomAssociations(100, Eigen::Vector3d::Zero(), 1.0, 2),
                                            at, LidarOnlyOptions(), IekfOptions(), 100.0);
  const PoseProbe one = ProbePoseAssociated(RoomAssociations(100, Eigen::Vector3d::Zero(), 0.1, 2),
                                            at, LidarOnlyOptions(), IekfOptions(), 100.0);
  ASSERT_EQ(ten.rows, one.rows);
  EXPECT_LT((ten.step_pos - 10.0 * one.step_pos).norm(), 1e-3 * ten.step_pos.norm());
  EXPECT_NEAR(ten.step_pos_sigmas, one.step_pos_sigmas, 1e-3 * one.step_pos_sigmas);
}

// The consistency check compares a scan's score with the recent scans' of the same kind. The
// scores below are those of an undisturbed kPpf hand-held walk (60 s indoor VLP-16): kNN
// associations fit 0.95-1.0, while a scan with too few of them is scored on a searched sample of
// the whole scan at 0.4-0.7 (the kNN map holds only the scattered points). With one shared
// baseline each sampled scan fell below fit_ratio x 0.98 and was reported as contradicted.
TEST(FitBaseline, JudgesEachKindOfScoreAgainstItsOwnRecentScores) {
  using Kind = FitBaseline::Kind;
  const double ratio = ConsistencyOptions().fit_ratio;
  FitBaseline b;
  auto poor = [&](Kind kind, double fit) { return fit < ratio * b.MedianFit(kind); };
  const double associated[] = {0.98, 0.97, 1.0, 0.99, 0.96, 0.98, 0.99, 1.0, 0.98, 0.97, 0.99};
  for (double f : associated) b.Remember(Kind::kAssociated, f, 0.01);
  EXPECT_TRUE(b.Ready(Kind::kAssociated));
  EXPECT_EQ(b.Size(Kind::kAssociated), 10u);  // the window
  // The first sampled scores meet no baseline of their kind: nothing to judge them by yet.
  EXPECT_FALSE(b.Ready(Kind::kSampled));
  const double sampled[] = {0.61, 0.65, 0.58, 0.52, 0.61, 0.64, 0.48};
  for (int i = 0; i < 5; ++i) {
    EXPECT_TRUE(poor(Kind::kAssociated, sampled[i]));  // what a shared baseline did
    b.Remember(Kind::kSampled, sampled[i], 0.03);
  }
  ASSERT_TRUE(b.Ready(Kind::kSampled));
  EXPECT_DOUBLE_EQ(b.MedianFit(Kind::kSampled), 0.61);
  EXPECT_FALSE(poor(Kind::kSampled, sampled[5]));
  EXPECT_FALSE(poor(Kind::kSampled, sampled[6]));
  // A heading error of degrees still drops either kind far below its own (about 0.4 of it).
  EXPECT_TRUE(poor(Kind::kSampled, 0.4 * 0.61));
  EXPECT_TRUE(poor(Kind::kAssociated, 0.4 * 0.98));
  // Neither kind moves the other's median; the step baselines are kept per kind too.
  EXPECT_DOUBLE_EQ(b.MedianFit(Kind::kAssociated), 0.99);  // the upper median of the last 10
  EXPECT_DOUBLE_EQ(b.MedianStepPos(Kind::kAssociated), 0.01);
  EXPECT_DOUBLE_EQ(b.MedianStepPos(Kind::kSampled), 0.03);
  b.Clear();
  EXPECT_FALSE(b.Ready(Kind::kAssociated));
  EXPECT_DOUBLE_EQ(b.MedianFit(Kind::kAssociated), 0.0);
}

}  // namespace
}  // namespace ppf
