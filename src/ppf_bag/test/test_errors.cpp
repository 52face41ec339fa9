// Rejected input: missing/corrupt/truncated files, CRC mismatches, bad schemas; plus reading
// hand-built MCAP variants (no summary, no chunks) and other sqlite3 layouts (Jazzy, pre-Humble).
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "ppf_bag/bag.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace ppf::bag;
using ppf::bag::test::ReadAll;
using ppf::bag::test::ReadFileBytes;
using ppf::bag::test::TempDir;
using ppf::bag::test::WriteFileBytes;

namespace {

// Runs fn, expects a BagError whose message contains `needle`.
template <typename Fn>
void ExpectBagError(Fn&& fn, const std::string& needle) {
  try {
    fn();
    ADD_FAILURE() << "expected BagError containing '" << needle << "'";
  } catch (const BagError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << "message was: " << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected BagError, got other exception: " << e.what();
  }
}

void OpenAndReadAll(const std::string& path) {
  Reader r(path);
  ReadAll(r);
}

const std::vector<uint8_t> kMarker = {0x00, 0x01, 0x00, 0x00, 'P', 'P', 'F', 'M', 'A', 'R', 'K'};

// An MCAP bag whose /a messages carry kMarker + index, so tests can find payload bytes.
std::string WriteMcap(const TempDir& tmp, const std::string& compression, size_t chunk = 1 << 20) {
  const std::string dir = tmp / ("bag_" + compression);
  WriterOptions opt;
  opt.compression = compression;
  opt.chunk_size = chunk;
  Writer w(dir, opt);
  w.AddTopic({"/a", "sensor_msgs/msg/Imu", "cdr", ""});
  w.AddTopic({"/b", "nav_msgs/msg/Odometry", "cdr", ""});
  for (int i = 0; i < 20; ++i) {
    std::vector<uint8_t> d = kMarker;
    d.push_back(static_cast<uint8_t>(i));
    w.Write("/a", 1000 + 10 * i, d);
    w.Write("/b", 1005 + 10 * i, std::vector<uint8_t>(40, static_cast<uint8_t>(i)));
  }
  w.Close();
  return dir + "/bag_" + compression + "_0.mcap";
}

uint64_t Le64(const std::vector<uint8_t>& b, size_t at) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= uint64_t(b[at + i]) << (8 * i);
  return v;
}

// Footer = opcode, length, summary_start, ... ; it sits right before the 8-byte trailing magic.
uint64_t SummaryStart(const std::vector<uint8_t>& b) { return Le64(b, b.size() - 8 - 29 + 9); }

size_t Find(const std::vector<uint8_t>& hay, const std::vector<uint8_t>& needle) {
  auto it = std::search(hay.begin(), hay.end(), needle.begin(), needle.end());
  return it == hay.end() ? std::string::npos : static_cast<size_t>(it - hay.begin());
}

// Offset of the first top-level record with opcode `op` (walking records after the magic).
size_t FindRecord(const std::vector<uint8_t>& b, uint8_t op) {
  size_t pos = 8;
  while (pos + 9 <= b.size()) {
    if (b[pos] == op) return pos;
    pos += 9 + Le64(b, pos + 1);
  }
  return std::string::npos;
}

// DataEnd is the 13-byte record right before the summary.
void ZeroDataEndCrc(std::vector<uint8_t>& b) {
  const uint64_t s = SummaryStart(b);
  ASSERT_EQ(b[s - 13], 0x0F);
  std::memset(&b[s - 4], 0, 4);
}

// Applies `corrupt` to the bytes of a fresh WriteMcap(tmp, compression) file and expects reading
// the result to fail with a BagError containing `needle`; a fatal failure in `corrupt` ends it.
template <typename Fn>
void ExpectCorruptMcapRejected(const std::string& compression, Fn&& corrupt,
                               const std::string& needle) {
  TempDir tmp;
  const std::string file = WriteMcap(tmp, compression);
  auto b = ReadFileBytes(file);
  corrupt(b);
  if (::testing::Test::HasFatalFailure()) return;
  WriteFileBytes(file, b);
  ExpectBagError([&] { OpenAndReadAll(file); }, needle);
}

void FlipMarkedPayloadByte(std::vector<uint8_t>& b) {
  const size_t at = Find(b, kMarker);
  ASSERT_NE(at, std::string::npos);
  b[at + 5] ^= 0x40;
}

// ---- paths and metadata ----------------------------------------------------------------------

TEST(Errors, MissingPath) {
  ExpectBagError([] { Reader r("/nonexistent/ppf_bag/nothing"); }, "/nonexistent/ppf_bag/nothing");
  ExpectBagError([] { Reader r("/nonexistent/x.mcap"); }, "no such bag");
}

TEST(Errors, DirectoryWithoutMetadata) {
  TempDir tmp;
  ExpectBagError([&] { Reader r(tmp.path()); }, "metadata.yaml");
}

TEST(Errors, MetadataProblems) {
  TempDir tmp;
  const std::string file = WriteMcap(tmp, "none");
  const std::string dir = fs::path(file).parent_path().string();
  const std::string meta = dir + "/metadata.yaml";
  std::string good;
  {
    std::ifstream in(meta);
    good.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto write = [&](const std::string& text) { std::ofstream(meta, std::ios::trunc) << text; };

  write("{{{ not yaml");
  ExpectBagError([&] { Reader r(dir); }, "metadata.yaml");
  write("something_else: 1\n");
  ExpectBagError([&] { Reader r(dir); }, "rosbag2_bagfile_information");
  std::string s = good;
  s.replace(s.find("storage_identifier: mcap"), 24, "storage_identifier: rosbag_v1");
  write(s);
  ExpectBagError([&] { Reader r(dir); }, "rosbag_v1");
  s = good;
  s.replace(s.find("- bag_none_0.mcap"), 17, "- missing_0.mcap");
  write(s);
  ExpectBagError([&] { Reader r(dir); }, "missing_0.mcap");
  write(good);
  EXPECT_NO_THROW(OpenAndReadAll(dir));
}

TEST(Errors, GarbageFiles) {
  TempDir tmp;
  std::vector<uint8_t> junk(4096);
  for (size_t i = 0; i < junk.size(); ++i) junk[i] = static_cast<uint8_t>(i * 131 + 7);
  WriteFileBytes(tmp / "junk.mcap", junk);
  WriteFileBytes(tmp / "junk.db3", junk);
  WriteFileBytes(tmp / "junk.bin", junk);
  ExpectBagError([&] { OpenAndReadAll(tmp / "junk.mcap"); }, "not an MCAP file");
  ExpectBagError([&] { OpenAndReadAll(tmp / "junk.db3"); }, "junk.db3");
  ExpectBagError([&] { OpenAndReadAll(tmp / "junk.bin"); }, "neither");
}

// ---- MCAP corruption -------------------------------------------------------------------------

TEST(McapErrors, PayloadByteFlipFailsDataSectionCrc) {
  ExpectCorruptMcapRejected("none", FlipMarkedPayloadByte, "data section CRC mismatch");
}

TEST(McapErrors, PayloadByteFlipFailsChunkCrc) {
  ExpectCorruptMcapRejected(
      "none",
      [](std::vector<uint8_t>& b) {
        FlipMarkedPayloadByte(b);
        if (::testing::Test::HasFatalFailure()) return;
        ZeroDataEndCrc(b);  // only the chunk CRC is left to catch it
      },
      "CRC mismatch");
}

TEST(McapErrors, CorruptCompressedChunk) {
  for (const char* algo : {"lz4", "zstd"}) {
    TempDir tmp;
    const std::string file = WriteMcap(tmp, algo);
    auto b = ReadFileBytes(file);
    // Flip bytes in the middle of the first chunk's compressed records.
    const size_t chunk = FindRecord(b, 0x06);
    ASSERT_NE(chunk, std::string::npos);
    const size_t records = chunk + 9 + 8 + 8 + 8 + 4 + 4 + std::strlen(algo) + 8;
    ASSERT_LT(records + 100, b.size());
    for (size_t i = 0; i < 8; ++i) b[records + 30 + i * 7] ^= 0x5A;
    ZeroDataEndCrc(b);
    WriteFileBytes(file, b);
    EXPECT_THROW(OpenAndReadAll(file), BagError) << algo;
  }
}

TEST(McapErrors, SummaryCrcMismatch) {
  ExpectCorruptMcapRejected(
      "none",
      [](std::vector<uint8_t>& b) {
        const uint64_t s = SummaryStart(b);
        ASSERT_EQ(b[s], 0x03) << "summary starts with the Schema group";
        b[s + 20] ^= 0x01;
      },
      "summary CRC mismatch");
}

TEST(McapErrors, Truncated) {
  TempDir tmp;
  const std::string file = WriteMcap(tmp, "zstd");
  const auto b = ReadFileBytes(file);
  for (size_t keep : {b.size() - 1, b.size() - 8, b.size() / 2, size_t(40), size_t(9), size_t(3)}) {
    WriteFileBytes(file, std::vector<uint8_t>(b.begin(), b.begin() + keep));
    EXPECT_THROW(OpenAndReadAll(file), BagError) << "kept " << keep << " bytes";
  }
}

TEST(McapErrors, RecordLengthBeyondFile) {
  ExpectCorruptMcapRejected(
      "none",
      [](std::vector<uint8_t>& b) {
        // The Header record's length field (bytes 9..16) made huge.
        b[9 + 6] = 0x7F;
      },
      "beyond the data section");
}

TEST(Mcap, MissingSummaryIsScanned) {
  TempDir tmp;
  const std::string file = WriteMcap(tmp, "lz4", 200);
  Reader original(file);
  const auto want = ReadAll(original);
  ASSERT_EQ(want.size(), 40u);

  auto b = ReadFileBytes(file);
  const uint64_t s = SummaryStart(b);
  std::vector<uint8_t> cut(b.begin(), b.begin() + static_cast<long>(s));
  const uint8_t footer[29] = {0x02, 20, 0, 0, 0, 0, 0, 0, 0};  // all offsets and CRC zero
  cut.insert(cut.end(), footer, footer + 29);
  cut.insert(cut.end(), b.begin(), b.begin() + 8);  // magic
  WriteFileBytes(tmp / "nosummary.mcap", cut);

  Reader r(tmp / "nosummary.mcap");
  EXPECT_EQ(r.Info().message_count, 40u);
  ASSERT_EQ(r.Info().topics.size(), 2u);
  EXPECT_EQ(r.Info().topics[0].info.type, "sensor_msgs/msg/Imu");
  EXPECT_EQ(r.Info().topics[0].message_count, 20u);
  EXPECT_EQ(r.Info().start_ns, 1000);
  EXPECT_EQ(r.Info().end_ns, 1195);
  const auto got = ReadAll(r);
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].topic, want[i].topic);
    EXPECT_EQ(got[i].timestamp_ns, want[i].timestamp_ns);
    EXPECT_EQ(got[i].data, want[i].data);
  }
}

// Minimal hand-written MCAP builder (independent of the library's writer).
struct Mini {
  std::vector<uint8_t> b{0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
  void Le(uint64_t v, int n) {
    for (int i = 0; i < n; ++i) b.push_back(uint8_t(v >> (8 * i)));
  }
  void Str(std::vector<uint8_t>& o, const std::string& s) {
    for (int i = 0; i < 4; ++i) o.push_back(uint8_t(s.size() >> (8 * i)));
    o.insert(o.end(), s.begin(), s.end());
  }
  void Record(uint8_t op, const std::vector<uint8_t>& content) {
    b.push_back(op);
    Le(content.size(), 8);
    b.insert(b.end(), content.begin(), content.end());
  }
  void Header() {
    std::vector<uint8_t> c;
    Str(c, "ros2");
    Str(c, "test");
    Record(0x01, c);
  }
  void Schema(uint16_t id, const std::string& name) {
    std::vector<uint8_t> c{uint8_t(id), uint8_t(id >> 8)};
    Str(c, name);
    Str(c, "ros2msg");
    Str(c, "int32 x\n");
    Record(0x03, c);
  }
  void Channel(uint16_t id, uint16_t schema, const std::string& topic) {
    std::vector<uint8_t> c{uint8_t(id), uint8_t(id >> 8), uint8_t(schema), uint8_t(schema >> 8)};
    Str(c, topic);
    Str(c, "cdr");
    c.insert(c.end(), {0, 0, 0, 0});  // empty metadata map
    Record(0x04, c);
  }
  void Msg(uint16_t ch, uint64_t t, uint8_t payload) {
    std::vector<uint8_t> c{uint8_t(ch), uint8_t(ch >> 8), 0, 0, 0, 0};
    for (int k = 0; k < 2; ++k) {
      for (int i = 0; i < 8; ++i) c.push_back(uint8_t(t >> (8 * i)));
    }
    c.insert(c.end(), {0, 1, 0, 0, payload});
    Record(0x05, c);
  }
  void EndNoSummary() {
    Record(0x0F, {0, 0, 0, 0});
    Record(0x02, std::vector<uint8_t>(20, 0));
    b.insert(b.end(), {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'});
  }
};

// Expects reading the hand-built MCAP `bytes` to fail with a BagError containing `needle`.
void ExpectMcapBytesRejected(const std::vector<uint8_t>& bytes, const std::string& needle) {
  TempDir tmp;
  WriteFileBytes(tmp / "u.mcap", bytes);
  ExpectBagError([&] { OpenAndReadAll(tmp / "u.mcap"); }, needle);
}

TEST(Mcap, UnchunkedOutOfOrderMessagesComeOutSorted) {
  Mini m;
  m.Header();
  m.Schema(1, "std_msgs/msg/Int32");
  m.Channel(3, 1, "/x");
  m.Channel(4, 1, "/y");
  m.Msg(3, 300, 1);
  m.Msg(4, 100, 2);
  m.Msg(3, 200, 3);
  m.Msg(4, 300, 4);
  m.EndNoSummary();
  TempDir tmp;
  WriteFileBytes(tmp / "u.mcap", m.b);
  Reader r(tmp / "u.mcap");
  EXPECT_EQ(r.Info().message_count, 4u);
  EXPECT_EQ(r.Info().start_ns, 100);
  EXPECT_EQ(r.Info().end_ns, 300);
  ASSERT_EQ(r.Info().topics.size(), 2u);
  EXPECT_EQ(r.Info().topics[0].info.name, "/x");
  EXPECT_EQ(r.Info().topics[0].info.type, "std_msgs/msg/Int32");
  EXPECT_EQ(r.Info().topics[0].message_count, 2u);
  const auto got = ReadAll(r);
  ASSERT_EQ(got.size(), 4u);
  const uint8_t order[4] = {2, 3, 1, 4};  // by time, ties in file order
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(got[i].data.size(), 5u);
    EXPECT_EQ(got[i].data[4], order[i]) << i;
  }
  r.SetTopicFilter({"/y"});
  EXPECT_EQ(ppf::bag::test::Stamps(ReadAll(r)), (std::vector<int64_t>{100, 300}));
}

TEST(McapErrors, MessageOnUnknownChannel) {
  Mini m;
  m.Header();
  m.Schema(1, "std_msgs/msg/Int32");
  m.Channel(3, 1, "/x");
  m.Msg(7, 100, 1);
  m.EndNoSummary();
  ExpectMcapBytesRejected(m.b, "unknown channel 7");
}

TEST(McapErrors, ChannelWithUnknownSchema) {
  Mini m;
  m.Header();
  m.Schema(1, "std_msgs/msg/Int32");
  m.Channel(3, 9, "/x");
  m.EndNoSummary();
  ExpectMcapBytesRejected(m.b, "unknown schema 9");
}

TEST(McapErrors, NoHeaderRecord) {
  Mini m;
  m.Schema(1, "std_msgs/msg/Int32");
  m.EndNoSummary();
  ExpectMcapBytesRejected(m.b, "Header");
}

// ---- sqlite3 layouts and corruption ----------------------------------------------------------

void Sql(sqlite3* db, const std::string& sql) {
  char* err = nullptr;
  ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err), SQLITE_OK) << (err ? err : "");
}

// Creates a .db3 with the given DDL and two topics / three messages.
std::string MakeDb3(const TempDir& tmp, const std::string& name, const std::string& ddl,
                    const std::string& topic_cols, const std::string& topic_extra) {
  const std::string path = tmp / name;
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  Sql(db, ddl);
  Sql(db, "INSERT INTO topics (id, " + topic_cols + ") VALUES (1, '/imu', 'sensor_msgs/msg/Imu', 'cdr', ''" +
              topic_extra + "), (5, '/odom', 'nav_msgs/msg/Odometry', 'cdr', ''" + topic_extra + ");");
  Sql(db,
      "INSERT INTO messages (topic_id, timestamp, data) VALUES "
      "(5, 30, x'0001000003'), (1, 10, x'0001000001'), (1, 20, x'0001000002');");
  sqlite3_close(db);
  return path;
}

void ExpectThreeMessages(const std::string& path) {
  Reader r(path);
  EXPECT_EQ(r.Info().storage, Storage::kSqlite3);
  EXPECT_EQ(r.Info().message_count, 3u);
  EXPECT_EQ(r.Info().start_ns, 10);
  EXPECT_EQ(r.Info().end_ns, 30);
  ASSERT_EQ(r.Info().topics.size(), 2u);
  EXPECT_EQ(r.Info().topics[0].info.name, "/imu");
  EXPECT_EQ(r.Info().topics[0].message_count, 2u);
  EXPECT_EQ(r.Info().topics[1].info.type, "nav_msgs/msg/Odometry");
  EXPECT_EQ(r.Info().topics[1].message_count, 1u);
  const auto got = ReadAll(r);
  ASSERT_EQ(got.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(got[i].timestamp_ns, 10 * (i + 1));
    EXPECT_EQ(got[i].data, (std::vector<uint8_t>{0, 1, 0, 0, uint8_t(i + 1)}));
  }
  EXPECT_EQ(got[2].topic, "/odom");
}

TEST(Sqlite, ReadsJazzySchema4) {
  TempDir tmp;
  const std::string path = MakeDb3(
      tmp, "jazzy.db3",
      "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL);"
      "INSERT INTO schema VALUES (4, 'jazzy');"
      "CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,metadata TEXT NOT NULL);"
      "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
      "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL,"
      "type_description_hash TEXT NOT NULL);"
      "CREATE TABLE message_definitions(id INTEGER PRIMARY KEY,topic_type TEXT NOT NULL,"
      "encoding TEXT NOT NULL,encoded_message_definition TEXT NOT NULL,type_description_hash TEXT NOT NULL);"
      "INSERT INTO message_definitions VALUES (1,'sensor_msgs/msg/Imu','ros2msg','...','RIHS01_00');"
      "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
      "timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
      "CREATE INDEX timestamp_idx ON messages (timestamp ASC);",
      "name, type, serialization_format, offered_qos_profiles, type_description_hash",
      ", 'RIHS01_00'");
  ExpectThreeMessages(path);
}

TEST(Sqlite, ReadsPreHumbleWithoutSchemaTable) {
  TempDir tmp;
  const std::string path = MakeDb3(
      tmp, "foxy.db3",
      "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
      "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL);"
      "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
      "timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
      "CREATE INDEX timestamp_idx ON messages (timestamp ASC);",
      "name, type, serialization_format, offered_qos_profiles", "");
  ExpectThreeMessages(path);
}

TEST(Sqlite, MessagesOnUnknownTopicId) {
  TempDir tmp;
  const std::string path = MakeDb3(
      tmp, "bad.db3",
      "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
      "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL);"
      "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
      "timestamp INTEGER NOT NULL, data BLOB NOT NULL);",
      "name, type, serialization_format, offered_qos_profiles", "");
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  Sql(db, "INSERT INTO messages (topic_id, timestamp, data) VALUES (42, 1, x'00010000');");
  sqlite3_close(db);
  ExpectBagError([&] { OpenAndReadAll(path); }, "topic id 42");
}

TEST(Sqlite, NotABag) {
  TempDir tmp;
  sqlite3* db = nullptr;
  const std::string path = tmp / "other.db3";
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  Sql(db, "CREATE TABLE foo(x INTEGER);");
  sqlite3_close(db);
  ExpectBagError([&] { OpenAndReadAll(path); }, "not a rosbag2 sqlite3 bag");
}

TEST(Sqlite, TruncatedDb3) {
  TempDir tmp;
  WriterOptions opt;
  opt.storage = Storage::kSqlite3;
  {
    Writer w(tmp / "bag", opt);
    w.AddTopic({"/p", "sensor_msgs/msg/PointCloud2", "cdr", ""});
    std::vector<uint8_t> d(20000, 7);
    d[1] = 1;
    for (int i = 0; i < 50; ++i) w.Write("/p", i, d);
  }
  const std::string file = tmp / "bag/bag_0.db3";
  const auto b = ReadFileBytes(file);
  for (size_t keep : {b.size() / 2, size_t(5000), size_t(50)}) {
    WriteFileBytes(file, std::vector<uint8_t>(b.begin(), b.begin() + static_cast<long>(keep)));
    EXPECT_THROW(OpenAndReadAll(file), BagError) << "kept " << keep;
  }
}

}  // namespace
