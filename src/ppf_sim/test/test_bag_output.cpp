// The written bag must be readable by our reader with the right topics, types, counts, and
// the exact scan bytes the generator produced; the same seed must give the same files.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "ppf_bag/bag.hpp"
#include "ppf_sim/simulation.hpp"
#include "ppf_trajectory/trajectory_io.hpp"

namespace ppf::sim {
namespace {

namespace fs = std::filesystem;

std::string TempDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("ppf_sim_test_" + std::to_string(getpid()) + "_" + name);
  fs::remove_all(p);
  return p.string();
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

SimConfig ShortConfig(const std::string& out, const std::string& storage) {
  SimConfig cfg;
  cfg.world.scene = "urban";
  cfg.world.duration = 3.0;
  cfg.lidar = "vlp16";
  cfg.seed = 4;
  cfg.out_dir = out;
  cfg.bag.storage = storage;
  return cfg;
}

class SimBag : public ::testing::TestWithParam<std::string> {};

TEST_P(SimBag, ReadableWithRightCountsTypesAndBytes) {
  const std::string dir = TempDir("bag_" + GetParam());
  const SimConfig cfg = ShortConfig(dir, GetParam());
  std::ostringstream log;
  const SimSummary s = RunSimulation(cfg, log);
  EXPECT_EQ(s.scans, 30);
  EXPECT_EQ(s.imu_samples, 601);

  bag::Reader reader(dir);
  const bag::BagInfo& info = reader.Info();
  EXPECT_EQ(info.storage, GetParam() == "mcap" ? bag::Storage::kMcap : bag::Storage::kSqlite3);
  ASSERT_EQ(info.topics.size(), 2u);
  EXPECT_EQ(info.message_count, 631u);
  for (const auto& t : info.topics) {
    if (t.info.name == "/points") {
      EXPECT_EQ(t.info.type, "sensor_msgs/msg/PointCloud2");
      EXPECT_EQ(t.message_count, 30u);
    } else {
      EXPECT_EQ(t.info.name, "/imu");
      EXPECT_EQ(t.info.type, "sensor_msgs/msg/Imu");
      EXPECT_EQ(t.message_count, 601u);
    }
    EXPECT_EQ(t.info.serialization_format, "cdr");
  }

  // Regenerate scan 0 and IMU directly: the bag must hold exactly these.
  WorldOptions wo = cfg.world;
  wo.seed = cfg.seed;
  const World world = BuildWorld(wo);
  ScanOptions so = cfg.scan;
  so.seed = cfg.seed;
  so.start_ns = cfg.start_ns;
  const CloudBuffer scan0 = ScanGenerator(world.scene, world.trajectory, GetLidarModel("vlp16"), so).Generate(0);
  const auto imu = SimulateImu(world.trajectory, cfg.imu_rate, cfg.world.duration, cfg.imu_noise, cfg.seed);

  bag::Message m;
  int64_t last = INT64_MIN;
  int clouds = 0, imus = 0;
  while (reader.Next(m)) {
    EXPECT_GE(m.timestamp_ns, last);
    last = m.timestamp_ns;
    std::string err;
    if (m.topic == "/points") {
      CloudBuffer c;
      ASSERT_TRUE(DecodePointCloud2(m.data.data(), m.data.size(), &c, &err)) << err;
      EXPECT_EQ(c.stamp_ns, cfg.start_ns + clouds * 100000000LL);
      EXPECT_EQ(m.timestamp_ns, c.stamp_ns + 100000000LL);  // bag time = scan end
      EXPECT_EQ(c.frame_id, "lidar");
      if (clouds == 0) {
        EXPECT_EQ(c.width, scan0.width);
        EXPECT_EQ(c.point_step, 32u);
        ASSERT_EQ(c.fields.size(), scan0.fields.size());
        for (size_t k = 0; k < c.fields.size(); ++k) {
          EXPECT_EQ(c.fields[k].name, scan0.fields[k].name);
          EXPECT_EQ(c.fields[k].offset, scan0.fields[k].offset);
          EXPECT_EQ(c.fields[k].datatype, scan0.fields[k].datatype);
        }
        EXPECT_TRUE(c.data == scan0.data);
      }
      ++clouds;
    } else {
      ImuMessage im;
      ASSERT_TRUE(DecodeImu(m.data.data(), m.data.size(), &im, &err)) << err;
      EXPECT_EQ(im.stamp_ns, cfg.start_ns + imus * 5000000LL);
      EXPECT_EQ(im.frame_id, "imu");
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(im.gyro[k], imu[imus].gyro[k]);
        EXPECT_EQ(im.accel[k], imu[imus].accel[k]);
      }
      ++imus;
    }
  }
  EXPECT_EQ(clouds, 30);
  EXPECT_EQ(imus, 601);

  // Ground truth: one line per IMU sample, T_world_imu.
  std::ifstream gt(dir + "/groundtruth.tum");
  std::string line;
  std::getline(gt, line);
  EXPECT_EQ(line[0], '#');
  int rows = 0;
  while (std::getline(gt, line)) {
    std::istringstream fields(line);
    double v[8];
    for (double& x : v) fields >> x;
    EXPECT_GE(v[7], 0.0);  // qw: one sign per rotation
    if (rows == 250) {
      EXPECT_EQ(line, FormatTumLine(cfg.start_ns + 250 * 5000000LL, world.trajectory.Pose(1.25)));
    }
    ++rows;
  }
  EXPECT_EQ(rows, 601);
  const std::string cal = Slurp(dir + "/calibration.yaml");
  EXPECT_NE(cal.find("T_imu_lidar"), std::string::npos);
  EXPECT_NE(cal.find("translation: [0.2, 0.05, 0.15]"), std::string::npos);
  // calibration.yaml is a pure config overlay; the sequence description lives beside it.
  EXPECT_EQ(cal.find("\nlidar:"), std::string::npos);
  const std::string sequence = Slurp(dir + "/sequence.yaml");
  EXPECT_NE(sequence.find("\nlidar:"), std::string::npos);
  EXPECT_NE(sequence.find("header_stamp: scan_start"), std::string::npos);
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Storage, SimBag, ::testing::Values("mcap", "sqlite3"));

TEST(SimBagDeterminism, SameSeedSameFiles) {
  const std::string a = TempDir("det_a"), b = TempDir("det_b"), c = TempDir("det_c");
  std::ostringstream log;
  RunSimulation(ShortConfig(a, "mcap"), log);
  RunSimulation(ShortConfig(b, "mcap"), log);
  SimConfig other = ShortConfig(c, "mcap");
  other.seed = 5;
  RunSimulation(other, log);
  for (const char* f : {"groundtruth.tum", "calibration.yaml", "sequence.yaml", "imu_bias.csv"}) {
    EXPECT_EQ(Slurp(fs::path(a) / f), Slurp(fs::path(b) / f)) << f;
  }
  const std::string sa = Slurp(fs::path(a) / (fs::path(a).filename().string() + "_0.mcap"));
  const std::string sb = Slurp(fs::path(b) / (fs::path(b).filename().string() + "_0.mcap"));
  const std::string sc = Slurp(fs::path(c) / (fs::path(c).filename().string() + "_0.mcap"));
  ASSERT_GT(sa.size(), 100000u);
  // File names differ (they carry the directory name), contents must not.
  EXPECT_TRUE(sa == sb);
  EXPECT_FALSE(sa == sc);
  for (const auto& d : {a, b, c}) fs::remove_all(d);
}

}  // namespace
}  // namespace ppf::sim
