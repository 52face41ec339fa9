// Preprocess stage: voxel grid with per-voxel mean time on the raw scan, then de-skew of the kept
// points (preprocess.hpp). The order swap must not change what registration sees.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <set>
#include <tuple>

#include "ppf_core/lio/deskew.hpp"
#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/preprocess.hpp"
#include "ppf_core/lio/voxel_downsample.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

TEST(Preprocess, VoxelCentroidCarriesMeanTimeAndIntensity) {
  std::vector<TimedPoint> in = {{Eigen::Vector3f(1.1f, 1.1f, 1.1f), 10.f, 5.00},
                                {Eigen::Vector3f(3.2f, 0.1f, 0.1f), 7.f, 5.01},
                                {Eigen::Vector3f(1.3f, 1.2f, 1.4f), 20.f, 5.02},
                                {Eigen::Vector3f(1.2f, 1.3f, 1.3f), 30.f, 5.04}};
  PreprocessOptions options;
  options.voxel_size = 0.5;
  options.min_range = 0.0;
  VoxelGridDownsampler ds;
  std::vector<TimedPoint> out;
  const PreprocessStats stats = ds.Run(in, 5.0, options, &out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(stats.valid_points, 4u);
  EXPECT_EQ(stats.downsampled_points, 2u);
  // First appearance order: the (1,1,1) voxel first.
  EXPECT_TRUE(out[0].p.isApprox(Eigen::Vector3f(1.2f, 1.2f, 1.2667f), 1e-4f));
  EXPECT_NEAR(out[0].t, (5.00 + 5.02 + 5.04) / 3.0, 1e-9);
  EXPECT_NEAR(out[0].intensity, 20.f, 1e-5f);
  EXPECT_TRUE(out[1].p.isApprox(in[1].p));
  EXPECT_NEAR(out[1].t, 5.01, 1e-9);
}

TEST(Preprocess, RangeAndStrideFilterBeforeTheGrid) {
  std::vector<TimedPoint> in;
  for (int i = 0; i < 100; ++i) in.push_back({Eigen::Vector3f(0.1f * i, 0.f, 0.f), 0.f, i * 1e-3});
  PreprocessOptions options;
  options.voxel_size = 0.0;  // no grid: filter only
  options.min_range = 1.0;
  options.max_range = 5.0;
  options.point_stride = 2;
  VoxelGridDownsampler ds;
  std::vector<TimedPoint> out;
  const PreprocessStats stats = ds.Run(in, 0.0, options, &out);
  // Even indices 10..50 (x = 1.0 .. 5.0 m) survive.
  ASSERT_EQ(out.size(), 21u);
  EXPECT_EQ(stats.valid_points, 21u);
  EXPECT_FLOAT_EQ(out.front().p.x(), 1.0f);
  EXPECT_FLOAT_EQ(out.back().p.x(), 5.0f);
}

TEST(Preprocess, SameVoxelsAsTheMapDownsamplerAndGrowsPastItsFirstTableSize) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-40.f, 40.f);
  std::vector<TimedPoint> in;
  std::vector<Eigen::Vector3f> plain;
  for (int i = 0; i < 60000; ++i) {
    const Eigen::Vector3f p(u(rng), u(rng), 0.05f * u(rng));
    in.push_back({p, 0.f, 100.0 + i * 1e-7});
    plain.push_back(p);
  }
  // 0.2 m voxels: ~50k distinct ones, far more than the table the first call reserves.
  PreprocessOptions options;
  options.voxel_size = 0.2;
  options.min_range = 0.0;
  options.max_range = 1e3;
  VoxelGridDownsampler ds;
  std::vector<TimedPoint> out;
  for (int call = 0; call < 2; ++call) {  // the second call reuses the grown table
    ds.Run(in, 100.0, options, &out);
    const auto reference = VoxelDownsample(plain, 0.2);
    ASSERT_EQ(out.size(), reference.size());
    std::set<std::tuple<int, int, int>> keys;
    for (size_t i = 0; i < out.size(); ++i) {
      ASSERT_TRUE(out[i].p.isApprox(reference[i], 1e-5f)) << i;
      const VoxelKey k = ToVoxelKey(out[i].p, 5.0);
      keys.insert({k.x, k.y, k.z});
    }
    EXPECT_EQ(keys.size(), out.size()) << "one point per voxel";
    EXPECT_GT(out.size(), 30000u);
  }
}

TEST(Preprocess, DownsampleThenDeskewEqualsDeskewThenDownsample) {
  // Hand-held worst case of the simulator: 150 deg/s and 1.5 m/s, T_imu_lidar off-centre.
  const test::PoseFn pose = [](double t) {
    return test::MakePose(Eigen::Vector3d(1.5 * t, 0.2 * std::sin(3.0 * t), 0.05 * t),
                          0.3 * std::sin(4.0 * t), 0.2 * std::sin(5.0 * t), 2.6 * t);
  };
  const Eigen::Isometry3d T_imu_lidar = test::MakePose(Eigen::Vector3d(0.1, 0.05, 0.2), 0, 0, 0.5);
  test::LidarModel lidar;
  lidar.azimuth_steps = 1440;
  const double t0 = 2.0;
  const auto pts = test::SimulateScan(test::MakeRoomScene(), pose, T_imu_lidar, t0, lidar);
  ASSERT_GT(pts.size(), 5000u);
  const double t_end = pts.back().t;
  std::vector<TimedPoint> timed;
  for (const auto& p : pts) timed.push_back({p.p, 0.f, p.t});
  const double t_first = timed.front().t;  // firings are in time order

  const PoseTrace trace = test::TraceFromTruth(pose, t0, t_end);

  // Product order: grid on raw points (mean times), then de-skew.
  PreprocessOptions options;
  options.voxel_size = 0.5;
  options.min_range = 0.0;
  VoxelGridDownsampler ds;
  std::vector<TimedPoint> kept;
  ds.Run(timed, t_first, options, &kept);
  std::vector<Eigen::Vector3f> fast;
  DeskewToEnd(kept, trace, t_end, T_imu_lidar, &fast);

  // Paper order, per voxel: de-skew each raw point, then average the same raw-voxel members.
  std::vector<Eigen::Vector3f> all;
  DeskewToEnd(timed, trace, t_end, T_imu_lidar, &all);
  std::vector<Eigen::Vector3d> sum(kept.size(), Eigen::Vector3d::Zero());
  std::vector<double> t_min(kept.size(), 1e30), t_max(kept.size(), -1e30);
  std::vector<int> n(kept.size(), 0);
  std::map<std::tuple<int, int, int, int>, size_t> slot;
  // The grid's voxel of a coordinate v (in voxels): floor(v), except that |v| <= 2^-35 counts
  // as 0 (preprocess.cpp, BiasedFloor): 16 points of this scan have such an x and 16 such a
  // y (the firings along the axes, where the cosine of a right angle is not 0).
  const auto grid_index = [](float c) {
    const float v = c * 2.0f;
    return static_cast<int>(std::abs(v) <= 0x1p-35f ? 0.0f : std::floor(v));
  };
  for (size_t i = 0; i < timed.size(); ++i) {
    const Eigen::Vector3f& p = timed[i].p;
    const VoxelKey k{grid_index(p.x()), grid_index(p.y()), grid_index(p.z())};
    const int bucket = static_cast<int>((timed[i].t - t_first) / options.time_bucket_s);
    const auto it = slot.emplace(std::make_tuple(k.x, k.y, k.z, bucket), slot.size()).first;
    sum[it->second] += all[i].cast<double>();
    t_min[it->second] = std::min(t_min[it->second], timed[i].t);
    t_max[it->second] = std::max(t_max[it->second], timed[i].t);
    ++n[it->second];
  }
  ASSERT_EQ(slot.size(), kept.size());
  std::vector<double> err;
  for (size_t v = 0; v < kept.size(); ++v) {
    EXPECT_LT(t_max[v] - t_min[v], 0.05) << "the sweep's seam never shares a voxel";
    err.push_back((fast[v].cast<double>() - sum[v] / n[v]).norm());
  }
  std::sort(err.begin(), err.end());
  EXPECT_LT(err.back(), 2e-3) << "worst voxel";
  EXPECT_LT(err[err.size() / 2], 2e-4) << "median voxel";

  // The split costs few points: only voxels on the seam and at mid-sweep are cut in two.
  options.time_bucket_s = 0.0;
  std::vector<TimedPoint> mixed;
  ds.Run(timed, t_first, options, &mixed);
  EXPECT_LT(mixed.size(), kept.size());
  EXPECT_LT(kept.size() - mixed.size(), kept.size() / 20);
}

// The parallel grid (each thread owning a share of the voxels) must give the serial output bit
// for bit: same voxels in the same order, same sums added in the same order. Also when its grids
// double their hashed share within a call (a sparse cloud, a voxel per point, after a dense one).
TEST(Preprocess, ParallelGridEqualsSerialBitForBit) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<TimedPoint> dense, sparse;
  // A spinning scan's shape: dense near the sensor (many points per voxel, voxels around the
  // origin with coordinates of both signs), sparse far away, a few out-of-range points, times
  // over one sweep with the seam at the end.
  const int n = 3 * static_cast<int>(VoxelGridDownsampler::kParallelPoints);
  for (int i = 0; i < n; ++i) {
    const float r = 0.3f + 40.f * std::pow(std::abs(u(rng)), 3.f);
    const float a = 6.2831853f * static_cast<float>(i) / static_cast<float>(n) + 0.01f * u(rng);
    const Eigen::Vector3f p(r * std::cos(a), r * std::sin(a), -1.7f + 0.5f * u(rng));
    dense.push_back({p, 100.f * std::abs(u(rng)), 40.0 + 0.1 * i / n});
    // 1.3 m apart in x and y, jittered within their 0.5 m voxel: no two share one.
    const Eigen::Vector3f q(1.3f * static_cast<float>(i % 200 - 100) + 0.1f * u(rng),
                            1.3f * static_cast<float>(i / 200 - 120) + 0.1f * u(rng), 0.2f);
    sparse.push_back({q, 50.f, 40.0 + 0.1 * i / n});
  }
  for (const int stride : {1, 2}) {
    PreprocessOptions options;
    options.point_stride = stride;
    options.max_range = 2000.0;  // the sparse cloud reaches beyond 150 m
    options.num_threads = 1;
    std::vector<TimedPoint> reference[2];
    PreprocessStats ref_stats[2];
    {
      VoxelGridDownsampler serial;
      ref_stats[0] = serial.Run(dense, 40.0, options, &reference[0]);
      ref_stats[1] = serial.Run(sparse, 40.0, options, &reference[1]);
    }
    ASSERT_GT(ref_stats[0].valid_points / 2, reference[0].size()) << "voxels hold several points";
    ASSERT_EQ(ref_stats[1].valid_points, reference[1].size()) << "a voxel per point";
    for (const int threads : {2, 1, 3, 2}) {  // a grid reused after another thread count
      options.num_threads = threads;
      VoxelGridDownsampler parallel;
      std::vector<TimedPoint> out;
      for (const int cloud : {0, 1, 0, 1}) {
        const PreprocessStats stats =
            parallel.Run(cloud == 0 ? dense : sparse, 40.0, options, &out);
        EXPECT_EQ(stats.valid_points, ref_stats[cloud].valid_points);
        const std::vector<TimedPoint>& ref = reference[cloud];
        ASSERT_EQ(out.size(), ref.size()) << threads << " threads, cloud " << cloud;
        for (size_t i = 0; i < out.size(); ++i) {
          ASSERT_EQ(std::memcmp(out[i].p.data(), ref[i].p.data(), sizeof(float) * 3), 0)
              << threads << " threads, cloud " << cloud << ", voxel " << i;
          ASSERT_EQ(std::memcmp(&out[i].intensity, &ref[i].intensity, sizeof(float)), 0);
          ASSERT_EQ(std::memcmp(&out[i].t, &ref[i].t, sizeof(double)), 0);
        }
      }
    }
  }
}

// The grid's vector key path (AVX2) must key and filter exactly as the scalar path: points on
// voxel faces, on both sides of the range bounds within a rounding of the squared range, beyond
// the int32 range of its floors (the scalar fallback), times on bucket edges and absurd ones, for
// strides and block starts that do not fall on its four-point groups.
TEST(Preprocess, VectorGridKeysEqualScalarKeys) {
  if (!detail::GridKeysHaveVectorPath()) GTEST_SKIP() << "no vector path on this CPU";
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::uniform_int_distribution<int> pick(0, 5);
  PreprocessOptions options;
  options.min_range = 1.0;  // squared 1.0f exactly
  options.max_range = 2e11;
  const double t0 = 100.0;
  std::vector<TimedPoint> cloud;
  int order_sensitive = 0;  // points another summation order of the squared range moves
  for (int i = 0; i < 20000; ++i) {
    TimedPoint tp;
    switch (pick(rng)) {
      case 0: {  // squared range within a few roundings of the minimum
        Eigen::Vector3f d(u(rng), u(rng), u(rng));
        d.normalize();
        tp.p = d * (1.f + 6e-8f * static_cast<float>(i % 7 - 3));
        const float x = tp.p.x(), y = tp.p.y(), z = tp.p.z();
        order_sensitive += (x * x + (y * y + z * z) >= 1.f) != ((x * x + y * y) + z * z >= 1.f);
        break;
      }
      case 1:  // on voxel faces, both signs
        tp.p = Eigen::Vector3f(0.5f * static_cast<float>(i % 41 - 20),
                               0.5f * static_cast<float>(i % 13 - 6), -0.5f);
        break;
      case 2:  // beyond 2^30 voxels on one axis, kept by the wide range bound
        tp.p = Eigen::Vector3f(6e8f * u(rng), 3.f, 1e3f * u(rng));
        break;
      default:
        tp.p = Eigen::Vector3f(60.f * u(rng), 60.f * u(rng), 5.f * u(rng));
    }
    tp.intensity = static_cast<float>(i % 100);
    const int tk = i % 9;
    tp.t = tk == 0   ? t0 + 0.05 * (i % 20)  // bucket edges
           : tk == 1 ? t0 + 1e300            // absurd: the last bucket
           : tk == 2 ? std::nan("")
                     : t0 + 0.1 * std::abs(u(rng));
    cloud.push_back(tp);
  }
  ASSERT_GT(order_sensitive, 20);
  for (const size_t stride : {1, 3}) {
    for (const size_t begin : {0, 1, 7}) {
      const size_t end = cloud.size() / stride - 2;
      std::vector<uint64_t> ks(end - begin + 4), kv(end - begin + 4);
      std::vector<uint32_t> is(end - begin + 4), iv(end - begin + 4);
      const size_t ns =
          detail::GridKeys(false, cloud, begin, end, stride, t0, options, ks.data(), is.data());
      const size_t nv =
          detail::GridKeys(true, cloud, begin, end, stride, t0, options, kv.data(), iv.data());
      ASSERT_EQ(nv, ns) << "stride " << stride << ", begin " << begin;
      ASSERT_LT(ns, end - begin) << "some points fall out of range";
      for (size_t j = 0; j < ns; ++j) {
        ASSERT_EQ(iv[j], is[j]) << j;
        ASSERT_EQ(kv[j], ks[j]) << "point " << begin + is[j];
      }
    }
  }
}

}  // namespace
}  // namespace ppf
