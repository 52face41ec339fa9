// Split bags (several storage files listed in metadata.yaml) and the ppf_bag_info CLI.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "ppf_bag/bag.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace ppf::bag;
using ppf::bag::test::ReadAll;
using ppf::bag::test::ShellQuote;
using ppf::bag::test::TempDir;

namespace {

void WritePart(const std::string& dir, Storage storage, int64_t t0) {
  WriterOptions opt;
  opt.storage = storage;
  Writer w(dir, opt);
  w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", ""});
  w.AddTopic({"/odom", "nav_msgs/msg/Odometry", "cdr", ""});
  for (int i = 0; i < 5; ++i) {
    w.Write("/imu", t0 + 10 * i, std::vector<uint8_t>{0, 1, 0, 0, uint8_t(t0 + i)});
  }
  w.Write("/odom", t0 + 25, std::vector<uint8_t>{0, 1, 0, 0, 0xEE});
}

// Two storage files whose time ranges overlap, as rosbag2 lists them after a split.
TEST(MultiFile, MergesFilesInTimeOrder) {
  for (Storage st : {Storage::kSqlite3, Storage::kMcap}) {
    TempDir tmp;
    const std::string ext = st == Storage::kMcap ? ".mcap" : ".db3";
    WritePart(tmp / "run", st, 100);
    WritePart(tmp / "part2", st, 105);
    fs::rename(tmp / ("part2/part2_0" + ext), tmp / ("run/run_1" + ext));
    std::string meta;
    {
      std::ifstream in(tmp / "run/metadata.yaml");
      meta.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string one = "- run_0" + ext;
    ASSERT_NE(meta.find(one), std::string::npos) << meta;
    meta.insert(meta.find(one) + one.size(), "\n    - run_1" + ext);
    std::ofstream(tmp / "run/metadata.yaml", std::ios::trunc) << meta;

    Reader r(tmp / "run");
    EXPECT_EQ(r.Info().message_count, 12u);
    EXPECT_EQ(r.Info().start_ns, 100);
    EXPECT_EQ(r.Info().end_ns, 145);
    ASSERT_EQ(r.Info().topics.size(), 2u);
    EXPECT_EQ(r.Info().topics[0].message_count, 10u);
    EXPECT_EQ(r.Info().topics[1].message_count, 2u);
    const auto msgs = ReadAll(r);
    ASSERT_EQ(msgs.size(), 12u);
    const int64_t want[12] = {100, 105, 110, 115, 120, 125, 125, 130, 130, 135, 140, 145};
    for (size_t i = 0; i < 12; ++i) EXPECT_EQ(msgs[i].timestamp_ns, want[i]) << i;
    // Tie at 125: /odom of file 0 before /imu of file 1 (file order).
    EXPECT_EQ(msgs[5].topic, "/odom");
    EXPECT_EQ(msgs[6].topic, "/imu");
    r.SetTopicFilter({"/odom"});
    EXPECT_EQ(ppf::bag::test::Stamps(ReadAll(r)), (std::vector<int64_t>{125, 130}));
  }
}

TEST(BagInfoCli, PrintsStorageCountsAndTopics) {
  TempDir tmp;
  WritePart(tmp / "cli", Storage::kMcap, 1700000000000000000LL);
  const auto r = ppf::bag::test::Run(std::string(PPF_BAG_INFO_EXE) + " " + ShellQuote(tmp / "cli") + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Storage id:        mcap"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Duration:          0.000000040s"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Messages:          6"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Start:             Nov 14 2023 22:13:20.000000000 UTC"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("Topic: /imu | Type: sensor_msgs/msg/Imu | Count: 5 | Serialization Format: cdr"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("Topic: /odom | Type: nav_msgs/msg/Odometry | Count: 1"), std::string::npos);

  const auto bad = ppf::bag::test::Run(std::string(PPF_BAG_INFO_EXE) + " /nonexistent/bag 2>&1");
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.output.find("no such bag"), std::string::npos) << bad.output;
}

}  // namespace
