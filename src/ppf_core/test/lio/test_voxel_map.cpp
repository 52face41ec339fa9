// Voxel-hash kNN map: exact kNN against brute force, downsampling, and the memory bound over
// ten minutes of scans.
#include <gtest/gtest.h>

#include <algorithm>
#include <list>
#include <map>
#include <random>
#include <tuple>

#include "ppf_core/lio/voxel_downsample.hpp"
#include "ppf_core/lio/voxel_map.hpp"

namespace ppf {
namespace {

std::vector<Eigen::Vector3f> RandomCloud(size_t n, float extent, std::mt19937* rng) {
  std::uniform_real_distribution<float> u(-extent, extent);
  std::vector<Eigen::Vector3f> pts(n);
  for (auto& p : pts) p = Eigen::Vector3f(u(*rng), u(*rng), u(*rng));
  return pts;
}

TEST(VoxelMap, KnnEqualsBruteForceWithNearby27) {
  std::mt19937 rng(7);
  for (double res : {0.5, 1.0}) {
    VoxelMapOptions opt;
    opt.resolution = res;
    opt.nearby = NearbyType::kNearby27;
    opt.max_points_per_voxel = 100000;
    opt.min_point_distance = 0.0;
    VoxelMap map(opt);
    const auto cloud = RandomCloud(20000, 5.0f, &rng);
    map.Insert(cloud);
    ASSERT_EQ(map.size(), cloud.size());
    const auto queries = RandomCloud(500, 5.5f, &rng);
    std::vector<Eigen::Vector3f> got;
    for (const auto& q : queries) {
      for (size_t k : {1u, 5u, 10u}) {
        map.GetClosest(q, k, res, &got);
        std::vector<float> brute;
        for (const auto& p : cloud) {
          const float d2 = (p - q).squaredNorm();
          if (d2 <= static_cast<float>(res * res)) brute.push_back(d2);
        }
        std::sort(brute.begin(), brute.end());
        brute.resize(std::min(brute.size(), k));
        ASSERT_EQ(got.size(), brute.size());
        for (size_t i = 0; i < got.size(); ++i) {
          ASSERT_FLOAT_EQ((got[i] - q).squaredNorm(), brute[i]) << "rank " << i;
        }
      }
    }
  }
}

TEST(VoxelMap, SmallerNeighbourhoodsReturnSubsetsNearestFirst) {
  std::mt19937 rng(11);
  VoxelMapOptions opt;
  opt.nearby = NearbyType::kNearby7;
  opt.min_point_distance = 0.0;
  opt.max_points_per_voxel = 1000;
  VoxelMap map(opt);
  map.Insert(RandomCloud(5000, 3.0f, &rng));
  std::vector<Eigen::Vector3f> got;
  const Eigen::Vector3f q(0.1f, 0.2f, 0.3f);
  map.GetClosest(q, 5, 1.0, &got);
  ASSERT_EQ(got.size(), 5u);
  for (size_t i = 1; i < got.size(); ++i) {
    EXPECT_LE((got[i - 1] - q).norm(), (got[i] - q).norm());
  }
}

TEST(VoxelMap, PerVoxelCapAndMinDistance) {
  VoxelMapOptions opt;
  opt.resolution = 1.0;
  opt.max_points_per_voxel = 3;
  opt.min_point_distance = 0.1;
  VoxelMap map(opt);
  map.Insert(Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  map.Insert(Eigen::Vector3f(0.52f, 0.5f, 0.5f));  // too close: ignored
  EXPECT_EQ(map.size(), 1u);
  map.Insert(Eigen::Vector3f(0.1f, 0.1f, 0.1f));
  map.Insert(Eigen::Vector3f(0.9f, 0.9f, 0.9f));
  map.Insert(Eigen::Vector3f(0.1f, 0.9f, 0.1f));  // voxel full
  EXPECT_EQ(map.size(), 3u);
  EXPECT_EQ(map.num_voxels(), 1u);
}

TEST(VoxelMap, NonFiniteAndDegenerateOptionsAreSafe) {
  VoxelMapOptions opt;
  opt.resolution = 0.0;  // would divide by zero
  opt.max_voxels = 0;
  VoxelMap map(opt);
  map.Insert(Eigen::Vector3f(std::nanf(""), 0.f, 0.f));
  EXPECT_EQ(map.size(), 0u);
  map.Insert(Eigen::Vector3f(1.f, 2.f, 3.f));
  EXPECT_EQ(map.size(), 1u);
  std::vector<Eigen::Vector3f> got;
  EXPECT_EQ(map.GetClosest(Eigen::Vector3f(std::nanf(""), 0.f, 0.f), 5, 1.0, &got), 0u);
}

TEST(VoxelMap, DownsampleKeepsOneCentroidPerVoxel) {
  const std::vector<Eigen::Vector3f> pts = {{0.1f, 0.1f, 0.1f},
                                            {0.3f, 0.3f, 0.3f},
                                            {1.2f, 0.1f, 0.1f},
                                            {std::nanf(""), 0.f, 0.f}};
  const auto out = VoxelDownsample(pts, 0.5);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_TRUE(out[0].isApprox(Eigen::Vector3f(0.2f, 0.2f, 0.2f)));
  EXPECT_TRUE(out[1].isApprox(Eigen::Vector3f(1.2f, 0.1f, 0.1f)));
  EXPECT_EQ(VoxelDownsample(pts, 0.0).size(), pts.size());  // 0 disables, never crashes
  // Nearest-to-centroid keeps a measured point: the first voxel's centroid (0.2) is equidistant
  // from both points, the first one wins; the second voxel has only one point.
  const auto picked = VoxelDownsample(pts, 0.5, DownsampleMode::kNearestToCentroid);
  ASSERT_EQ(picked.size(), 2u);
  EXPECT_TRUE(picked[0] == pts[0] || picked[0] == pts[1]);
  EXPECT_EQ(picked[1], pts[2]);
}

// Ten minutes at 10 Hz of a vehicle driving a 6 km loop-free path at 10 m/s (6000 scans of 1000
// points within 60 m): without a bound the map would hold millions of points.
TEST(VoxelMap, MemoryStaysBoundedOverTenMinutesOfScans) {
  VoxelMapOptions opt;
  opt.resolution = 0.5;
  opt.max_voxels = 20000;
  opt.max_points_per_voxel = 10;
  VoxelMap map(opt);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> ang(0.f, 6.2831853f), rad(2.f, 60.f), h(-2.f, 5.f);
  size_t max_size = 0, max_voxels = 0, size_after_first_minute = 0;
  std::vector<Eigen::Vector3f> scan(1000);
  for (int s = 0; s < 6000; ++s) {
    const Eigen::Vector3f sensor(10.0f * 0.1f * s, 0.f, 0.f);
    for (auto& p : scan) {
      const float a = ang(rng), r = rad(rng);
      p = sensor + Eigen::Vector3f(r * std::cos(a), r * std::sin(a), h(rng));
    }
    map.Insert(scan);
    if (s % 10 == 0) map.RemoveFarFrom(sensor.cast<double>(), 100.0);
    max_size = std::max(max_size, map.size());
    max_voxels = std::max(max_voxels, map.num_voxels());
    if (s == 600) size_after_first_minute = map.size();
  }
  EXPECT_LE(max_voxels, opt.max_voxels);
  EXPECT_LE(max_size, map.capacity_points());
  // Flat after warm-up: the last nine minutes never exceed the first minute's level by much.
  EXPECT_LE(map.size(), size_after_first_minute + size_after_first_minute / 10);
  EXPECT_GT(map.size(), 0u);
}

TEST(VoxelMap, RemoveFarFromDropsDistantVoxels) {
  VoxelMap map;
  map.Insert(Eigen::Vector3f(0.f, 0.f, 0.f));
  map.Insert(Eigen::Vector3f(100.f, 0.f, 0.f));
  map.RemoveFarFrom(Eigen::Vector3d::Zero(), 10.0);
  EXPECT_EQ(map.size(), 1u);
  std::vector<Eigen::Vector3f> got;
  EXPECT_EQ(map.GetClosest(Eigen::Vector3f(100.f, 0.f, 0.f), 1, 1.0, &got), 0u);
}

TEST(VoxelMap, EvictionsAndRemovalsKeepEveryLookupExact) {
  // Thousands of voxels created, evicted (LRU, 300 at most) and removed (RemoveFarFrom) in a
  // region small enough that the index's probe runs overlap: after every step the map holds
  // exactly what a plain model of its rules holds, and kNN over it equals brute force over the
  // model. Deleting from an open-addressing table must not lose entries behind the hole.
  VoxelMapOptions opt;
  opt.resolution = 0.5;
  opt.nearby = NearbyType::kNearby27;
  opt.max_voxels = 300;
  opt.max_points_per_voxel = 3;
  opt.min_point_distance = 0.0;
  VoxelMap map(opt);
  std::map<std::tuple<int, int, int>, std::vector<Eigen::Vector3f>> model;
  std::list<std::tuple<int, int, int>> lru;  // front = most recently fed
  std::mt19937 rng(11);
  std::vector<Eigen::Vector3f> got;
  for (int step = 0; step < 60; ++step) {
    const Eigen::Vector3f centre(0.3f * step, 0.f, 0.f);
    for (const Eigen::Vector3f& d : RandomCloud(200, 4.0f, &rng)) {
      const Eigen::Vector3f p = centre + d;
      map.Insert(p);
      const VoxelKey k = ToVoxelKey(p, 2.0);
      const auto key = std::make_tuple(k.x, k.y, k.z);
      lru.remove(key);
      lru.push_front(key);
      if (model[key].size() < opt.max_points_per_voxel) model[key].push_back(p);
      if (model.size() > opt.max_voxels) {
        model.erase(lru.back());
        lru.pop_back();
      }
    }
    if (step % 7 == 6) {
      map.RemoveFarFrom(centre.cast<double>(), 3.0);
      for (auto it = lru.begin(); it != lru.end();) {
        const auto [x, y, z] = *it;
        const Eigen::Vector3d c((x + 0.5) * 0.5, (y + 0.5) * 0.5, (z + 0.5) * 0.5);
        if ((c - centre.cast<double>()).squaredNorm() > 9.0) {
          model.erase(*it);
          it = lru.erase(it);
        } else {
          ++it;
        }
      }
    }
    ASSERT_EQ(map.num_voxels(), model.size()) << "step " << step;
    size_t points = 0;
    for (const auto& [key, pts] : model) points += pts.size();
    ASSERT_EQ(map.size(), points) << "step " << step;
    for (const Eigen::Vector3f& d : RandomCloud(50, 5.0f, &rng)) {
      const Eigen::Vector3f q = centre + d;
      map.GetClosest(q, 3, 0.5, &got);
      std::vector<float> brute;
      for (const auto& [key, pts] : model) {
        for (const auto& p : pts) {
          const float d2 = (p - q).squaredNorm();
          if (d2 <= 0.25f) brute.push_back(d2);
        }
      }
      std::sort(brute.begin(), brute.end());
      brute.resize(std::min<size_t>(brute.size(), 3));
      ASSERT_EQ(got.size(), brute.size()) << "step " << step;
      for (size_t i = 0; i < got.size(); ++i) ASSERT_FLOAT_EQ((got[i] - q).squaredNorm(), brute[i]);
    }
  }
}

}  // namespace
}  // namespace ppf
