// ROS 1 bag reader against an independent writer: Debian's python3-rosbag (write_ros1_bag.py)
// writes uncompressed, bz2 and lz4 bags; every message must come back converted to exactly the
// CDR bytes this file's hand-built encoder (test_util.hpp's CdrWriter) gives for the same content.
// Damaged and truncated copies must be refused with a BagError naming the byte offset.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <map>
#include <memory>

#include "ppf_bag/bag.hpp"
#include "ros1_convert.hpp"
#include "test_util.hpp"

namespace ppf::bag::test {
namespace {

constexpr const char* kPython = "/usr/bin/python3";

// Empty when the writer can run, else why not.
std::string WriterMissingReason() {
  static const std::string reason = [] {
    const CommandResult r = Run(std::string(kPython) +
                                " -c 'import rosbag, roslz4, sensor_msgs.msg, std_msgs.msg, "
                                "genpy.dynamic' 2>&1");
    if (r.exit_code == 0) return std::string();
    return std::string(
               "the ROS 1 bag writer needs Debian's python3-rosbag and "
               "python3-sensor-msgs for ") +
           kPython +
           " (apt-get install -y python3-rosbag python3-sensor-msgs; scripts/setup.sh "
           "installs them): " +
           r.output;
  }();
  return reason;
}

struct WrittenBag {
  std::string path;
  YAML::Node expected;  // write_ros1_bag.py's EXPECTED.json
};

// One bag per compression per test process: the writer takes about a second.
const WrittenBag& Bag(const std::string& compression) {
  static TempDir dir;
  static std::map<std::string, WrittenBag> bags;
  auto it = bags.find(compression);
  if (it != bags.end()) return it->second;
  WrittenBag b;
  b.path = dir / ("seq_" + compression + ".bag");
  const std::string json = dir / ("seq_" + compression + ".json");
  // A small chunk threshold gives several chunks, so the cross-chunk merge is exercised.
  const CommandResult r =
      Run(std::string(kPython) + " " + ShellQuote(PPF_BAG_ROS1_WRITER) + " " + ShellQuote(b.path) +
          " " + compression + " 2048 " + ShellQuote(json) + " 2>&1");
  if (r.exit_code != 0) throw std::runtime_error("write_ros1_bag.py failed: " + r.output);
  b.expected = YAML::LoadFile(json);
  return bags.emplace(compression, std::move(b)).first->second;
}

std::vector<uint8_t> Hex(const std::string& s) {
  std::vector<uint8_t> out(s.size() / 2);
  for (size_t i = 0; i < out.size(); ++i) out[i] = std::stoi(s.substr(2 * i, 2), nullptr, 16);
  return out;
}

void F32(CdrWriter& w, float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, 4);
  w.U32(bits);
}

// The ROS 2 message a record of EXPECTED.json must become, encoded independently of the reader.
std::vector<uint8_t> ExpectedPayload(const YAML::Node& m) {
  const std::string kind = m["kind"].as<std::string>();
  if (kind == "raw") return Hex(m["data"].as<std::string>());
  CdrWriter w;
  if (kind == "imu") {
    w.I32(m["sec"].as<int32_t>());
    w.U32(m["nsec"].as<uint32_t>());
    w.Str(m["frame"].as<std::string>());
    for (const auto& v : m["values"]) w.F64(v.as<double>());
  } else if (kind == "cloud") {
    w.I32(m["sec"].as<int32_t>());
    w.U32(m["nsec"].as<uint32_t>());
    w.Str(m["frame"].as<std::string>());
    w.U32(m["height"].as<uint32_t>());
    w.U32(m["width"].as<uint32_t>());
    w.U32(static_cast<uint32_t>(m["fields"].size()));
    for (const auto& f : m["fields"]) {
      w.Str(f[0].as<std::string>());
      w.U32(f[1].as<uint32_t>());
      w.U8(f[2].as<uint8_t>());
      w.U32(f[3].as<uint32_t>());
    }
    w.Bool(m["is_bigendian"].as<int>() != 0);
    w.U32(m["point_step"].as<uint32_t>());
    w.U32(m["row_step"].as<uint32_t>());
    w.Bytes(Hex(m["data"].as<std::string>()));
    w.Bool(m["is_dense"].as<int>() != 0);
  } else if (kind == "livox") {
    // The documented layout (README): stamp = timebase; x y z intensity float32, tag line
    // uint8, offset_time uint32 at 20, point_step 24.
    const uint64_t tb = m["timebase"].as<uint64_t>();
    w.I32(static_cast<int32_t>(tb / 1000000000u));
    w.U32(static_cast<uint32_t>(tb % 1000000000u));
    w.Str(m["frame"].as<std::string>());
    const YAML::Node pts = m["points"];
    const uint32_t n = static_cast<uint32_t>(pts.size());
    w.U32(1);
    w.U32(n);
    const std::vector<std::tuple<const char*, uint32_t, uint8_t>> fields = {
        {"x", 0, 7},    {"y", 4, 7},     {"z", 8, 7},           {"intensity", 12, 7},
        {"tag", 16, 2}, {"line", 17, 2}, {"offset_time", 20, 6}};
    w.U32(static_cast<uint32_t>(fields.size()));
    for (const auto& [name, off, type] : fields) {
      w.Str(name);
      w.U32(off);
      w.U8(type);
      w.U32(1);
    }
    w.Bool(false);
    w.U32(24);
    w.U32(24 * n);
    w.U32(24 * n);
    for (const auto& p : pts) {  // [offset_time, x, y, z, reflectivity, tag, line]
      const size_t start = w.data().size();
      F32(w, p[1].as<float>());
      F32(w, p[2].as<float>());
      F32(w, p[3].as<float>());
      F32(w, static_cast<float>(p[4].as<int>()));
      w.U8(p[5].as<uint8_t>());
      w.U8(p[6].as<uint8_t>());
      w.U8(0);
      w.U8(0);
      w.U32(p[0].as<uint32_t>());
      EXPECT_EQ(w.data().size() - start, 24u);
    }
    w.Bool(true);
  } else {
    ADD_FAILURE() << "unknown kind " << kind;
  }
  return w.data();
}

struct Expected {
  std::string topic;
  int64_t t;
  std::vector<uint8_t> data;
};

// In the reader's promised order: timestamp, ties in storage order (the data has none).
std::vector<Expected> ExpectedMessages(const WrittenBag& b) {
  std::vector<Expected> out;
  for (const auto& m : b.expected["messages"]) {
    out.push_back({m["topic"].as<std::string>(), m["t"].as<int64_t>(), ExpectedPayload(m)});
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Expected& a, const Expected& b) { return a.t < b.t; });
  return out;
}

void ExpectSame(const std::vector<Message>& got, const std::vector<Expected>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i) {
    SCOPED_TRACE("message " + std::to_string(i) + " on " + want[i].topic);
    EXPECT_EQ(got[i].topic, want[i].topic);
    EXPECT_EQ(got[i].timestamp_ns, want[i].t);
    EXPECT_EQ(got[i].data, want[i].data);
  }
}

// The BagError text, or "" if reading the whole file succeeded. Any other exception fails.
std::string ReadError(const std::string& path) {
  try {
    Reader r(path);
    ReadAll(r);
  } catch (const BagError& e) {
    return e.what();
  }
  return "";
}

uint32_t U32At(const std::vector<uint8_t>& b, size_t pos) {
  uint32_t v;
  std::memcpy(&v, b.data() + pos, 4);
  return v;
}

// Position of `needle` in b at or after `from` (npos if absent).
size_t Find(const std::vector<uint8_t>& b, const std::string& needle, size_t from = 0) {
  auto it = std::search(b.begin() + from, b.end(), needle.begin(), needle.end());
  return it == b.end() ? std::string::npos : static_cast<size_t>(it - b.begin());
}

class Ros1Bag : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    const std::string why = WriterMissingReason();
    if (!why.empty()) GTEST_SKIP() << why;
  }
};

TEST_P(Ros1Bag, EveryMessageComesBackAsItsRos2CdrBytes) {
  const WrittenBag& b = Bag(GetParam());
  const auto want = ExpectedMessages(b);
  Reader r(b.path);
  ExpectSame(ReadAll(r), want);
  // The writer's out-of-order Imu really is out of order in the file (else the sort is untested).
  const YAML::Node msgs = b.expected["messages"];
  bool out_of_order = false;
  for (size_t i = 1; i < msgs.size(); ++i) {
    out_of_order = out_of_order || msgs[i]["t"].as<int64_t>() < msgs[i - 1]["t"].as<int64_t>();
  }
  EXPECT_TRUE(out_of_order);
  EXPECT_GT(b.expected["chunks"].size(), 3u);
}

TEST_P(Ros1Bag, InfoPresentsRos2TypesAndCounts) {
  const WrittenBag& b = Bag(GetParam());
  const BagInfo info = ReadInfo(b.path);
  EXPECT_EQ(info.storage, Storage::kRos1);
  EXPECT_STREQ(StorageIdentifier(info.storage), "rosbag_v2");
  const auto want = ExpectedMessages(b);
  EXPECT_EQ(info.message_count, want.size());
  EXPECT_EQ(info.start_ns, want.front().t);
  EXPECT_EQ(info.end_ns, want.back().t);
  std::map<std::string, std::tuple<std::string, std::string, uint64_t>> topics;
  for (const auto& t : info.topics) {
    topics[t.info.name] = {t.info.type, t.info.serialization_format, t.message_count};
  }
  using T = std::tuple<std::string, std::string, uint64_t>;
  EXPECT_EQ(topics["/imu"], T("sensor_msgs/msg/Imu", "cdr", 40));
  EXPECT_EQ(topics["/points"], T("sensor_msgs/msg/PointCloud2", "cdr", 10));
  EXPECT_EQ(topics["/livox"], T("sensor_msgs/msg/PointCloud2", "cdr", 4));
  EXPECT_EQ(topics["/livox2"], T("sensor_msgs/msg/PointCloud2", "cdr", 4));
  EXPECT_EQ(topics["/chatter"], T("std_msgs/String", "ros1", 4));
  EXPECT_EQ(topics.size(), 5u);
}

TEST_P(Ros1Bag, TopicFilterAndSeek) {
  const WrittenBag& b = Bag(GetParam());
  auto want = ExpectedMessages(b);
  Reader r(b.path);
  const int64_t mid = want[want.size() / 2].t;
  r.SetTopicFilter({"/points", "/livox2"});
  r.Seek(mid);
  std::vector<Expected> sub;
  for (const auto& e : want) {
    if ((e.topic == "/points" || e.topic == "/livox2") && e.t >= mid) sub.push_back(e);
  }
  ASSERT_FALSE(sub.empty());
  ExpectSame(ReadAll(r), sub);
  r.Seek(0);
  sub.clear();
  for (const auto& e : want) {
    if (e.topic == "/points" || e.topic == "/livox2") sub.push_back(e);
  }
  ExpectSame(ReadAll(r), sub);
}

// Every cut of the file loses (part of) the index at its end: always refused, with an offset.
TEST_P(Ros1Bag, TruncatedAnywhereIsRefusedWithTheOffset) {
  const WrittenBag& b = Bag(GetParam());
  const auto bytes = ReadFileBytes(b.path);
  TempDir tmp;
  const std::string cut = tmp / "cut.bag";
  for (size_t n = 0; n < bytes.size(); n += (n < 64 ? 1 : 97)) {
    WriteFileBytes(cut, std::vector<uint8_t>(bytes.begin(), bytes.begin() + n));
    const std::string e = ReadError(cut);
    ASSERT_FALSE(e.empty()) << "cut at " << n << " was accepted";
    if (n >= 13) {
      EXPECT_NE(e.find("byte offset"), std::string::npos) << e;
    }
  }
  // Cut in the middle of the data: the bag header's index_pos now points past the end.
  const size_t half = bytes.size() / 2;
  WriteFileBytes(cut, std::vector<uint8_t>(bytes.begin(), bytes.begin() + half));
  const std::string e = ReadError(cut);
  EXPECT_NE(
      e.find("record at byte offset 13: index_pos " + b.expected["index_pos"].as<std::string>() +
             " lies outside the file of " + std::to_string(half) + " bytes (truncated?)"),
      std::string::npos)
      << e;
}

// Damage inside a chunk is reported with the chunk's byte offset in the file.
TEST_P(Ros1Bag, DamagedChunkIsRefusedWithItsOffset) {
  const WrittenBag& b = Bag(GetParam());
  const auto bytes = ReadFileBytes(b.path);
  const size_t chunk = b.expected["chunks"][1].as<size_t>();
  const size_t hlen = U32At(bytes, chunk);
  const size_t data = chunk + 4 + hlen + 4;
  const size_t data_len = U32At(bytes, chunk + 4 + hlen);
  auto damaged = bytes;
  if (GetParam() == "none") {
    // First record in the chunk gets an absurd header length.
    damaged[data + 3] = 0x7f;
  } else {
    // Compressed payload damage: bz2 and roslz4's frame both carry a checksum.
    for (size_t i = data + data_len / 2; i < data + data_len / 2 + 8; ++i) damaged[i] ^= 0x5a;
  }
  TempDir tmp;
  WriteFileBytes(tmp / "d.bag", damaged);
  const std::string e = ReadError(tmp / "d.bag");
  // ": what" for the chunk itself, ", record at byte N of the inflated chunk: what" inside it.
  const std::string at = "record at byte offset " + std::to_string(chunk);
  EXPECT_TRUE(e.find(at + ": ") != std::string::npos || e.find(at + ", ") != std::string::npos)
      << e;
  // Info still works: it only needs the index.
  EXPECT_NO_THROW(ReadInfo(tmp / "d.bag"));

  // The chunk info points at a record that is not a chunk.
  damaged = bytes;
  const size_t op = Find(damaged, std::string("op=\x05", 4), chunk);
  ASSERT_LT(op, data);
  damaged[op + 3] = 0x04;
  WriteFileBytes(tmp / "op.bag", damaged);
  EXPECT_NE(
      ReadError(tmp / "op.bag")
          .find("record at byte offset " + std::to_string(chunk) + ": chunk info (at byte offset "),
      std::string::npos)
      << ReadError(tmp / "op.bag");
}

// A chunk's declared uncompressed size is not trusted for allocation: 3.75 GiB is refused by
// comparison (none), by lz4's maximum ratio, or by streaming bz2 until its real end.
TEST_P(Ros1Bag, ImplausibleChunkSizeIsRefused) {
  const WrittenBag& b = Bag(GetParam());
  auto bytes = ReadFileBytes(b.path);
  const size_t chunk = b.expected["chunks"][0].as<size_t>();
  const size_t field = Find(bytes, "size=", chunk);
  ASSERT_LT(field, chunk + 64);
  const uint32_t real = U32At(bytes, field + 5);
  const uint32_t huge = 0xf0000000u;
  std::memcpy(bytes.data() + field + 5, &huge, 4);
  TempDir tmp;
  WriteFileBytes(tmp / "s.bag", bytes);
  const std::string e = ReadError(tmp / "s.bag");
  const std::string at = "record at byte offset " + std::to_string(chunk) + ": ";
  const std::map<std::string, std::string> want = {
      {"none", "but declares 4026531840"},
      {"lz4", "declares 4026531840 uncompressed bytes, beyond lz4's ratio"},
      {"bz2", "bz2 chunk inflated to " + std::to_string(real) + " bytes, expected 4026531840"}};
  EXPECT_NE(e.find(at), std::string::npos) << e;
  EXPECT_NE(e.find(want.at(GetParam())), std::string::npos) << e;
}

TEST_P(Ros1Bag, DamagedIndexIsRefusedWithItsOffset) {
  const WrittenBag& b = Bag(GetParam());
  auto bytes = ReadFileBytes(b.path);
  const size_t index_pos = b.expected["index_pos"].as<size_t>();
  // Point the first chunk info's chunk_pos past the data section.
  const size_t field = Find(bytes, "chunk_pos=", index_pos);
  ASSERT_NE(field, std::string::npos);
  const uint64_t bad = index_pos + 1;
  std::memcpy(bytes.data() + field + 10, &bad, 8);
  TempDir tmp;
  WriteFileBytes(tmp / "i.bag", bytes);
  const std::string e = ReadError(tmp / "i.bag");
  EXPECT_NE(e.find("chunk_pos " + std::to_string(bad) + " is not inside the data section"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("record at byte offset "), std::string::npos) << e;
}

// Flipping any byte must end in a result or a BagError: never a crash or another exception.
TEST_P(Ros1Bag, ByteFlipsNeverCrash) {
  const WrittenBag& b = Bag(GetParam());
  const auto bytes = ReadFileBytes(b.path);
  TempDir tmp;
  const std::string path = tmp / "f.bag";
  size_t refused = 0, n = 0;
  for (size_t i = 0; i < bytes.size(); i += 29, ++n) {
    auto f = bytes;
    f[i] ^= 0xff;
    WriteFileBytes(path, f);
    refused += !ReadError(path).empty();
  }
  EXPECT_GT(refused, 0u);
  EXPECT_LE(refused, n);
}

// A known type name whose md5sum is not the standard definition's is not decoded as if it were.
TEST_P(Ros1Bag, UnknownDefinitionOfAKnownTypeIsPassedThrough) {
  const WrittenBag& b = Bag(GetParam());
  auto bytes = ReadFileBytes(b.path);
  const std::string md5 = "1158d486dd51d683ce2f1be655c3c181";  // sensor_msgs/PointCloud2
  size_t replaced = 0;
  for (size_t p = Find(bytes, md5); p != std::string::npos; p = Find(bytes, md5, p + 1)) {
    bytes[p] = 'x';
    ++replaced;
  }
  // Only the index's connection record is outside compressed chunks.
  ASSERT_GE(replaced, 1u);
  TempDir tmp;
  WriteFileBytes(tmp / "m.bag", bytes);
  for (const auto& t : ReadInfo(tmp / "m.bag").topics) {
    if (t.info.name == "/points") {
      EXPECT_EQ(t.info.type, "sensor_msgs/PointCloud2");
      EXPECT_EQ(t.info.serialization_format, "ros1");
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Compressions, Ros1Bag, ::testing::Values("none", "bz2", "lz4"),
                         [](const auto& info) { return info.param; });

TEST(Ros1BagCli, BagInfoTakesABagFile) {
  const std::string why = WriterMissingReason();
  if (!why.empty()) GTEST_SKIP() << why;
  const WrittenBag& b = Bag("lz4");
  const CommandResult r = test::Run(std::string(PPF_BAG_INFO_EXE) + " " + ShellQuote(b.path));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Storage id:        rosbag_v2"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Topic: /imu | Type: sensor_msgs/msg/Imu | Count: 40 | "
                          "Serialization Format: cdr"),
            std::string::npos)
      << r.output;
}

// Without the Python writer: the magic line decides, whatever the name.
TEST(Ros1Errors, NotABagAndOldFormat) {
  TempDir tmp;
  WriteFileBytes(tmp / "a.bag", std::vector<uint8_t>(100, 'x'));
  EXPECT_NE(ReadError(tmp / "a.bag").find("not a ROS 1 bag (no '#ROSBAG V2.0' line at byte 0)"),
            std::string::npos);
  const std::string v12 = "#ROSBAG V1.2\n0123456789";
  WriteFileBytes(tmp / "old", std::vector<uint8_t>(v12.begin(), v12.end()));
  EXPECT_NE(ReadError(tmp / "old").find("format 1.2; only 2.0 is supported"), std::string::npos)
      << ReadError(tmp / "old");
  EXPECT_THROW(Writer(tmp / "w", WriterOptions{Storage::kRos1}), BagError);
}

// The PointCloud2 example of ROS2-INTEROP.md (stamp 1 s 2 ns, frame "lidar", 2 points of one
// float32 field "x"), from its ROS 1 serialization (seq 9 first, no alignment) to the reference's
// CDR bytes.
TEST(Ros1Convert, InteropReferenceCloud) {
  const std::vector<uint8_t> ros1 = {
      9, 0, 0, 0, 1, 0, 0,    0,    2,   0, 0, 0,    5, 0, 0, 0, 'l', 'i', 'd', 'a', 'r',  // header
      1, 0, 0, 0, 2, 0, 0,    0,                                          // height, width
      1, 0, 0, 0, 1, 0, 0,    0,    'x', 0, 0, 0,    0, 7, 1, 0, 0,   0,  // fields
      0, 4, 0, 0, 0, 8, 0,    0,    0,                // is_bigendian, point_step, row_step
      8, 0, 0, 0, 0, 0, 0x80, 0x3f, 0,   0, 0, 0x40,  // data
      1};                                             // is_dense
  const std::vector<uint8_t> cdr = {
      0x00, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x06, 0x00,
      0x00, 0x00, 0x6c, 0x69, 0x64, 0x61, 0x72, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00,
      0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x78, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x07, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x08, 0x00, 0x00, 0x00, 0x08, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00, 0x40, 0x01};
  std::vector<uint8_t> out;
  std::string error;
  ASSERT_TRUE(detail::ConvertRos1Message(detail::Ros1Conversion::kPointCloud2, ros1.data(),
                                         ros1.size(), &out, &error))
      << error;
  EXPECT_EQ(out, cdr);
  // Every shorter prefix is malformed, and says where it ran out (or that the field count
  // cannot fit, checked before the fields are read).
  for (size_t n = 0; n < ros1.size(); ++n) {
    EXPECT_FALSE(detail::ConvertRos1Message(detail::Ros1Conversion::kPointCloud2, ros1.data(), n,
                                            &out, &error));
    const bool says_where =
        error.find("past the end of the " + std::to_string(n) + "-byte message") !=
            std::string::npos ||
        error == "PointCloud2 declares 1 fields, more than the message can hold";
    EXPECT_TRUE(says_where) << n << ": " << error;
  }
  auto longer = ros1;
  longer.push_back(0);
  EXPECT_FALSE(detail::ConvertRos1Message(detail::Ros1Conversion::kPointCloud2, longer.data(),
                                          longer.size(), &out, &error));
  EXPECT_EQ(error, "1 unexpected trailing bytes after byte " + std::to_string(ros1.size()));
}

}  // namespace
}  // namespace ppf::bag::test
