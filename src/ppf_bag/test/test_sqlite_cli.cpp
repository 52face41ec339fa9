// Our .db3 checked by an independent reader: the sqlite3 command line shell.
#include <gtest/gtest.h>

#include <filesystem>

#include "ppf_bag/bag.hpp"
#include "test_util.hpp"

using namespace ppf::bag;
using ppf::bag::test::Run;
using ppf::bag::test::ShellQuote;
using ppf::bag::test::TempDir;

namespace {

std::string Sqlite(const std::string& db, const std::string& sql) {
  const auto r = Run(std::string(SQLITE3_CLI) + " -batch -readonly " + ShellQuote(db) + " " +
                     ShellQuote(sql) + " 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return r.output;
}

TEST(SqliteCli, IndependentReaderSeesOurBag) {
  if (std::string(SQLITE3_CLI).empty()) {
    GTEST_SKIP() << "sqlite3 command line shell not found at configure time (apt-get install sqlite3)";
  }
  TempDir tmp;
  const std::string dir = tmp / "cli";
  WriterOptions opt;
  opt.storage = Storage::kSqlite3;
  {
    Writer w(dir, opt);
    w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", ""});
    w.AddTopic({"/odom", "nav_msgs/msg/Odometry", "cdr", "- history: 1\n"});
    w.Write("/odom", 1500, std::vector<uint8_t>{0, 1, 0, 0, 0xAB});
    for (uint8_t i = 0; i < 3; ++i) {
      w.Write("/imu", 1000 + 1000 * i, std::vector<uint8_t>{0, 1, 0, 0, i, 0xFF});
    }
    w.Close();
  }
  const std::string db = dir + "/cli_0.db3";
  EXPECT_EQ(Sqlite(db, "PRAGMA integrity_check;"), "ok\n");
  EXPECT_EQ(Sqlite(db, "SELECT schema_version, ros_distro FROM schema;"), "3|humble\n");
  EXPECT_EQ(Sqlite(db, "SELECT id, name, type, serialization_format FROM topics ORDER BY id;"),
            "1|/imu|sensor_msgs/msg/Imu|cdr\n2|/odom|nav_msgs/msg/Odometry|cdr\n");
  EXPECT_EQ(Sqlite(db, "SELECT hex(offered_qos_profiles) FROM topics WHERE id = 2;"),
            "2D20686973746F72793A20310A\n");  // "- history: 1\n"
  EXPECT_EQ(Sqlite(db, "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id ORDER BY topic_id;"),
            "1|3\n2|1\n");
  EXPECT_EQ(Sqlite(db, "SELECT topic_id, timestamp, hex(data) FROM messages ORDER BY id;"),
            "2|1500|00010000AB\n1|1000|0001000000FF\n1|2000|0001000001FF\n1|3000|0001000002FF\n");
  const std::string schema = Sqlite(db, ".schema");
  EXPECT_NE(schema.find("CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
                        "timestamp INTEGER NOT NULL, data BLOB NOT NULL);"),
            std::string::npos)
      << schema;
  EXPECT_NE(schema.find("CREATE INDEX timestamp_idx ON messages (timestamp ASC);"), std::string::npos);
  EXPECT_NE(schema.find("CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT "
                        "NULL,metadata TEXT NOT NULL);"),
            std::string::npos);
  // The index is usable for time-range queries, as rosbag2's reader does.
  const std::string plan =
      Sqlite(db, "EXPLAIN QUERY PLAN SELECT * FROM messages WHERE timestamp >= 2000 ORDER BY timestamp;");
  EXPECT_NE(plan.find("timestamp_idx"), std::string::npos) << plan;
  // No journal or WAL file is left behind after Close().
  EXPECT_FALSE(std::filesystem::exists(db + "-journal"));
  EXPECT_FALSE(std::filesystem::exists(db + "-wal"));
}

}  // namespace
