// Faults while the pipeline runs: the replay killed with SIGKILL and started again, the
// node crashing (SIGKILL) and restarted while the replay goes on, recorders started before and
// after the node. Each time the survivors go on, the node says what happened, odometry flows
// again and the recorded bags hold what was published. (The IMU falling silent mid-run is in
// test_hostile: the Cyclone peer drops it.)
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "dds_test_util.hpp"
#include "nav_msgs/msg/Odometry.h"
#include "ppf_bag/bag.hpp"
#include "ppf_bridge/convert.hpp"
#include "ppf_dds_node/child_process.hpp"
#include "ppf_msgs_cdr/cdr.hpp"
#include "test_domain.hpp"
#include "tool_paths.hpp"

using namespace std::chrono_literals;
using ppf::dds::ChildProcess;
using ppf::test::CountLinesWith;
using ppf::test::kProfileUdp;
using ppf::test::kProfiles;
using ppf::test::SummaryField;

namespace {

class Faults : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim_ = ppf::test::FindTool("ppf_sim", PPF_SIM_CONFIGURED);
    if (sim_.empty()) return;
    dir_ = ppf::test::TempDir("ppf_dds_faults");
    // 20 s indoors with a VLP-16, at rest for the first 16 s: a node started mid-run can still
    // initialize (it needs 1 s at rest) before the motion starts, and a restarted node, which the
    // replay matches within ~1 s over UDP, has most of the bag to show that it publishes.
    ASSERT_TRUE(
        ppf::test::SimulateSequence(sim_,
                                    {"--scene", "indoor", "--lidar", "vlp16", "--duration", "20",
                                     "--static", "16", "--seed", "4", "--storage", "mcap"},
                                    dir_ + "/bag", dir_ + "/sim.log"));
    for (const auto& t : ppf::bag::ReadInfo(dir_ + "/bag").topics) {
      if (t.info.name == "/points") clouds_ = static_cast<int>(t.message_count);
    }
  }
  // The suite's directory goes only when every test passed: a failed test's logs (node, replay,
  // recorders) are what says why, and CI shows only the test's own output.
  static void TearDownTestSuite() {
    if (!dir_.empty() && !failed_) std::system(("rm -rf '" + dir_ + "'").c_str());
  }
  void TearDown() override {
    if (!HasFailure()) return;
    failed_ = true;
    if (run_dir_.empty()) return;
    std::printf("logs kept in %s; their last lines:\n", run_dir_.c_str());
    std::fflush(stdout);
    std::system(("for f in '" + run_dir_ + "'/*.log; do echo \"== $f\"; tail -n 25 \"$f\"; done")
                    .c_str());
  }
  void SetUp() override {
    if (sim_.empty()) GTEST_SKIP() << "ppf_sim not found (PATH or configure time): build ppf_sim";
    ASSERT_GE(clouds_, 195);
  }

  // A run directory, a node config on the loopback test profile, and the common tool arguments.
  std::string NewRun(const std::string& name, int domain) {
    const std::string dir = dir_ + "/" + name;
    run_dir_ = dir;
    mkdir(dir.c_str(), 0755);
    std::ofstream cfg(dir + "/node.yaml");
    // UDP only: over shared memory a SIGKILLed participant can leave the survivors deaf to the
    // one restarted in its place (Fast DDS 2.9; docs/reliability.md, "Crash and restart (shared
    // memory)").
    cfg << "dds: {domain_id: " << domain << ", profiles_file: \"" << kProfiles
        << "\", profile_name: " << kProfileUdp << "}\n"
        << "core: {config_file: \"" << PPF_CONFIG_DIR << "/vlp16.yaml\"}\n"
        << "trajectory: {tum_file: \"" << dir << "/node.tum\"}\n";
    dds_ = {"--domain", std::to_string(domain), "--profiles", kProfiles, "--profile", kProfileUdp};
    return dir;
  }
  void StartNode(ChildProcess& node, const std::string& dir, const std::string& log) {
    ASSERT_TRUE(node.Start({PPF_NODE_EXE, "--config", dir + "/node.yaml"}, {}, dir + "/" + log));
    std::string line;
    ASSERT_TRUE(node.WaitForLine("PPF_NODE_READY", &line, 20s)) << "see " << dir << "/" << log;
  }
  void StartReplay(ChildProcess& replay, const std::string& dir, const std::string& log) {
    std::vector<std::string> args = {PPF_REPLAY_EXE, "--bag", dir_ + "/bag", "--wait-matched",
                                     "15"};
    args.insert(args.end(), dds_.begin(), dds_.end());
    ASSERT_TRUE(replay.Start(args, {}, dir + "/" + log));
    std::string line;
    ASSERT_TRUE(replay.WaitForLine("PPF_REPLAY_START", &line, 20s)) << "see " << dir << "/" << log;
  }
  void StartRecorder(ChildProcess& rec, const std::string& dir, const std::string& name) {
    std::vector<std::string> args = {PPF_RECORD_EXE,   "--topics",  "/odometry", "--out",
                                     dir + "/" + name, "--storage", "sqlite3"};
    args.insert(args.end(), dds_.begin(), dds_.end());
    ASSERT_TRUE(rec.Start(args, {}, dir + "/" + name + ".log"));
    std::string line;
    ASSERT_TRUE(rec.WaitForLine("PPF_RECORD_READY", &line, 20s));
  }
  // Stops a recorder; returns its /odometry count (-1 on failure) after checking that the bag
  // holds exactly that many odometry messages, each decodable.
  int StopRecorder(ChildProcess& rec, const std::string& bag) {
    rec.Signal(SIGINT);
    std::string done;
    if (!rec.WaitForLine("PPF_RECORD_DONE", &done, 20s)) return -1;
    EXPECT_TRUE(ppf::dds::ExitedWith(rec.Wait(10s), 0));
    std::printf("%s: %s\n", bag.c_str(), done.c_str());
    const int said = static_cast<int>(SummaryField(done, "/odometry"));
    ppf::bag::Reader reader(bag);
    ppf::bag::Message m;
    int in_bag = 0;
    while (reader.Next(m)) {
      nav_msgs::msg::Odometry o;
      EXPECT_EQ(m.topic, "/odometry");
      EXPECT_TRUE(ppf::msgs::DecodeCdr(m.data, &o));
      ++in_bag;
    }
    EXPECT_EQ(in_bag, said) << bag;
    return said;
  }

  static std::string sim_, dir_;
  static int clouds_;
  static bool failed_;
  std::string run_dir_;
  std::vector<std::string> dds_;
};
std::string Faults::sim_, Faults::dir_;
int Faults::clouds_ = 0;
bool Faults::failed_ = false;

// Stamps of a TUM file and how often they jump back.
std::vector<double> TumStamps(const std::string& path) {
  std::stringstream ss(ppf::test::ReadTextFile(path));
  std::vector<double> t;
  std::string line;
  while (std::getline(ss, line)) t.push_back(std::atof(line.c_str()));
  return t;
}

}  // namespace

// ppf_replay killed with SIGKILL 3 s into the bag, then started again from the beginning: its
// stamps go back 3 s. The node restarts its core once (both streams jumped back), initializes
// again and publishes odometry for the second run; nothing is counted lost.
TEST_F(Faults, ReplayKilledWithSigkillAndRestartedNodeRestartsOnceAndResumes) {
  const std::string dir = NewRun("replay_kill", ppf::test::TestDomainId(41));
  ChildProcess node, first, second;
  ASSERT_NO_FATAL_FAILURE(StartNode(node, dir, "node.log"));
  ASSERT_NO_FATAL_FAILURE(StartReplay(first, dir, "replay1.log"));
  std::this_thread::sleep_for(3s);
  first.Signal(SIGKILL);
  const int status = first.Wait(5s);
  EXPECT_TRUE(status >= 0 && WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
  ASSERT_NO_FATAL_FAILURE(StartReplay(second, dir, "replay2.log"));
  std::string line;
  ASSERT_TRUE(second.WaitForLine("PPF_REPLAY_DONE", &line, 40s));
  EXPECT_TRUE(ppf::dds::ExitedWith(second.Wait(10s), 0));
  std::this_thread::sleep_for(1500ms);  // the node works through what it has queued
  std::string s;
  ASSERT_TRUE(ppf::test::StopNodeAndReadSummary(node, &s));
  std::printf("%s\n", s.c_str());
  const std::string log = ppf::test::ReadTextFile(dir + "/node.log");

  // Said what happened: one restart, for the IMU stream jumping back.
  EXPECT_EQ(SummaryField(s, "resets"), 1);
  EXPECT_EQ(CountLinesWith(log, "IMU time jumped back by"), 1) << log;
  EXPECT_EQ(CountLinesWith(log, "core restarted (initialization starts over)"), 1);
  EXPECT_EQ(CountLinesWith(log, "IMU initialized at"), 2);
  EXPECT_GE(SummaryField(s, "time_jumps"), 1);
  EXPECT_EQ(SummaryField(s, "imu_outliers"), 0);
  EXPECT_EQ(SummaryField(s, "scans_malformed"), 0);
  // The second replay is complete and nothing from it is lost, late or dropped.
  EXPECT_EQ(SummaryField(line, "/points"), clouds_);
  EXPECT_EQ(SummaryField(s, "scans_lost"), 0);
  EXPECT_EQ(SummaryField(s, "imu_lost"), 0);
  EXPECT_EQ(SummaryField(s, "scans_late"), 0);
  EXPECT_EQ(SummaryField(s, "scans_dropped"), 0);
  // Odometry from both runs: the trajectory jumps back once, and the second run gives a pose for
  // every scan after its initialization (~1 s).
  const std::vector<double> t = TumStamps(dir + "/node.tum");
  ASSERT_EQ(static_cast<double>(t.size()), SummaryField(s, "odometry_published"));
  size_t jumps = 0, after = 0;
  for (size_t i = 1; i < t.size(); ++i) {
    if (t[i] < t[i - 1]) ++jumps;
    if (jumps == 1) ++after;
  }
  EXPECT_EQ(jumps, 1u);
  EXPECT_GE(after, static_cast<size_t>(clouds_) - 15) << "odometry after the replay restarted";
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

// ppf_node crashes (SIGKILL) 2 s into a replay and is started again while the replay goes on.
// Recorder 1 was started before the first node, recorder 2 after the second. The replay does not
// notice beyond its subscriber going away; the new node initializes on the data still at rest and
// publishes; recorder 1 holds the odometry of both nodes, recorder 2 that of the second.
TEST_F(Faults, NodeRestartedWhileReplayRunsAndRecordersStartedBeforeAndAfterIt) {
  const std::string dir = NewRun("node_restart", ppf::test::TestDomainId(42));
  ChildProcess rec_before, node_a, replay, node_b, rec_after;
  ASSERT_NO_FATAL_FAILURE(StartRecorder(rec_before, dir, "rec_before"));
  ASSERT_NO_FATAL_FAILURE(StartNode(node_a, dir, "node_a.log"));
  std::string line;
  ASSERT_TRUE(rec_before.WaitForLine("PPF_RECORD_MATCHED /odometry 1", &line, 20s));
  ASSERT_NO_FATAL_FAILURE(StartReplay(replay, dir, "replay.log"));
  std::this_thread::sleep_for(2000ms);
  node_a.Kill();
  ASSERT_NO_FATAL_FAILURE(StartNode(node_b, dir, "node_b.log"));
  ASSERT_NO_FATAL_FAILURE(StartRecorder(rec_after, dir, "rec_after"));
  ASSERT_TRUE(rec_after.WaitForLine("PPF_RECORD_MATCHED /odometry 1", &line, 20s));
  ASSERT_TRUE(replay.WaitForLine("PPF_REPLAY_DONE", &line, 40s));
  EXPECT_TRUE(ppf::dds::ExitedWith(replay.Wait(10s), 0));
  EXPECT_EQ(SummaryField(line, "/points"), clouds_);
  std::this_thread::sleep_for(1500ms);
  std::string s;
  ASSERT_TRUE(ppf::test::StopNodeAndReadSummary(node_b, &s));
  std::printf("%s\n", s.c_str());
  const int before = StopRecorder(rec_before, dir + "/rec_before");
  const int after = StopRecorder(rec_after, dir + "/rec_after");

  // Node A had initialized before it died (it had 2 s, 1 s of which initialization).
  const std::string log_a = ppf::test::ReadTextFile(dir + "/node_a.log");
  EXPECT_EQ(CountLinesWith(log_a, "IMU initialized at"), 1);
  // Node B joined mid-stream: no loss counted for what came before it, initialized at rest,
  // then a pose for every scan.
  const std::string log_b = ppf::test::ReadTextFile(dir + "/node_b.log");
  EXPECT_EQ(CountLinesWith(log_b, "IMU initialized at"), 1) << log_b;
  EXPECT_EQ(SummaryField(s, "scans_lost"), 0);
  EXPECT_EQ(SummaryField(s, "imu_lost"), 0);
  EXPECT_EQ(SummaryField(s, "resets"), 0);
  const double b_published = SummaryField(s, "odometry_published");
  EXPECT_EQ(b_published,
            SummaryField(s, "scans_processed") - SummaryField(s, "scans_initializing"));
  EXPECT_GE(b_published, 20);  // at least the 2 s of motion
  // B's trajectory (A was killed before writing its own) reaches the end of the bag.
  const std::vector<double> t = TumStamps(dir + "/node.tum");
  EXPECT_EQ(static_cast<double>(t.size()), b_published);
  ASSERT_FALSE(t.empty());
  EXPECT_GT(t.back(), 1700000000.0 + 19.8);  // ppf_sim's default start time + the bag's end
  // Recorder 1 kept recording across the crash: A's odometry and all of B's.
  EXPECT_GE(before, b_published + 5);
  // Recorder 2 matched B within B's 1 s of initialization: all (or nearly all) of B's. Under
  // ThreadSanitizer, with the fuzzers running beside the stage, the recorder's own start and
  // discovery took 3 s once (141 of 160 recorded): there it is only required to have matched
  // within 4 s (the Release stage asserts the tight bound).
  EXPECT_LE(after, b_published);
  EXPECT_GE(after, b_published - (ppf::test::kUnderTsan ? 40 : 3));
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}
