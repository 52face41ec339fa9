// MCAP interop with an independent implementation: @mcap/core + @foxglove/rosmsg2-serialization
// (node scripts in test/js). Skips if node or test/js/node_modules is missing.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <sstream>

#include "ppf_bag/bag.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace ppf::bag;
using ppf::bag::test::ReadAll;
using ppf::bag::test::Run;
using ppf::bag::test::ShellQuote;
using ppf::bag::test::TempDir;

namespace {

std::string NodeSkipReason() {
  if (std::string(NODE_EXECUTABLE).empty()) return "node not found at configure time";
  const fs::path js = PPF_BAG_JS_DIR;
  if (js.empty()) {
    return "PPF_JS_DIR not set (configure with -DPPF_JS_DIR=<workspace>/test/js, as "
           "scripts/setup.sh does)";
  }
  if (!fs::exists(js / "node_modules/@mcap/core") ||
      !fs::exists(js / "node_modules/@foxglove/rosmsg2-serialization")) {
    return "node_modules missing in " + js.string() + " (run: npm ci --prefix " + js.string() + ")";
  }
  return {};
}

std::string Node(const std::string& script, const std::string& args, int* code = nullptr) {
  const std::string cmd = std::string(NODE_EXECUTABLE) + " " +
                          ShellQuote(std::string(PPF_BAG_JS_DIR) + "/" + script) + " " + args;
  const auto r = Run(cmd);
  if (code) {
    *code = r.exit_code;
  } else {
    EXPECT_EQ(r.exit_code, 0) << cmd << "\n" << r.output;
  }
  return r.output;
}

// Shortest round-trip formatting; matches JavaScript's Number#toString for the dyadic values
// used here (0.5, -2, 9.75, ...).
std::string Num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

template <size_t N>
std::string Arr(const double (&a)[N]) {
  std::string s = "[";
  for (size_t i = 0; i < N; ++i) s += (i ? "," : "") + Num(a[i]);
  return s + "]";
}

std::string Vec3(const double (&a)[3]) {
  return "{\"x\":" + Num(a[0]) + ",\"y\":" + Num(a[1]) + ",\"z\":" + Num(a[2]) + "}";
}

std::string ImuJson(const std::string& topic, int64_t t, const test::Imu& m) {
  return "{\"topic\":\"" + topic + "\",\"schema\":\"sensor_msgs/msg/Imu\",\"log_time\":\"" +
         std::to_string(t) + "\",\"message\":{\"header\":{\"stamp\":{\"sec\":" + std::to_string(m.sec) +
         ",\"nanosec\":" + std::to_string(m.nanosec) + "},\"frame_id\":\"" + m.frame_id +
         "\"},\"orientation\":{\"x\":" + Num(m.orientation[0]) + ",\"y\":" + Num(m.orientation[1]) +
         ",\"z\":" + Num(m.orientation[2]) + ",\"w\":" + Num(m.orientation[3]) +
         "},\"orientation_covariance\":" + Arr(m.orientation_cov) +
         ",\"angular_velocity\":" + Vec3(m.angular_velocity) +
         ",\"angular_velocity_covariance\":" + Arr(m.angular_velocity_cov) +
         ",\"linear_acceleration\":" + Vec3(m.linear_acceleration) +
         ",\"linear_acceleration_covariance\":" + Arr(m.linear_acceleration_cov) + "}}";
}

std::vector<std::string> Lines(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

// A 3-point PointCloud2 (x,y,z float32) built by hand.
std::vector<uint8_t> EncodeCloud(uint32_t sec, std::vector<uint8_t>& points_out) {
  test::CdrWriter w;
  w.I32(static_cast<int32_t>(sec));
  w.U32(0);
  w.Str("lidar");
  w.U32(1);  // height
  w.U32(3);  // width
  w.U32(3);  // fields
  const char* names[3] = {"x", "y", "z"};
  for (uint32_t i = 0; i < 3; ++i) {
    w.Str(names[i]);
    w.U32(4 * i);
    w.U8(7);  // FLOAT32
    w.U32(1);
  }
  w.Bool(false);
  w.U32(12);
  w.U32(36);
  points_out.clear();
  for (int p = 0; p < 3; ++p) {
    for (int c = 0; c < 3; ++c) {
      const float v = 0.5f * static_cast<float>(p) + static_cast<float>(c) + static_cast<float>(sec);
      const auto* b = reinterpret_cast<const uint8_t*>(&v);
      points_out.insert(points_out.end(), b, b + 4);
    }
  }
  w.Bytes(points_out);
  w.Bool(true);
  return w.data();
}

class NodeReadsOurs : public ::testing::TestWithParam<const char*> {};

TEST_P(NodeReadsOurs, DecodedFieldsMatch) {
  const std::string skip = NodeSkipReason();
  if (!skip.empty()) GTEST_SKIP() << skip;
  TempDir tmp;
  const std::string dir = tmp / "ours";
  WriterOptions opt;
  opt.compression = GetParam();
  opt.chunk_size = 700;  // several chunks
  std::vector<std::string> expected;
  {
    Writer w(dir, opt);
    w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", ""});
    w.AddTopic({"/points", "sensor_msgs/msg/PointCloud2", "cdr", ""});
    // Clouds written first but stamped later than most IMU samples: the dump is time ordered.
    std::vector<std::pair<int64_t, std::string>> lines;
    for (uint32_t k = 0; k < 2; ++k) {
      std::vector<uint8_t> pts;
      const auto cdr = EncodeCloud(20 + k, pts);
      const int64_t t = (20 + k) * 1000000000LL + 500;
      w.Write("/points", t, cdr);
      char fnv[16];
      std::snprintf(fnv, sizeof(fnv), "%08x", test::Fnv1a(pts));
      lines.push_back(
          {t, "{\"topic\":\"/points\",\"schema\":\"sensor_msgs/msg/PointCloud2\",\"log_time\":\"" +
                  std::to_string(t) + "\",\"message\":{\"header\":{\"stamp\":{\"sec\":" +
                  std::to_string(20 + k) +
                  ",\"nanosec\":0},\"frame_id\":\"lidar\"},\"height\":1,\"width\":3,\"fields\":["
                  "{\"name\":\"x\",\"offset\":0,\"datatype\":7,\"count\":1},"
                  "{\"name\":\"y\",\"offset\":4,\"datatype\":7,\"count\":1},"
                  "{\"name\":\"z\",\"offset\":8,\"datatype\":7,\"count\":1}],"
                  "\"is_bigendian\":false,\"point_step\":12,\"row_step\":36,\"data\":{\"length\":36,"
                  "\"fnv1a\":\"" + std::string(fnv) + "\"},\"is_dense\":true}}"});
    }
    for (int i = 0; i < 12; ++i) {
      test::Imu m;
      m.sec = 18 + i / 4;
      m.nanosec = static_cast<uint32_t>((i % 4) * 250000000);
      m.frame_id = "imu_link";
      m.orientation[2] = 0.5;
      m.orientation[3] = -0.75;
      for (int k = 0; k < 9; ++k) m.orientation_cov[k] = k == 0 ? -1 : 0;
      m.angular_velocity[0] = 0.125 * i;
      m.angular_velocity[1] = -2;
      m.angular_velocity[2] = 1e-3 * 1024;  // not a short decimal: exercises number formatting
      m.angular_velocity_cov[4] = 0.25;
      m.linear_acceleration[2] = 9.75 + i;
      m.linear_acceleration_cov[8] = 3;
      const int64_t t = m.sec * 1000000000LL + m.nanosec;
      w.Write("/imu", t, test::EncodeImu(m));
      lines.push_back({t, ImuJson("/imu", t, m)});
    }
    w.Close();
    std::stable_sort(lines.begin(), lines.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (auto& l : lines) expected.push_back(l.second);
  }
  const std::string file = dir + "/ours_0.mcap";
  for (const char* mode : {"", " --stream"}) {
    const auto got = Lines(Node("mcap_dump.mjs", ShellQuote(file) + mode));
    ASSERT_EQ(got.size(), expected.size()) << "mode '" << mode << "'";
    for (size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i], expected[i]) << "line " << i << mode;
  }
}

INSTANTIATE_TEST_SUITE_P(Compression, NodeReadsOurs, ::testing::Values("none", "lz4", "zstd"));

struct NodeCase {
  const char* name;
  const char* args;
};

void PrintTo(const NodeCase& c, std::ostream* os) { *os << c.name; }

class WeReadNode : public ::testing::TestWithParam<NodeCase> {};

TEST_P(WeReadNode, ValuesMatchScript) {
  const std::string skip = NodeSkipReason();
  if (!skip.empty()) GTEST_SKIP() << skip;
  TempDir tmp;
  const std::string file = tmp / "node.mcap";
  Node("mcap_write.mjs", ShellQuote(file) + " --count 7 " + GetParam().args);
  Reader r(file);
  const BagInfo& info = r.Info();
  EXPECT_EQ(info.storage, Storage::kMcap);
  EXPECT_EQ(info.message_count, 7u);
  ASSERT_EQ(info.topics.size(), 1u);
  EXPECT_EQ(info.topics[0].info.name, "/imu");
  EXPECT_EQ(info.topics[0].info.type, "sensor_msgs/msg/Imu");
  EXPECT_EQ(info.topics[0].info.serialization_format, "cdr");
  EXPECT_EQ(info.topics[0].message_count, 7u);
  EXPECT_EQ(info.start_ns, 1700000000250000000LL);
  EXPECT_EQ(info.end_ns, 1700000006250000000LL);
  const auto msgs = ReadAll(r);
  ASSERT_EQ(msgs.size(), 7u);
  for (int i = 0; i < 7; ++i) {
    const auto& msg = msgs[static_cast<size_t>(i)];
    EXPECT_EQ(msg.topic, "/imu");
    EXPECT_EQ(msg.timestamp_ns, (1700000000LL + i) * 1000000000LL + 250000000LL);
    const test::Imu m = test::DecodeImu(msg.data);
    EXPECT_EQ(m.sec, 1700000000 + i);
    EXPECT_EQ(m.nanosec, 250000000u);
    EXPECT_EQ(m.frame_id, "imu_link");
    EXPECT_EQ(m.orientation[3], 1.0);
    EXPECT_EQ(m.orientation[0], 0.0);
    for (int k = 0; k < 9; ++k) EXPECT_EQ(m.orientation_cov[k], 0.5 * k);
    EXPECT_EQ(m.angular_velocity[0], 0.25 * i);
    EXPECT_EQ(m.angular_velocity[1], -0.5);
    EXPECT_EQ(m.angular_velocity[2], 1.5);
    EXPECT_EQ(m.linear_acceleration[0], 0.125);
    EXPECT_EQ(m.linear_acceleration[2], 9.75 + i);
    EXPECT_EQ(m.linear_acceleration_cov[0], -1.0);
  }
  // Seek into the middle works on a foreign file too.
  r.Seek(1700000004000000000LL);
  ppf::bag::Message m;
  ASSERT_TRUE(r.Next(m));
  EXPECT_EQ(m.timestamp_ns, 1700000004250000000LL);
}

INSTANTIATE_TEST_SUITE_P(Variants, WeReadNode,
                         ::testing::Values(NodeCase{"chunked_none", "--compression none"},
                                           NodeCase{"chunked_lz4", "--compression lz4"},
                                           NodeCase{"chunked_zstd", "--compression zstd"},
                                           NodeCase{"small_chunks_zstd",
                                                    "--compression zstd --chunk-size 300"},
                                           NodeCase{"unchunked", "--no-chunks"}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(NodeDump, RejectsCorruptFile) {
  const std::string skip = NodeSkipReason();
  if (!skip.empty()) GTEST_SKIP() << skip;
  TempDir tmp;
  test::WriteFileBytes(tmp / "x.mcap", {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n', 1, 2, 3});
  int code = 0;
  Node("mcap_dump.mjs", ShellQuote(tmp / "x.mcap") + " 2>/dev/null", &code);
  EXPECT_NE(code, 0) << "the independent reader must not accept garbage, or it proves nothing";
}

}  // namespace

namespace {

// Every schema text we write parses in @foxglove/rosmsg with all nested types resolved (it throws
// on a missing dependency) and round-trips a default message through rosmsg2-serialization.
TEST(NodeSchemas, AllRequiredDefinitionsParse) {
  const std::string skip = NodeSkipReason();
  if (!skip.empty()) GTEST_SKIP() << skip;
  const std::pair<const char*, const char*> kTypes[] = {
      {"sensor_msgs/msg/PointCloud2",
       "[\"header\",\"height\",\"width\",\"fields\",\"is_bigendian\",\"point_step\",\"row_step\","
       "\"data\",\"is_dense\"]"},
      {"sensor_msgs/msg/Imu",
       "[\"header\",\"orientation\",\"orientation_covariance\",\"angular_velocity\","
       "\"angular_velocity_covariance\",\"linear_acceleration\",\"linear_acceleration_covariance\"]"},
      {"nav_msgs/msg/Odometry", "[\"header\",\"child_frame_id\",\"pose\",\"twist\"]"},
      {"nav_msgs/msg/Path", "[\"header\",\"poses\"]"},
      {"tf2_msgs/msg/TFMessage", "[\"transforms\"]"},
      {"geometry_msgs/msg/PoseStamped", "[\"header\",\"pose\"]"},
      {"ppf_msgs/msg/SkeletonPlaneArray", "[\"header\",\"planes\"]"},
  };
  TempDir tmp;
  {
    Writer w(tmp / "schemas", WriterOptions());
    for (const auto& [type, fields] : kTypes) w.AddTopic({std::string("/") + type, type, "cdr", ""});
    w.AddTopic({"/unknown", "x_msgs/msg/Nope", "cdr", ""});
  }
  const auto lines = Lines(Node("mcap_dump.mjs", ShellQuote(tmp / "schemas/schemas_0.mcap") + " --schemas"));
  ASSERT_EQ(lines.size(), 8u);
  for (size_t i = 0; i < 7; ++i) {
    const std::string prefix = std::string("{\"schema\":\"") + kTypes[i].first +
                               "\",\"encoding\":\"ros2msg\",\"fields\":" + kTypes[i].second +
                               ",\"default_size\":";
    EXPECT_EQ(lines[i].rfind(prefix, 0), 0u) << lines[i];
  }
  EXPECT_EQ(lines[7], "{\"schema\":\"x_msgs/msg/Nope\",\"encoding\":\"\",\"fields\":[],\"default_size\":0}");
}

}  // namespace
