// Write -> read round trips for sqlite3 and MCAP (none/lz4/zstd, large and tiny chunks).
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <random>

#include "ppf_bag/bag.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace ppf::bag;
using ppf::bag::test::ReadAll;
using ppf::bag::test::TempDir;

namespace {

struct Case {
  const char* name;
  Storage storage;
  const char* compression;
  size_t chunk_size;
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

const Case kCases[] = {
    {"sqlite3", Storage::kSqlite3, "none", 0},
    {"mcap_none", Storage::kMcap, "none", 4 << 20},
    {"mcap_lz4", Storage::kMcap, "lz4", 4 << 20},
    {"mcap_zstd", Storage::kMcap, "zstd", 4 << 20},
    // Tiny chunks: one or two messages per chunk, many overlapping chunks to merge.
    {"mcap_none_tiny_chunks", Storage::kMcap, "none", 64},
    {"mcap_lz4_small_chunks", Storage::kMcap, "lz4", 3000},
    {"mcap_zstd_small_chunks", Storage::kMcap, "zstd", 3000},
};

struct Written {
  std::string topic;
  int64_t t;
  std::vector<uint8_t> data;
};

const char* kQos =
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: "
    "9223372036\n    nsec: 854775807\n";

// Writes three topics in an order that is NOT globally time sorted (topic by topic, with equal
// stamps across topics) and returns the messages in write order.
std::vector<Written> WriteBag(const std::string& dir, const Case& c) {
  WriterOptions opt;
  opt.storage = c.storage;
  opt.compression = c.compression;
  if (c.chunk_size) opt.chunk_size = c.chunk_size;
  Writer w(dir, opt);
  w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", kQos});
  w.AddTopic({"/points", "sensor_msgs/msg/PointCloud2", "cdr", ""});
  w.AddTopic({"/custom", "my_pkg/msg/Unknown", "cdr", ""});
  w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", kQos});  // identical re-add is a no-op
  std::vector<Written> out;
  std::mt19937 rng(42);
  for (int i = 0; i < 60; ++i) {
    ppf::bag::test::Imu imu;
    imu.sec = 100 + i / 10;
    imu.nanosec = static_cast<uint32_t>((i % 10) * 100000000);
    imu.frame_id = "imu";
    imu.angular_velocity[0] = 0.25 * i;
    imu.linear_acceleration[2] = 9.75;
    out.push_back({"/imu", 100000000000LL + i * 100000000LL, ppf::bag::test::EncodeImu(imu)});
  }
  for (int i = 0; i < 6; ++i) {
    // Compressible but not constant: a ramp with noise in the low bits.
    std::vector<uint8_t> data(4 + 5000 + i);
    data[1] = 1;
    for (size_t k = 4; k < data.size(); ++k) data[k] = static_cast<uint8_t>((k / 16) + (rng() & 3));
    // Equal stamps to /imu messages 0, 10, 20, ... (ties must keep write order: /imu first).
    out.push_back({"/points", 100000000000LL + i * 1000000000LL, data});
  }
  for (int i = 0; i < 5; ++i) {
    out.push_back({"/custom", 99000000000LL + i * 3000000000LL, {0, 1, 0, 0, uint8_t(i)}});
  }
  out.push_back({"/custom", 100000000000LL, {}});  // empty payload is preserved too
  for (const auto& m : out) w.Write(m.topic, m.t, m.data.data(), m.data.size());
  w.Close();
  w.Close();  // idempotent
  return out;
}

std::vector<Written> TimeOrder(std::vector<Written> v) {
  std::stable_sort(v.begin(), v.end(), [](const Written& a, const Written& b) { return a.t < b.t; });
  return v;
}

void ExpectSame(const std::vector<Message>& got, const std::vector<Written>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(got[i].topic, want[i].topic) << "message " << i;
    EXPECT_EQ(got[i].timestamp_ns, want[i].t) << "message " << i;
    EXPECT_EQ(got[i].data, want[i].data) << "message " << i;
  }
}

class RoundTrip : public ::testing::TestWithParam<Case> {};

TEST_P(RoundTrip, ExactBytesOrderAndCounts) {
  const Case& c = GetParam();
  TempDir tmp;
  const std::string dir = tmp / "bag";
  const auto written = WriteBag(dir, c);
  const auto expected = TimeOrder(written);

  Reader r(dir);
  const BagInfo& info = r.Info();
  EXPECT_EQ(info.storage, c.storage);
  EXPECT_EQ(info.message_count, written.size());
  EXPECT_EQ(info.start_ns, 99000000000LL);
  EXPECT_EQ(info.end_ns, 111000000000LL);  // last /custom message
  ASSERT_EQ(info.topics.size(), 3u);
  EXPECT_EQ(info.topics[0].info.name, "/imu");
  EXPECT_EQ(info.topics[0].info.type, "sensor_msgs/msg/Imu");
  EXPECT_EQ(info.topics[0].info.serialization_format, "cdr");
  EXPECT_EQ(info.topics[0].info.offered_qos_profiles, kQos);
  EXPECT_EQ(info.topics[0].message_count, 60u);
  EXPECT_EQ(info.topics[1].info.name, "/points");
  EXPECT_EQ(info.topics[1].info.type, "sensor_msgs/msg/PointCloud2");
  EXPECT_EQ(info.topics[1].message_count, 6u);
  EXPECT_EQ(info.topics[2].info.name, "/custom");
  EXPECT_EQ(info.topics[2].info.type, "my_pkg/msg/Unknown");
  EXPECT_EQ(info.topics[2].message_count, 6u);

  ExpectSame(ReadAll(r), expected);

  // Topic filter: only /points and /custom, still time ordered.
  r.SetTopicFilter({"/points", "/custom"});
  std::vector<Written> filtered;
  for (const auto& m : expected) {
    if (m.topic != "/imu") filtered.push_back(m);
  }
  ExpectSame(ReadAll(r), filtered);

  // Seek with the filter active: first /points or /custom message at or after 102 s.
  r.Seek(102000000000LL);
  std::vector<Written> after;
  for (const auto& m : filtered) {
    if (m.t >= 102000000000LL) after.push_back(m);
  }
  ExpectSame(ReadAll(r), after);

  // Clearing the filter rewinds to the last Seek position.
  r.SetTopicFilter({});
  std::vector<Written> all_after;
  for (const auto& m : expected) {
    if (m.t >= 102000000000LL) all_after.push_back(m);
  }
  ExpectSame(ReadAll(r), all_after);

  // Seek back to the beginning.
  r.Seek(0);
  ExpectSame(ReadAll(r), expected);

  EXPECT_THROW(r.SetTopicFilter({"/nope"}), BagError);

  // Same content when opening the storage file directly.
  const std::string ext = c.storage == Storage::kMcap ? ".mcap" : ".db3";
  ASSERT_TRUE(fs::exists(dir + "/bag_0" + ext));
  Reader direct(dir + "/bag_0" + ext);
  EXPECT_EQ(direct.Info().message_count, written.size());
  ExpectSame(ReadAll(direct), expected);
}

TEST_P(RoundTrip, MetadataYaml) {
  const Case& c = GetParam();
  TempDir tmp;
  const std::string dir = tmp / "bag";
  const auto written = WriteBag(dir, c);
  const YAML::Node m = YAML::LoadFile(dir + "/metadata.yaml")["rosbag2_bagfile_information"];
  ASSERT_TRUE(m);
  const bool mcap = c.storage == Storage::kMcap;
  EXPECT_EQ(m["version"].as<int>(), mcap ? 9 : 5);
  EXPECT_EQ(m["storage_identifier"].as<std::string>(), mcap ? "mcap" : "sqlite3");
  EXPECT_EQ(m["starting_time"]["nanoseconds_since_epoch"].as<int64_t>(), 99000000000LL);
  EXPECT_EQ(m["duration"]["nanoseconds"].as<int64_t>(), 111000000000LL - 99000000000LL);
  EXPECT_EQ(m["message_count"].as<uint64_t>(), written.size());
  ASSERT_EQ(m["topics_with_message_count"].size(), 3u);
  const YAML::Node t0 = m["topics_with_message_count"][0];
  EXPECT_EQ(t0["topic_metadata"]["name"].as<std::string>(), "/imu");
  EXPECT_EQ(t0["topic_metadata"]["type"].as<std::string>(), "sensor_msgs/msg/Imu");
  EXPECT_EQ(t0["topic_metadata"]["serialization_format"].as<std::string>(), "cdr");
  EXPECT_EQ(t0["topic_metadata"]["offered_qos_profiles"].as<std::string>(), kQos);
  EXPECT_EQ(t0["message_count"].as<uint64_t>(), 60u);
  EXPECT_EQ(m["topics_with_message_count"][2]["message_count"].as<uint64_t>(), 6u);
  EXPECT_EQ(m["compression_format"].as<std::string>(), "");
  EXPECT_EQ(m["compression_mode"].as<std::string>(), "");
  const std::string file = std::string("bag_0") + (mcap ? ".mcap" : ".db3");
  ASSERT_EQ(m["relative_file_paths"].size(), 1u);
  EXPECT_EQ(m["relative_file_paths"][0].as<std::string>(), file);
  ASSERT_EQ(m["files"].size(), 1u);
  EXPECT_EQ(m["files"][0]["path"].as<std::string>(), file);
  EXPECT_EQ(m["files"][0]["message_count"].as<uint64_t>(), written.size());
  EXPECT_EQ(m["files"][0]["starting_time"]["nanoseconds_since_epoch"].as<int64_t>(), 99000000000LL);
}

INSTANTIATE_TEST_SUITE_P(Storages, RoundTrip, ::testing::ValuesIn(kCases),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(RoundTripMcap, CompressionShrinksFileAndChunksAreUsed) {
  TempDir tmp;
  uintmax_t size[3];
  const char* algos[3] = {"none", "lz4", "zstd"};
  for (int i = 0; i < 3; ++i) {
    const std::string dir = tmp / algos[i];
    WriteBag(dir, {algos[i], Storage::kMcap, algos[i], 4 << 20});
    size[i] = fs::file_size(dir + "/" + algos[i] + "_0.mcap");
    // The compression name is recorded in the Chunk/ChunkIndex records.
    const auto bytes = ppf::bag::test::ReadFileBytes(dir + "/" + algos[i] + "_0.mcap");
    const std::string s(bytes.begin(), bytes.end());
    if (i > 0) {
      // As an MCAP String: uint32 length, then the bytes.
      const std::string name = algos[i];
      const std::string field = std::string(1, char(name.size())) + std::string(3, '\0') + name;
      EXPECT_NE(s.find(field), std::string::npos) << name;
    }
  }
  EXPECT_LT(size[1], size[0] * 3 / 4);
  EXPECT_LT(size[2], size[0] * 3 / 4);
}

TEST(RoundTripMcap, SchemaTextIsStored) {
  TempDir tmp;
  const std::string dir = tmp / "bag";
  WriteBag(dir, kCases[1]);
  const auto bytes = ppf::bag::test::ReadFileBytes(dir + "/bag_0.mcap");
  const std::string s(bytes.begin(), bytes.end());
  EXPECT_EQ(s.compare(0, 8, "\x89MCAP0\r\n"), 0);
  EXPECT_EQ(s.compare(s.size() - 8, 8, "\x89MCAP0\r\n"), 0);
  EXPECT_NE(s.find("ros2msg"), std::string::npos);
  EXPECT_NE(s.find(MessageDefinition("sensor_msgs/msg/Imu")), std::string::npos);
  EXPECT_NE(s.find(MessageDefinition("sensor_msgs/msg/PointCloud2")), std::string::npos);
  EXPECT_NE(s.find("my_pkg/msg/Unknown"), std::string::npos);
}

TEST(RoundTrip, EmptyBag) {
  for (Storage st : {Storage::kSqlite3, Storage::kMcap}) {
    TempDir tmp;
    const std::string dir = tmp / "empty";
    {
      WriterOptions opt;
      opt.storage = st;
      Writer w(dir, opt);
      w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", ""});
    }  // destructor closes
    Reader r(dir);
    EXPECT_EQ(r.Info().message_count, 0u);
    ASSERT_EQ(r.Info().topics.size(), 1u);
    EXPECT_EQ(r.Info().topics[0].message_count, 0u);
    Message m;
    EXPECT_FALSE(r.Next(m));
  }
}

TEST(RoundTrip, WriterRejectsMisuse) {
  TempDir tmp;
  {
    Writer w(tmp / "a", WriterOptions());
    w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", ""});
    const uint8_t b[4] = {0, 1, 0, 0};
    EXPECT_THROW(w.Write("/other", 1, b, 4), BagError);
    EXPECT_THROW(w.AddTopic({"/imu", "nav_msgs/msg/Odometry", "cdr", ""}), BagError);
    EXPECT_THROW(w.Write("/imu", -5, b, 4), BagError);
    w.Close();
    EXPECT_THROW(w.Write("/imu", 1, b, 4), BagError);
  }
  // Existing non-empty directory.
  EXPECT_THROW(Writer(tmp / "a", WriterOptions()), BagError);
  WriterOptions bad;
  bad.compression = "brotli";
  EXPECT_THROW(Writer(tmp / "b", bad), BagError);
  WriterOptions sqlite_lz4;
  sqlite_lz4.storage = Storage::kSqlite3;
  sqlite_lz4.compression = "lz4";
  EXPECT_THROW(Writer(tmp / "c", sqlite_lz4), BagError);
}

}  // namespace
