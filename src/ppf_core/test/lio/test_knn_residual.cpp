// kNN point-to-plane residuals: the plane validity test of the k neighbours, and the range
// limit on the points that give rows, the neighbours kept between a scan's iterations, and the
// searches made ahead of the split (Prefetch).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <vector>

#include "lio/knn_room_fixture.hpp"
#include "ppf_core/lio/knn_residual.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

TEST(KnnResidual, PlaneValidityRejectsNonPlanarNeighbours) {
  Eigen::Vector3d n;
  double d;
  std::vector<Eigen::Vector3f> flat = {
      {0, 0, 0}, {1, 0, 0.02f}, {0, 1, -0.02f}, {1, 1, 0}, {0.5f, 0.5f, 0.01f}};
  ASSERT_TRUE(FitPlane(flat, 0.1, &n, &d));
  EXPECT_NEAR(std::abs(n.z()), 1.0, 1e-3);
  std::vector<Eigen::Vector3f> corner = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}};
  EXPECT_FALSE(FitPlane(corner, 0.1, &n, &d));
  std::vector<Eigen::Vector3f> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}};
  EXPECT_FALSE(FitPlane(line, 0.1, &n, &d));
  // A 1 m piece of a scan ring on the floor 7.5 m away: nearly collinear. Accepted by the distance
  // test alone; rejected once a minimum cross spread is required.
  std::vector<Eigen::Vector3f> arc;
  for (int i = -2; i <= 2; ++i) {
    const double a = 0.033 * i;
    arc.emplace_back(static_cast<float>(7.5 * std::cos(a)), static_cast<float>(7.5 * std::sin(a)),
                     -2.f);
  }
  EXPECT_TRUE(FitPlane(arc, 0.1, &n, &d));
  EXPECT_FALSE(FitPlane(arc, 0.1, &n, &d, 0.04));
  EXPECT_TRUE(FitPlane(flat, 0.1, &n, &d, 0.04));
}

// residual_max_range: only points within it give rows (they all still exist in the frame).
TEST(KnnResidual, FarPointsGiveNoRowsBeyondResidualMaxRange) {
  test::KnnRoomFixture f;
  test::BuildKnnRoom(test::MakeRoomScene(), &f);
  KnnResidualProvider knn;
  std::vector<PointPlaneRow> all, near;
  knn.BeginScan(f.frame);
  knn.ComputeRows(Eigen::Isometry3d::Identity(), &all);
  ASSERT_GT(all.size(), 100u);
  std::vector<double> ranges;
  for (const PointPlaneRow& r : all) ranges.push_back(r.point_lidar.norm());
  std::nth_element(ranges.begin(), ranges.begin() + ranges.size() / 2, ranges.end());
  // About half the rows are nearer; off the median point itself (float vs double rounding).
  const double limit = ranges[ranges.size() / 2] + 1e-4;
  f.frame.residual_max_range = limit;
  knn.BeginScan(f.frame);
  knn.ComputeRows(Eigen::Isometry3d::Identity(), &near);
  size_t within = 0;
  for (const PointPlaneRow& r : all) within += r.point_lidar.norm() <= limit ? 1 : 0;
  EXPECT_EQ(near.size(), within);
  EXPECT_LT(near.size(), all.size());
  for (const PointPlaneRow& r : near) EXPECT_LE(r.point_lidar.norm(), limit);
}

// The rows of two ComputeRows calls are the same: same points, planes and offsets, in order.
bool SameRows(const std::vector<PointPlaneRow>& a, const std::vector<PointPlaneRow>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!(a[i].point_lidar == b[i].point_lidar) || !(a[i].normal_world == b[i].normal_world) ||
        a[i].offset != b[i].offset) {
      return false;
    }
  }
  return true;
}

// The room scan with search_again_distance 0.1 m, and a pose 0.075 m from the identity: within
// the distance of every point's search there.
struct KeepCase {
  test::KnnRoomFixture f;
  KnnOptions options;
  Eigen::Isometry3d near = Eigen::Isometry3d::Identity();
  KeepCase() {
    test::BuildKnnRoom(test::MakeRoomScene(), &f);
    options.search_again_distance = 0.1;
    near.translation() = Eigen::Vector3d(0.06, -0.04, 0.02);
  }
  // What a fresh search at T gives (a provider with nothing kept).
  std::vector<PointPlaneRow> Fresh(const Eigen::Isometry3d& T) const {
    KnnResidualProvider fresh;
    std::vector<PointPlaneRow> rows;
    fresh.BeginScan(f.frame);
    fresh.ComputeRows(T, &rows);
    return rows;
  }
};

// search_again_distance: within one scan a point that moved less than it since its search keeps
// that search's plane (its row is still evaluated at the new pose); one that moved farther
// searches again and gets what a fresh search gives.
TEST(KnnResidual, KeepsNeighboursWhileThePointStaysNearItsSearch) {
  KeepCase c;
  KnnResidualProvider keep(c.options);
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(0.3, 0.0, 0.0);
  std::vector<PointPlaneRow> first, kept, again;
  keep.BeginScan(c.f.frame);
  keep.ComputeRows(Eigen::Isometry3d::Identity(), &first);
  keep.ComputeRows(c.near, &kept);
  ASSERT_GT(first.size(), 100u);
  ASSERT_EQ(kept.size(), first.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    EXPECT_TRUE(kept[i].point_lidar == first[i].point_lidar);
    EXPECT_TRUE(kept[i].normal_world == first[i].normal_world);
    EXPECT_EQ(kept[i].offset, first[i].offset);
  }
  // A new search from there finds other neighbours for some points (noisy map): other planes.
  EXPECT_FALSE(SameRows(c.Fresh(c.near), first));
  keep.ComputeRows(far, &again);
  EXPECT_TRUE(SameRows(again, c.Fresh(far)));
  EXPECT_FALSE(SameRows(again, first));
}

// SetKeepNeighbours(false) (a scan registered from LiDAR-only guesses, or a prediction less
// certain than search_again_distance): every iteration searches again, whatever the distance.
TEST(KnnResidual, SearchesEveryIterationWhenKeepingIsOff) {
  KeepCase c;
  KnnResidualProvider provider(c.options);
  provider.SetKeepNeighbours(false);
  std::vector<PointPlaneRow> first, second;
  provider.BeginScan(c.f.frame);
  provider.ComputeRows(Eigen::Isometry3d::Identity(), &first);
  provider.ComputeRows(c.near, &second);  // kept if keeping were on (previous test)
  const std::vector<PointPlaneRow> fresh = c.Fresh(c.near);
  ASSERT_GT(fresh.size(), 100u);
  EXPECT_TRUE(SameRows(second, fresh));
  EXPECT_FALSE(SameRows(second, first));  // the kept planes would have been the first search's
}

// Prefetch searches the points at the predicted pose before the split has labelled them: the
// first iteration reuses the searches of the points that are scattered, and its rows are exactly
// a fresh search's; a later iteration at another pose searches again. Only the next BeginScan of
// the same frame reads them, and a query at another pose never does.
TEST(KnnResidual, PrefetchedSearchesGiveExactlyTheRowsOfAFreshSearch) {
  KeepCase c;
  const Eigen::Isometry3d far = [] {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.3, 0.0, 0.0);
    return T;
  }();
  const std::atomic<bool> go{false}, stopped{true};
  KnnResidualProvider plain(c.options), fetched(c.options);
  plain.SetKeepNeighbours(false);
  fetched.SetKeepNeighbours(false);
  // Prefetched before the split: every point searched, whatever its label will be.
  fetched.Prefetch(c.f.frame, c.near, {}, 0.0, go);
  // The split: every third point becomes a skeleton point, a few are discarded.
  size_t scattered = 0;
  for (size_t i = 0; i < c.f.frame.labels.size(); ++i) {
    c.f.frame.labels[i] = i % 3 == 0   ? PointLabel::kSkeleton
                          : i % 7 == 0 ? PointLabel::kDiscarded
                                       : PointLabel::kScattered;
    scattered += c.f.frame.labels[i] == PointLabel::kScattered ? 1 : 0;
  }
  std::vector<PointPlaneRow> a0, a1, b0, b1;
  plain.BeginScan(c.f.frame);
  fetched.BeginScan(c.f.frame);
  EXPECT_EQ(plain.prefetched(), 0u);
  EXPECT_EQ(fetched.prefetched(), c.f.frame.points_lidar.size());
  EXPECT_EQ(fetched.prefetched_scattered(), scattered);
  plain.ComputeRows(c.near, &a0);
  fetched.ComputeRows(c.near, &b0);
  ASSERT_GT(a0.size(), 50u);
  EXPECT_TRUE(SameRows(a0, b0));
  plain.ComputeRows(far, &a1);
  fetched.ComputeRows(far, &b1);
  EXPECT_TRUE(SameRows(a1, b1));
  EXPECT_FALSE(SameRows(b1, b0));

  // Consumed by that BeginScan: the next one starts with nothing searched.
  fetched.BeginScan(c.f.frame);
  EXPECT_EQ(fetched.prefetched(), 0u);
  // Prefetched at another pose than the first iteration's: counted, never read.
  fetched.Prefetch(c.f.frame, far, {}, 0.0, go);
  fetched.BeginScan(c.f.frame);
  EXPECT_EQ(fetched.prefetched_scattered(), scattered);
  std::vector<PointPlaneRow> other;
  fetched.ComputeRows(c.near, &other);
  EXPECT_TRUE(SameRows(other, a0));
  // Stopped at once (the split was done first): nothing searched, the same rows.
  fetched.Prefetch(c.f.frame, c.near, {}, 0.0, stopped);
  fetched.BeginScan(c.f.frame);
  EXPECT_EQ(fetched.prefetched(), 0u);
  std::vector<PointPlaneRow> none;
  fetched.ComputeRows(c.near, &none);
  EXPECT_TRUE(SameRows(none, a0));
}

// Prefetch's order: the points within the band of a likely plane last (they will mostly be
// skeleton points, which need no search), each part in index order; points beyond the residual
// range not at all.
TEST(KnnResidual, PrefetchSearchesThePointsNearLikelyPlanesLast) {
  test::KnnRoomFixture f;
  test::BuildKnnRoom(test::MakeRoomScene(), &f);
  f.frame.residual_max_range = 12.0;
  const Plane floor{Eigen::Vector3d::UnitZ(), 2.0};  // z = -2 in the scan frame
  KnnResidualProvider knn;
  const std::vector<size_t>& order = knn.PrefetchOrder(f.frame, {floor}, 0.1);
  size_t within_range = 0, on_floor = 0;
  for (const Eigen::Vector3f& p : f.frame.points_lidar) {
    if (!f.frame.GivesResidual(p)) continue;
    ++within_range;
    on_floor += std::abs(p.z() + 2.0f) < 0.1f ? 1 : 0;
  }
  ASSERT_GT(on_floor, 20u);
  ASSERT_LT(on_floor + 20, within_range);
  ASSERT_EQ(order.size(), within_range);
  const size_t first_floor = order.size() - on_floor;
  for (size_t k = 0; k < order.size(); ++k) {
    const Eigen::Vector3f& p = f.frame.points_lidar[order[k]];
    EXPECT_TRUE(f.frame.GivesResidual(p));
    EXPECT_EQ(std::abs(p.z() + 2.0f) < 0.1f, k >= first_floor) << k;
    if (k > 0 && k != first_floor) {
      EXPECT_LT(order[k - 1], order[k]);
    }
  }
}

}  // namespace
}  // namespace ppf
