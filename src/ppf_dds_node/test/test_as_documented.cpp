// The tools run exactly as the READMEs show them: no transport profile in the environment, no
// --profiles, only --domain so that parallel test runs stay apart. A user doing so can lose most
// HDL-32 clouds between ppf_replay and ppf_node when the replay falls back to Fast DDS's
// defaults, and a core preset passed as the node config must not start a node on defaults.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "dds_test_util.hpp"
#include "ppf_bag/bag.hpp"
#include "ppf_dds_node/child_process.hpp"
#include "test_domain.hpp"
#include "tool_paths.hpp"

using namespace std::chrono_literals;
using ppf::dds::ChildProcess;
using ppf::test::SummaryField;

namespace {

class AsDocumented : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // What a user's shell has when following the README: no profile chosen anywhere.
    unsetenv("FASTRTPS_DEFAULT_PROFILES_FILE");
    sim_ = ppf::test::FindTool("ppf_sim", PPF_SIM_CONFIGURED);
    if (sim_.empty()) return;
    dir_ = ppf::test::TempDir("ppf_dds_documented");
    // 5 s of urban HDL-32 (the sensor): ~1.5 MB clouds, three times Fast DDS's default
    // shared-memory segment.
    ASSERT_TRUE(ppf::test::SimulateSequence(sim_,
                                            {"--scene", "urban", "--lidar", "hdl32", "--duration",
                                             "5", "--seed", "2", "--storage", "mcap"},
                                            dir_ + "/bag", dir_ + "/sim.log"));
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) std::system(("rm -rf '" + dir_ + "/bag'").c_str());
  }
  void SetUp() override {
    if (sim_.empty()) GTEST_SKIP() << "ppf_sim not found (PATH or configure time): build ppf_sim";
    // Fast DDS would also load this file from the working directory by itself.
    ASSERT_NE(access("DEFAULT_FASTRTPS_PROFILES.xml", F_OK), 0)
        << "a DEFAULT_FASTRTPS_PROFILES.xml in the working directory chooses the transport";
  }
  static std::string sim_, dir_;
};
std::string AsDocumented::sim_, AsDocumented::dir_;

// README: `ppf_node --config config/node_hdl32.yaml`, `ppf_record --topics ... --out DIR
// --storage sqlite3`, `ppf_replay --bag DIR --wait-matched 10`.
TEST_F(AsDocumented, ReplayIntoNodeLosesNoCloudWithoutAProfileInTheEnvironment) {
  const std::string dir = dir_ + "/run";
  ASSERT_EQ(mkdir(dir.c_str(), 0755), 0);
  const std::string domain = std::to_string(ppf::test::TestDomainId(60));
  ChildProcess node, record, replay;
  ASSERT_TRUE(
      node.Start({PPF_NODE_EXE, "--config", PPF_CONFIG_DIR "/node_hdl32.yaml", "--domain", domain},
                 {}, dir + "/node.log"));
  std::string line;
  ASSERT_TRUE(node.WaitForLine("PPF_NODE_READY", &line, 20s)) << "see " << dir << "/node.log";
  ASSERT_TRUE(record.Start({PPF_RECORD_EXE, "--topics", "/odometry", "--out", dir + "/rec",
                            "--storage", "sqlite3", "--domain", domain},
                           {}, dir + "/record.log"));
  ASSERT_TRUE(record.WaitForLine("PPF_RECORD_MATCHED /odometry 1", &line, 20s))
      << "see " << dir << "/record.log";
  ASSERT_TRUE(replay.Start(
      {PPF_REPLAY_EXE, "--bag", dir_ + "/bag", "--wait-matched", "10", "--domain", domain}, {},
      dir + "/replay.log"));
  ASSERT_TRUE(replay.WaitForLine("PPF_REPLAY_DONE", &line, 40s)) << "see " << dir << "/replay.log";
  EXPECT_TRUE(ppf::dds::ExitedWith(replay.Wait(10s), 0));
  // Each tool says which transport it chose (the project's profile, found on its own).
  EXPECT_NE(ppf::test::ReadTextFile(dir + "/replay.log").find("shm_udp.xml (project default"),
            std::string::npos);
  EXPECT_NE(ppf::test::ReadTextFile(dir + "/record.log").find("shm_udp.xml (project default"),
            std::string::npos);

  std::this_thread::sleep_for(1500ms);  // the node works through what it has queued
  std::string summary;
  ASSERT_TRUE(ppf::test::StopNodeAndReadSummary(node, &summary));
  record.Signal(SIGINT);
  std::string record_done;
  ASSERT_TRUE(record.WaitForLine("PPF_RECORD_DONE", &record_done, 20s));
  EXPECT_TRUE(ppf::dds::ExitedWith(record.Wait(10s), 0));
  std::printf("%s\n%s\n", summary.c_str(), record_done.c_str());

  double clouds = 0, imus = 0;
  for (const auto& t : ppf::bag::ReadInfo(dir_ + "/bag").topics) {
    if (t.info.name == "/points") clouds = static_cast<double>(t.message_count);
    if (t.info.name == "/imu") imus = static_cast<double>(t.message_count);
  }
  ASSERT_GE(clouds, 45);
  EXPECT_EQ(SummaryField(summary, "scans_lost"), 0);
  EXPECT_EQ(SummaryField(summary, "scans_received"), clouds);
  EXPECT_EQ(SummaryField(summary, "scans_processed"), clouds);
  EXPECT_EQ(SummaryField(summary, "scans_malformed"), 0);
  EXPECT_EQ(SummaryField(summary, "imu_lost"), 0);
  EXPECT_EQ(SummaryField(summary, "imu_received"), imus);
  // Every processed scan with a pose became one odometry message, and the recorder got each.
  const double odom = SummaryField(summary, "odometry_published");
  EXPECT_EQ(odom, clouds - SummaryField(summary, "scans_dropped") -
                      SummaryField(summary, "scans_initializing") -
                      SummaryField(summary, "scans_rejected"));
  EXPECT_GT(odom, 0);
  EXPECT_NE(record_done.find(" /odometry=" + std::to_string(static_cast<int>(odom))),
            std::string::npos)
      << record_done;
}

// A core preset (every key unknown to the node) is the wrong file: refuse, say so, exit 2.
TEST(AsDocumentedConfig, NodeRefusesACorePresetAsItsConfig) {
  const std::string log = ppf::test::TempDir("ppf_dds_wrong_config") + "/node.log";
  ChildProcess node;
  ASSERT_TRUE(node.Start({PPF_NODE_EXE, "--config", PPF_CONFIG_DIR "/vlp16.yaml", "--domain",
                          std::to_string(ppf::test::TestDomainId(61))},
                         {}, log));
  std::string line;
  EXPECT_FALSE(node.WaitForLine("PPF_NODE_READY", &line, 5s));
  EXPECT_TRUE(ppf::dds::ExitedWith(node.Wait(10s), 2));
  const std::string err = ppf::test::ReadTextFile(log);
  EXPECT_NE(err.find("not a ppf_node config"), std::string::npos) << err;
  EXPECT_NE(err.find("core.config_file"), std::string::npos) << err;
}

}  // namespace
