// Decodes our MCAP with an independent implementation (@mcap/core + @foxglove/rosmsg2-serialization
// through test/js/mcap_dump.mjs) and compares it field by field with what the generator made.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "ppf_sim/simulation.hpp"

namespace ppf::sim {
namespace {

namespace fs = std::filesystem;

std::string Fnv1a(const std::vector<uint8_t>& bytes) {
  uint32_t h = 0x811c9dc5u;
  for (uint8_t b : bytes) h = (h ^ b) * 0x01000193u;
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%08x", h);
  return buf;
}

double Num(const std::string& json, const std::string& object, const std::string& key) {
  const std::regex re("\"" + object + "\":\\{[^}]*\"" + key + "\":([-0-9.eE+]+)");
  std::smatch m;
  if (!std::regex_search(json, m, re)) {
    ADD_FAILURE() << object << "." << key << " not in " << json.substr(0, 300);
    return 0.0;
  }
  return std::strtod(m[1].str().c_str(), nullptr);
}

TEST(JsInterop, McapDecodedByFoxgloveMatchesFieldByField) {
  if (std::string(PPF_JS_DIR).empty())
    GTEST_SKIP() << "PPF_JS_DIR not set (configure with -DPPF_JS_DIR=<workspace>/test/js, as "
                    "scripts/setup.sh does)";
  const fs::path js = fs::path(PPF_JS_DIR);
  if (!fs::exists(js / "mcap_dump.mjs") || !fs::exists(js / "node_modules"))
    GTEST_SKIP() << "test/js or its node_modules missing (npm ci --prefix test/js)";
  if (std::system("node --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "node not found";

  for (const std::string lidar : {"vlp16", "os1_64"}) {
    const fs::path dir = fs::temp_directory_path() / ("ppf_sim_js_" + std::to_string(getpid()) + lidar);
    fs::remove_all(dir);
    SimConfig cfg;
    cfg.world.duration = 3.0;
    cfg.lidar = lidar;
    cfg.seed = 8;
    cfg.out_dir = dir.string();
    std::ostringstream log;
    RunSimulation(cfg, log);
    const fs::path dump = dir / "dump.jsonl";
    const std::string cmd = "node " + (js / "mcap_dump.mjs").string() + " " +
                            (dir / (dir.filename().string() + "_0.mcap")).string() + " > " + dump.string();
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;

    WorldOptions wo = cfg.world;
    wo.seed = cfg.seed;
    const World world = BuildWorld(wo);
    ScanOptions so = cfg.scan;
    so.seed = cfg.seed;
    so.start_ns = cfg.start_ns;
    const ScanGenerator gen(world.scene, world.trajectory, GetLidarModel(lidar), so);
    const auto imu = SimulateImu(world.trajectory, cfg.imu_rate, cfg.world.duration, cfg.imu_noise, cfg.seed);

    std::ifstream in(dump);
    std::string line;
    int clouds = 0, imus = 0;
    while (std::getline(in, line)) {
      if (line.find("\"topic\":\"/points\"") != std::string::npos) {
        EXPECT_NE(line.find("\"schema\":\"sensor_msgs/msg/PointCloud2\""), std::string::npos);
        if (clouds == 3) {
          const CloudBuffer c = gen.Generate(3);
          std::ostringstream fields;
          fields << "\"fields\":[";
          for (size_t k = 0; k < c.fields.size(); ++k) {
            fields << (k ? "," : "") << "{\"name\":\"" << c.fields[k].name << "\",\"offset\":"
                   << c.fields[k].offset << ",\"datatype\":" << int(c.fields[k].datatype)
                   << ",\"count\":" << c.fields[k].count << "}";
          }
          fields << "]";
          const std::string expect_head =
              "\"header\":{\"stamp\":{\"sec\":1700000000,\"nanosec\":300000000},\"frame_id\":\"lidar\"},"
              "\"height\":" + std::to_string(c.height) + ",\"width\":" + std::to_string(c.width) + "," +
              fields.str() + ",\"is_bigendian\":false,\"point_step\":" + std::to_string(c.point_step) +
              ",\"row_step\":" + std::to_string(c.row_step) + ",\"data\":{\"length\":" +
              std::to_string(c.data.size()) + ",\"fnv1a\":\"" + Fnv1a(c.data) + "\"},\"is_dense\":" +
              (c.is_dense ? "true" : "false");
          EXPECT_NE(line.find(expect_head), std::string::npos) << lidar << "\nexpected " << expect_head
                                                                << "\nin " << line;
          EXPECT_NE(line.find("\"log_time\":\"1700000000400000000\""), std::string::npos);
        }
        ++clouds;
      } else {
        EXPECT_NE(line.find("\"schema\":\"sensor_msgs/msg/Imu\""), std::string::npos);
        if (imus == 321) {
          EXPECT_EQ(Num(line, "angular_velocity", "x"), imu[imus].gyro.x());
          EXPECT_EQ(Num(line, "angular_velocity", "y"), imu[imus].gyro.y());
          EXPECT_EQ(Num(line, "angular_velocity", "z"), imu[imus].gyro.z());
          EXPECT_EQ(Num(line, "linear_acceleration", "x"), imu[imus].accel.x());
          EXPECT_EQ(Num(line, "linear_acceleration", "y"), imu[imus].accel.y());
          EXPECT_EQ(Num(line, "linear_acceleration", "z"), imu[imus].accel.z());
          EXPECT_EQ(Num(line, "stamp", "nanosec"), 605000000.0);
          EXPECT_NE(line.find("\"orientation_covariance\":[-1,0,0,0,0,0,0,0,0]"), std::string::npos);
        }
        ++imus;
      }
    }
    EXPECT_EQ(clouds, 30) << lidar;
    EXPECT_EQ(imus, 601) << lidar;
    fs::remove_all(dir);
  }
}

}  // namespace
}  // namespace ppf::sim
