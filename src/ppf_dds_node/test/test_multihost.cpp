// Multi-host, as on a robot whose LiDAR driver runs on another computer: ppf_replay and ppf_node in
// two network namespaces joined by a veth pair, so DDS between them can only go over UDP, with the
// UDP-only profile (config/dds/udp_only.xml) and multicast discovery as a user would run it.
//   - HDL-64 clouds (~3.9 MB) at real-time rate with reliable sensor QoS: every scan and IMU
//     sample arrives, none lost;
//   - the link cut for 2 s mid-drive (`ip link set down`) and restored, with the default
//     best-effort readers: the same node process keeps publishing odometry within the accuracy
//     bound and reports what it lost and the gap.
// Needs root and iproute2 (ip netns, veth); without them every test is skipped with the reason.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "dds_test_util.hpp"
#include "ppf_bag/bag.hpp"
#include "ppf_dds_node/child_process.hpp"
#include "ppf_trajectory/evaluation.hpp"
#include "test_domain.hpp"
#include "tool_paths.hpp"

using namespace std::chrono_literals;
using ppf::dds::ChildProcess;
using ppf::test::SummaryField;

namespace {

const std::string kUdpProfiles = PPF_DDS_CONFIG_DIR "/udp_only.xml";
const std::string kUdpProfile = "ppf_udp_only";
constexpr double kBagSeconds = 10.0;
constexpr double kCutAfterS = 4.5;  // after the replay started; initialization is done by then
constexpr double kCutSeconds = 2.0;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

size_t CountOccurrences(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

// Runs a command to completion; stderr goes to `err_file` so a failure can say why.
bool RunCommand(const std::vector<std::string>& argv, const std::string& err_file,
                std::string* error) {
  ChildProcess p;
  if (!p.Start(argv, {}, err_file)) {
    *error = "cannot start " + argv[0];
    return false;
  }
  if (!ppf::dds::ExitedWith(p.Wait(20s), 0)) {
    std::string cmd;
    for (const auto& a : argv) cmd += a + " ";
    *error = cmd + "failed: " + ReadFile(err_file);
    return false;
  }
  return true;
}

// Two namespaces joined by a veth pair, removed on destruction (deleting a namespace deletes its
// end of the pair and with it the other end). Names carry the test's pid, so a namespace left by
// a killed run is recognised and removed by the next one (RemoveStale).
class TwoHosts {
 public:
  TwoHosts(std::string ip, std::string dir) : ip_(std::move(ip)), dir_(std::move(dir)) {
    const std::string id = std::to_string(getpid());
    node_ns_ = "ppfmh" + id + "n";
    replay_ns_ = "ppfmh" + id + "r";
    node_if_ = "pmh" + id + "n";  // interface names: at most 15 characters
    replay_if_ = "pmh" + id + "r";
  }
  ~TwoHosts() {
    std::string ignored;
    // Ends not moved yet live in the test's own namespace.
    if (veth_created_) Ip({"link", "del", node_if_}, &ignored);
    if (node_created_) Ip({"netns", "del", node_ns_}, &ignored);
    if (replay_created_) Ip({"netns", "del", replay_ns_}, &ignored);
  }

  // Namespaces of earlier runs whose process is gone (a test killed by its timeout).
  static void RemoveStale(const std::string& ip, const std::string& dir) {
    ChildProcess list;
    if (!list.Start({ip, "netns", "list"})) return;
    std::string line;
    std::vector<std::string> stale;
    while (list.ReadLine(&line, 5s)) {
      const std::string name = line.substr(0, line.find(' '));
      if (name.rfind("ppfmh", 0) != 0 || name.size() < 7) continue;
      const std::string pid = name.substr(5, name.size() - 6);
      if (pid.find_first_not_of("0123456789") != std::string::npos) continue;
      if (access(("/proc/" + pid).c_str(), F_OK) != 0) stale.push_back(name);
    }
    list.Wait(5s);
    std::string ignored;
    for (const auto& name : stale) {
      RunCommand({ip, "netns", "del", name}, dir + "/ip_stale.err", &ignored);
      // A run killed between creating the pair and moving it left it here.
      const std::string pid = name.substr(5, name.size() - 6);
      RunCommand({ip, "link", "del", "pmh" + pid + "n"}, dir + "/ip_stale.err", &ignored);
    }
  }

  // False with `error` when the sandbox does not allow namespaces or veth (a skip, not a bug).
  bool Create(std::string* error) {
    if (!Ip({"netns", "add", node_ns_}, error)) return false;
    node_created_ = true;
    if (!Ip({"netns", "add", replay_ns_}, error)) return false;
    replay_created_ = true;
    veth_created_ =
        Ip({"link", "add", node_if_, "type", "veth", "peer", "name", replay_if_}, error);
    return veth_created_;
  }

  // Moves the ends into the namespaces, addresses them and brings everything up.
  bool Configure(std::string* error) {
    if (!Ip({"link", "set", node_if_, "netns", node_ns_}, error) ||
        !Ip({"link", "set", replay_if_, "netns", replay_ns_}, error)) {
      return false;
    }
    veth_created_ = false;  // now deleted with the namespaces
    return Ip({"-n", node_ns_, "addr", "add", "10.77.0.1/24", "dev", node_if_}, error) &&
           Ip({"-n", replay_ns_, "addr", "add", "10.77.0.2/24", "dev", replay_if_}, error) &&
           Ip({"-n", node_ns_, "link", "set", "lo", "up"}, error) &&
           Ip({"-n", replay_ns_, "link", "set", "lo", "up"}, error) &&
           Ip({"-n", node_ns_, "link", "set", node_if_, "up"}, error) &&
           SetReplayLink(true, error) &&
           // Multicast discovery (239.255.0.1) needs a route, as on any host with a default one.
           Ip({"-n", node_ns_, "route", "add", "default", "dev", node_if_}, error);
  }

  // Cuts or restores the link at the replay's end. `ip link set down` flushes the routes of the
  // interface, so restoring it also restores the default route, as the network would.
  bool SetReplayLink(bool up, std::string* error) {
    if (!up) return Ip({"-n", replay_ns_, "link", "set", replay_if_, "down"}, error);
    return Ip({"-n", replay_ns_, "link", "set", replay_if_, "up"}, error) &&
           Ip({"-n", replay_ns_, "route", "replace", "default", "dev", replay_if_}, error);
  }

  // argv prefix that runs a program inside a namespace.
  std::vector<std::string> InNode() const { return {ip_, "netns", "exec", node_ns_}; }
  std::vector<std::string> InReplay() const { return {ip_, "netns", "exec", replay_ns_}; }

 private:
  bool Ip(std::vector<std::string> args, std::string* error) {
    args.insert(args.begin(), ip_);
    return RunCommand(args, dir_ + "/ip.err", error);
  }

  std::string ip_, dir_;
  std::string node_ns_, replay_ns_, node_if_, replay_if_;
  bool node_created_ = false, replay_created_ = false, veth_created_ = false;
};

struct RunResult {
  std::string summary;
  std::string replay_done;
  std::string node_log;
  double cut_at_s = -1;  // seconds after the replay started
  double restored_at_s = -1;
};

class MultiHost : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (geteuid() != 0) {
      skip_ = "needs root for network namespaces (ip netns add, veth)";
      return;
    }
    ip_ = ppf::test::FindTool("ip", "");
    if (ip_.empty()) {
      skip_ = "iproute2 ('ip') not found on PATH";
      return;
    }
    dir_ = ppf::test::TempDir("ppf_dds_multihost");
    TwoHosts::RemoveStale(ip_, dir_);
    {
      // Probe: a sandbox may refuse namespaces or veth even to root (no CAP_SYS_ADMIN, no veth
      // module). That is the environment, not the node: skip and say so.
      TwoHosts probe(ip_, dir_);
      std::string error;
      if (!probe.Create(&error)) {
        skip_ = "network namespaces or veth not available here: " + error;
        return;
      }
    }
    const std::string sim = ppf::test::FindTool("ppf_sim", PPF_SIM_CONFIGURED);
    if (sim.empty()) {
      skip_ = "ppf_sim not found (PATH or configure time): build ppf_sim";
      return;
    }
    // Urban drive with an HDL-64 (~122k points, ~3.9 MB per cloud), 2.5 s static start.
    ChildProcess p;
    ASSERT_TRUE(p.Start(
        {sim, "--scene", "urban", "--lidar", "hdl64", "--duration", std::to_string(kBagSeconds),
         "--seed", "3", "--storage", "mcap", "--out", dir_ + "/bag"},
        {}, dir_ + "/sim.log"));
    ASSERT_TRUE(ppf::dds::ExitedWith(p.Wait(180s), 0)) << "ppf_sim failed, see " << dir_;
    for (const auto& t : ppf::bag::ReadInfo(dir_ + "/bag").topics) {
      if (t.info.name == "/points") bag_scans_ = static_cast<double>(t.message_count);
      if (t.info.name == "/imu") bag_imus_ = static_cast<double>(t.message_count);
    }
    // The UDP profile asks for 8 MB socket buffers; the kernel grants up to rmem_max.
    std::printf("net.core.rmem_max %s", ReadFile("/proc/sys/net/core/rmem_max").c_str());
  }
  static void TearDownTestSuite() {
    // The clouds (~390 MB) go; ground truth and the node's logs stay for inspection.
    if (!dir_.empty()) std::system(("rm -f '" + dir_ + "'/bag/*.mcap").c_str());
  }
  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_;
    ASSERT_GT(bag_scans_, 90);
  }

  // Node in one namespace, replay in the other, real time; with cut_link the link goes down
  // kCutAfterS after the replay started, for kCutSeconds. `reliable` sets the node's sensor
  // readers to reliable (the replay's writers are reliable, 50 deep).
  void Run(const std::string& dir, bool cut_link, bool reliable, RunResult* out) {
    ASSERT_EQ(mkdir(dir.c_str(), 0755), 0);
    TwoHosts net(ip_, dir);
    std::string error;
    ASSERT_TRUE(net.Create(&error)) << error;
    ASSERT_TRUE(net.Configure(&error)) << error;
    const int domain = ppf::test::TestDomainId(cut_link ? 1 : 0);
    {
      std::ofstream cfg(dir + "/node.yaml");
      cfg << "dds: {domain_id: " << domain << ", profiles_file: \"" << kUdpProfiles
          << "\", profile_name: " << kUdpProfile << "}\n"
          << "core: {config_file: \"" << PPF_CONFIG_DIR << "/hdl64.yaml\", calibration_file: \""
          << dir_ << "/bag/calibration.yaml\"}\n"
          << "trajectory: {tum_file: \"" << dir << "/node.tum\"}\n"
          << "qos: {sensor_reliability: " << (reliable ? "reliable" : "best_effort") << "}\n";
    }
    std::vector<std::string> node_cmd = net.InNode();
    node_cmd.insert(node_cmd.end(), {PPF_NODE_EXE, "--config", dir + "/node.yaml"});
    ChildProcess node, replay;
    ASSERT_TRUE(node.Start(node_cmd, {}, dir + "/node.log"));
    std::string line;
    ASSERT_TRUE(node.WaitForLine("PPF_NODE_READY", &line, 30s)) << "see " << dir << "/node.log";
    std::vector<std::string> replay_cmd = net.InReplay();
    replay_cmd.insert(replay_cmd.end(), {PPF_REPLAY_EXE, "--bag", dir_ + "/bag", "--rate", "1",
                                         "--wait-matched", "30", "--domain", std::to_string(domain),
                                         "--profiles", kUdpProfiles, "--profile", kUdpProfile});
    ASSERT_TRUE(replay.Start(replay_cmd, {}, dir + "/replay.log"));
    // Discovery over the veth (multicast): the replay waits until the node's readers matched.
    ASSERT_TRUE(replay.WaitForLine("PPF_REPLAY_START", &line, 40s))
        << "the participants did not discover each other across the namespaces; see " << dir;
    const auto start = std::chrono::steady_clock::now();
    const auto since_start = [&start] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    if (cut_link) {
      std::this_thread::sleep_until(start + std::chrono::duration<double>(kCutAfterS));
      ASSERT_TRUE(net.SetReplayLink(false, &error)) << error;
      out->cut_at_s = since_start();
      std::this_thread::sleep_for(std::chrono::duration<double>(kCutSeconds));
      ASSERT_TRUE(net.SetReplayLink(true, &error)) << error;
      out->restored_at_s = since_start();
    }
    ASSERT_TRUE(replay.WaitForLine("PPF_REPLAY_DONE", &out->replay_done,
                                   std::chrono::seconds(static_cast<int>(kBagSeconds) + 30)))
        << "replay did not finish";
    EXPECT_TRUE(ppf::dds::ExitedWith(replay.Wait(10s), 0));
    // The node works through its queue (a few HDL-64 scans), then is stopped as a user would.
    std::this_thread::sleep_for(2s);
    node.Signal(SIGINT);
    ASSERT_TRUE(node.WaitForLine("PPF_NODE_SUMMARY", &out->summary, 30s));
    EXPECT_TRUE(ppf::dds::ExitedWith(node.Wait(10s), 0));
    out->node_log = ReadFile(dir + "/node.log");
    std::printf("%s\n%s\n", out->replay_done.c_str(), out->summary.c_str());
    if (cut_link) {
      std::printf("link down at %.2f s, up at %.2f s after the replay started\n", out->cut_at_s,
                  out->restored_at_s);
    }
    // One node process throughout: it came up once and was never restarted.
    EXPECT_EQ(CountOccurrences(out->node_log, "ppf_node up:"), 1u);
  }

  static std::string skip_, ip_, dir_;
  static double bag_scans_, bag_imus_;
};
std::string MultiHost::skip_, MultiHost::ip_, MultiHost::dir_;
double MultiHost::bag_scans_ = 0, MultiHost::bag_imus_ = 0;

// Every received scan is processed, dropped for a busy core, malformed or late: none vanishes.
void ExpectScansAccountedFor(const std::string& s) {
  EXPECT_EQ(SummaryField(s, "scans_processed") + SummaryField(s, "scans_dropped") +
                SummaryField(s, "scans_malformed") + SummaryField(s, "scans_late"),
            SummaryField(s, "scans_received"));
}

// Reliable, because best effort cannot promise this here: the kernel caps the socket buffers the
// profile asks for (8 MB) at net.core.rmem_max, which the test's namespaces may not raise (denied
// here), and a 3.9 MB cloud is dozens of datagrams: one dropped while the receive thread waits for
// a core loses the whole cloud (counted in scans_lost; the link-cut test asserts that accounting).
// Reliable readers have the writer resend the missing fragments.
TEST_F(MultiHost, RealTimeHdl64OverUdpLosesNothing) {
  RunResult run;
  Run(dir_ + "/rt", false, true, &run);
  ASSERT_FALSE(HasFatalFailure());
  const std::string& s = run.summary;
  EXPECT_NE(run.replay_done.find("/points=" + std::to_string(static_cast<int>(bag_scans_))),
            std::string::npos);
  EXPECT_EQ(SummaryField(s, "scans_received"), bag_scans_);
  EXPECT_EQ(SummaryField(s, "scans_lost"), 0);
  EXPECT_EQ(SummaryField(s, "imu_received"), bag_imus_);
  EXPECT_EQ(SummaryField(s, "imu_lost"), 0);
  EXPECT_EQ(SummaryField(s, "scans_malformed"), 0);
  EXPECT_EQ(SummaryField(s, "resets"), 0);
  EXPECT_EQ(SummaryField(s, "imu_gaps_bridged"), 0);
  ExpectScansAccountedFor(s);
  // Scans dropped because the core fell behind are a CPU matter (2 shared cores), not the
  // network's; the figure is printed above. Most scans still give a pose.
  EXPECT_GT(SummaryField(s, "odometry_published"), bag_scans_ / 2);
}

TEST_F(MultiHost, LinkDownTwoSecondsNodeContinuesAndReportsTheGap) {
  RunResult run;
  Run(dir_ + "/cut", true, false, &run);
  ASSERT_FALSE(HasFatalFailure());
  const std::string& s = run.summary;
  const double scans_lost = SummaryField(s, "scans_lost");
  const double imu_lost = SummaryField(s, "imu_lost");
  std::printf("lost: %.0f scans, %.0f IMU samples; bridged gap %.3f s\n", scans_lost, imu_lost,
              SummaryField(s, "imu_gap_max_s"));
  // Everything the replay sent either arrived or is counted lost: nothing vanished silently.
  EXPECT_EQ(SummaryField(s, "scans_received") + scans_lost, bag_scans_);
  EXPECT_EQ(SummaryField(s, "imu_received") + imu_lost, bag_imus_);
  // The data gap is the 2 s cut plus however long the restored link takes to carry data again
  // (docs/decisions.md, "Figures behind test bounds"); what was lost must match it: 10 scans and
  // 200 IMU samples a second.
  const double gap = SummaryField(s, "imu_gap_max_s");
  EXPECT_GE(gap, kCutSeconds - 0.1);
  EXPECT_NEAR(scans_lost, gap * 10.0, 2.0);
  EXPECT_NEAR(imu_lost, gap * 200.0 - 1.0, 5.0);
  EXPECT_NE(run.node_log.find("scan(s) never reached the node"), std::string::npos);
  EXPECT_NE(run.node_log.find("sample(s) never reached the node"), std::string::npos);
  // The gap is reported and bridged, not a reset (which would wait for a static start a moving
  // robot never gives: no odometry after the gap).
  EXPECT_EQ(SummaryField(s, "resets"), 0);
  EXPECT_EQ(SummaryField(s, "imu_gaps_bridged"), 1);
  EXPECT_NE(run.node_log.find("input gap: no IMU for"), std::string::npos);
  ExpectScansAccountedFor(s);

  // Odometry continues after the gap, and it is right: the node's trajectory against ground truth.
  ppf::Trajectory est, gt;
  std::string error;
  ASSERT_TRUE(ppf::ReadTum(dir_ + "/cut/node.tum", &est, &error)) << error;
  ASSERT_TRUE(ppf::ReadTum(dir_ + "/bag/groundtruth.tum", &gt, &error)) << error;
  ASSERT_GT(est.size(), 10u);
  size_t gap_end = 0;
  for (size_t i = 1; i < est.size(); ++i) {
    if (est[i].stamp_s - est[i - 1].stamp_s > 1.5) gap_end = i;
  }
  ASSERT_GT(gap_end, 0u) << "no 2 s hole in the node's trajectory";
  const size_t after = est.size() - gap_end;
  std::printf("poses: %zu before the gap, %zu after it\n", gap_end, after);
  // ~3.5 s of drive remain after the gap (35 scans); some may be dropped by a busy core.
  EXPECT_GE(after, 15u);
  ppf::EvalOptions o;
  const ppf::EvalResult ape = ppf::ComputeApe(gt, est, o);
  ASSERT_TRUE(ape.ok) << ape.error;
  double path = 0;
  for (size_t i = 1; i < gt.size(); ++i) {
    path += (gt[i].T.translation() - gt[i - 1].T.translation()).norm();
  }
  std::printf("APE rmse %.4f m, max %.4f m over %zu poses, path %.1f m\n", ape.stats.rmse,
              ape.stats.max, ape.matched, path);
  EXPECT_GE(ape.matched, est.size() - 1);
  // The core's accuracy bound for urban scenes (0.5 % of the path), gap included.
  EXPECT_LT(ape.stats.rmse, 0.005 * path);
}

}  // namespace
