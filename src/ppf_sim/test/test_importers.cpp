#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "ppf_bag/bag.hpp"
#include "ppf_sim/importers.hpp"

namespace ppf::sim {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("ppf_sim_imp_" + std::to_string(getpid()) + "_" + name);
  fs::remove_all(p);
  return p;
}

std::vector<bag::Message> ReadAll(const fs::path& dir) {
  bag::Reader r(dir.string());
  std::vector<bag::Message> out;
  bag::Message m;
  while (r.Next(m)) out.push_back(m);
  return out;
}

TEST(KittiImport, TimestampParsing) {
  EXPECT_EQ(ParseKittiTimestamp("2011-09-26 13:02:25.964389445"), 1317042145964389445LL);
  EXPECT_EQ(ParseKittiTimestamp("2011-09-26 13:02:25.9"), 1317042145900000000LL);
  EXPECT_THROW(ParseKittiTimestamp("yesterday"), std::runtime_error);
  // Clockwise sweep from behind: left (+y) a quarter in, ahead half, right three quarters.
  EXPECT_NEAR(AzimuthTime(0, 5, 0.1), 0.025, 1e-12);
  EXPECT_NEAR(AzimuthTime(5, 0, 0.1), 0.05, 1e-12);
  EXPECT_NEAR(AzimuthTime(0, -5, 0.1), 0.075, 1e-12);
}

// A three-scan drive in KITTI raw layout, written by the test.
TEST(KittiImport, SyntheticDriveRoundTrip) {
  const fs::path raw = TempDir("kitti_raw") / "2011_09_26_drive_0001_extract";
  const fs::path out = TempDir("kitti_bag");
  fs::create_directories(raw / "velodyne_points" / "data");
  fs::create_directories(raw / "oxts" / "data");
  const char* starts[] = {"2011-09-26 13:02:25.900000000", "2011-09-26 13:02:26.000000000",
                          "2011-09-26 13:02:26.100000000"};
  std::ofstream ts(raw / "velodyne_points" / "timestamps_start.txt");
  std::ofstream te(raw / "velodyne_points" / "timestamps_end.txt");
  std::ofstream tm(raw / "velodyne_points" / "timestamps.txt");
  for (int s = 0; s < 3; ++s) {
    ts << starts[s] << "\n";
    te << "2011-09-26 13:02:" << (s == 0 ? "26.000000000" : s == 1 ? "26.100000000" : "26.200000000") << "\n";
    tm << "2011-09-26 13:02:" << (s == 0 ? "25.950000000" : s == 1 ? "26.050000000" : "26.150000000") << "\n";
    char name[32];
    std::snprintf(name, sizeof(name), "%010d.bin", s);
    std::ofstream bin(raw / "velodyne_points" / "data" / name, std::ios::binary);
    const float pts[4][4] = {{0, 5, 0, 0.1f}, {5, 0, -1, 0.2f}, {0, -5, 0.5f, 0.3f}, {-5, 0.01f, 0, 0.4f}};
    for (int i = 0; i < 4; ++i) bin.write(reinterpret_cast<const char*>(pts[i]), sizeof(pts[i]));
  }
  ts.close();
  te.close();
  tm.close();
  std::ofstream ot(raw / "oxts" / "timestamps.txt");
  for (int i = 0; i < 30; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%010d.txt", i);
    std::ofstream f(raw / "oxts" / "data" / name);
    // lat, lon (moving east ~1.1 m per sample at this latitude), alt, roll, pitch, yaw, ...
    for (int k = 0; k < 30; ++k) {
      const double v = k == 0 ? 49.0 : k == 1 ? 8.4 + 1e-5 * i : k == 2 ? 110.0 : k == 5 ? 0.3
                     : k == 11 ? 0.5 + i : k == 13 ? 9.8 : k == 19 ? 0.01 * i : 0.0;
      f << std::setprecision(12) << v << (k < 29 ? " " : "\n");
    }
    char t[64];
    std::snprintf(t, sizeof(t), "2011-09-26 13:02:%02d.%09d", 25 + (90 + i) / 100, ((90 + i) % 100) * 10000000);  // 100 Hz
    ot << t << "\n";
  }
  ot.close();

  const ImportSummary s = ImportKittiRaw(raw.string(), out.string(), BagOutputOptions{}, KittiOptions{});
  EXPECT_EQ(s.clouds, 3);
  EXPECT_EQ(s.imu_samples, 30);
  const auto msgs = ReadAll(out);
  ASSERT_EQ(msgs.size(), 33u);
  int clouds = 0, imus = 0;
  for (const auto& m : msgs) {
    std::string err;
    if (m.topic == "/points") {
      CloudBuffer c;
      ASSERT_TRUE(DecodePointCloud2(m.data.data(), m.data.size(), &c, &err)) << err;
      EXPECT_EQ(c.stamp_ns, ParseKittiTimestamp(starts[clouds]));
      EXPECT_EQ(m.timestamp_ns, c.stamp_ns + 100000000LL);  // timestamps_end
      ASSERT_EQ(c.width, 4u);
      const PointFieldDesc* t = c.Field("time");
      ASSERT_NE(t, nullptr);
      EXPECT_NEAR(c.Get<float>(0, *t), 0.025f, 1e-6);
      EXPECT_NEAR(c.Get<float>(1, *t), 0.05f, 1e-6);
      EXPECT_NEAR(c.Get<float>(2, *t), 0.075f, 1e-6);
      EXPECT_NEAR(c.Get<float>(3, *t), 0.0f, 1e-3);
      EXPECT_FLOAT_EQ(c.Get<float>(2, *c.Field("intensity")), 0.3f);
      EXPECT_FLOAT_EQ(c.Get<float>(1, *c.Field("z")), -1.0f);
      ++clouds;
    } else {
      ImuMessage im;
      ASSERT_TRUE(DecodeImu(m.data.data(), m.data.size(), &im, &err)) << err;
      EXPECT_DOUBLE_EQ(im.accel[0], 0.5 + imus);
      EXPECT_DOUBLE_EQ(im.accel[2], 9.8);
      EXPECT_DOUBLE_EQ(im.gyro[2], 0.01 * imus);
      EXPECT_EQ(im.stamp_ns, ParseKittiTimestamp("2011-09-26 13:02:25.900000000") + imus * 10000000LL);
      ++imus;
    }
  }
  EXPECT_EQ(clouds, 3);
  EXPECT_EQ(imus, 30);
  // Ground truth from OXTS: starts at the origin, moves east, yaw 0.3 rad.
  std::ifstream gt(out / "groundtruth.tum");
  std::string line;
  std::getline(gt, line);
  EXPECT_EQ(line[0], '#');
  std::vector<std::vector<double>> rows;
  while (std::getline(gt, line)) {
    std::istringstream ss(line);
    std::vector<double> v(8);
    for (double& x : v) ss >> x;
    rows.push_back(v);
  }
  ASSERT_EQ(rows.size(), 30u);
  EXPECT_NEAR(rows[0][1], 0.0, 1e-6);
  const double east_per_sample = std::cos(49.0 * M_PI / 180) * 6378137.0 * 1e-5 * M_PI / 180;
  EXPECT_NEAR(rows[29][1], 29 * east_per_sample, 1e-3);
  EXPECT_NEAR(rows[29][2], 0.0, 1e-6);
  EXPECT_NEAR(2 * std::atan2(rows[29][6], rows[29][7]), 0.3, 1e-9);  // qz, qw of a pure yaw
  fs::remove_all(raw.parent_path());
  fs::remove_all(out);
}

TEST(KittiImport, RejectsAFolderWithoutScans) {
  const fs::path raw = TempDir("kitti_empty");
  fs::create_directories(raw);
  EXPECT_THROW(ImportKittiRaw(raw.string(), (raw / "bag").string(), BagOutputOptions{}, KittiOptions{}),
               std::runtime_error);
  fs::remove_all(raw);
}

TEST(PcdImport, StampsFromFileNames) {
  int64_t ns = 0;
  ASSERT_TRUE(StampFromFileName("/x/1673403880898440686.pcd", &ns));
  EXPECT_EQ(ns, 1673403880898440686LL);
  ASSERT_TRUE(StampFromFileName("1673403880.5.pcd", &ns));
  EXPECT_EQ(ns, 1673403880500000000LL);
  ASSERT_TRUE(StampFromFileName("2021-10-26-16-21-29-468.pcd", &ns));
  EXPECT_EQ(ns, 1635265289468000000LL);
  EXPECT_FALSE(StampFromFileName("scan_0001.pcd", &ns));
}

// Five real Pandar64 scans (binary_compressed, per-point F64 timestamp and ring).
TEST(PcdImport, RealPandar64Scans) {
  const fs::path dir = fs::path(PPF_SHARED_DIR) / "data/real/pjlab_pandar64_ins/top_center_lidar";
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data not found at " << dir << " (PPF_SHARED_DIR)";
  const fs::path out = TempDir("pcd_bag");
  const fs::path csv = TempDir("imu_csv");
  {
    std::ofstream f(csv);
    f << "t,wx,wy,wz,ax,ay,az\n";
    for (int i = 0; i < 20; ++i) f << 1635236489.40 + 0.025 * i << ",0.01,0.02,0.03,0.1,0.2,9.81\n";
  }
  PcdOptions opt;
  opt.imu_csv = csv.string();
  const ImportSummary s = ImportPcdDirectory(dir.string(), out.string(), BagOutputOptions{}, opt);
  EXPECT_EQ(s.clouds, 5);
  EXPECT_EQ(s.imu_samples, 20);
  const CloudBuffer first = LoadPcd((dir / "2021-10-26-16-21-29-468.pcd").string());
  EXPECT_EQ(first.width, 80787u);
  const auto msgs = ReadAll(out);
  int clouds = 0;
  int64_t prev = 0;
  for (const auto& m : msgs) {
    if (m.topic != "/points") continue;
    CloudBuffer c;
    std::string err;
    ASSERT_TRUE(DecodePointCloud2(m.data.data(), m.data.size(), &c, &err)) << err;
    const PointFieldDesc* ts = c.Field("timestamp");
    ASSERT_NE(ts, nullptr);
    EXPECT_EQ(ts->datatype, kFloat64);
    ASSERT_NE(c.Field("ring"), nullptr);
    EXPECT_EQ(c.Field("ring")->datatype, kUint16);
    double tmin = 1e300, tmax = 0;
    for (size_t i = 0; i < c.num_points(); ++i) {
      tmin = std::min(tmin, c.Get<double>(i, *ts));
      tmax = std::max(tmax, c.Get<double>(i, *ts));
    }
    EXPECT_NEAR(c.stamp_ns * 1e-9, tmin, 1e-6);  // header stamp = scan start
    EXPECT_GT(tmax - tmin, 0.08);
    EXPECT_LT(tmax - tmin, 0.12);
    if (clouds == 0) {
      EXPECT_EQ(c.width, first.width);
      EXPECT_TRUE(c.data == first.data);
    } else {
      EXPECT_NEAR((c.stamp_ns - prev) * 1e-9, 0.1, 0.01);
    }
    prev = c.stamp_ns;
    ++clouds;
  }
  EXPECT_EQ(clouds, 5);
  fs::remove_all(out);
  fs::remove(csv);
}

// Sweeps without any time (already motion-compensated keyframes): the times come from a
// TUM file's first column (its comment line skipped) or from --rate; with neither, a clear error.
TEST(PcdImport, StampsFromTumFileOrRate) {
  const fs::path dir = TempDir("pcd_untimed");
  fs::create_directories(dir);
  for (int i = 0; i < 3; ++i) {
    std::ofstream f(dir / ("scan_00" + std::to_string(i) + ".pcd"));
    f << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
         "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
  }
  const fs::path tum = TempDir("untimed_poses.tum");
  {
    std::ofstream f(tum);
    f << "# timestamp tx ty tz qx qy qz qw\n";
    f << std::fixed << std::setprecision(6);
    for (int i = 0; i < 3; ++i) f << 1630577758.5 + 0.5 * i << " 0 0 0 0 0 0 1\n";
  }
  auto stamps = [](const fs::path& bag) {
    std::vector<int64_t> out;
    for (const auto& m : ReadAll(bag)) {
      if (m.topic != "/points") continue;
      CloudBuffer c;
      std::string err;
      EXPECT_TRUE(DecodePointCloud2(m.data.data(), m.data.size(), &c, &err)) << err;
      out.push_back(c.stamp_ns);
    }
    return out;
  };
  PcdOptions opt;
  opt.stamps_file = tum.string();
  const fs::path out1 = TempDir("untimed_bag_tum");
  ImportPcdDirectory(dir.string(), out1.string(), BagOutputOptions{}, opt);
  EXPECT_EQ(stamps(out1), (std::vector<int64_t>{1630577758500000000LL, 1630577759000000000LL,
                                                1630577759500000000LL}));
  opt = PcdOptions();
  opt.rate_hz = 2.0;
  const fs::path out2 = TempDir("untimed_bag_rate");
  ImportPcdDirectory(dir.string(), out2.string(), BagOutputOptions{}, opt);
  EXPECT_EQ(stamps(out2), (std::vector<int64_t>{0, 500000000LL, 1000000000LL}));
  const fs::path out3 = TempDir("untimed_bag_none");
  EXPECT_THROW(ImportPcdDirectory(dir.string(), out3.string(), BagOutputOptions{}, PcdOptions()),
               std::runtime_error);
  for (const fs::path& p : {dir, tum, out1, out2, out3}) fs::remove_all(p);
}

}  // namespace
}  // namespace ppf::sim
