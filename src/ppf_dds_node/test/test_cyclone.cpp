// Interop with a second DDS implementation: an Eclipse Cyclone DDS program (C, types from its own
// IDL compiler) feeds a short simulated sequence into ppf_node on rt/imu + rt/points and checks
// rt/odometry and rt/skeleton_planes, across processes and vendors (UDP; shared memory is vendor
// specific). Discovery: Fast DDS keeps its defaults (multicast + well-known unicast ports); the
// Cyclone side also lists 127.0.0.1 as a peer with a participant index, so discovery works with or
// without multicast.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "child_process.hpp"
#include "dds_test_util.hpp"
#include "ppf_bag/bag.hpp"
#include "ppf_bridge/cdr.hpp"
#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/PointCloud2.h"
#include "tool_paths.hpp"

using namespace std::chrono_literals;
using ppf::test::ChildProcess;
using ppf::test::SummaryField;

namespace {

class DumpWriter {
 public:
  explicit DumpWriter(const std::string& path) : out_(path, std::ios::binary) {
    out_.write("PPFDUMP1", 8);
  }
  template <typename T>
  void Pod(const T& v) {
    out_.write(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  void Str(const std::string& s) {
    Pod(static_cast<uint32_t>(s.size()));
    out_.write(s.data(), static_cast<std::streamsize>(s.size()));
  }
  void Bytes(const std::vector<uint8_t>& b) {
    Pod(static_cast<uint32_t>(b.size()));
    out_.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  }
  void Doubles(const double* v, size_t n) {
    out_.write(reinterpret_cast<const char*>(v), static_cast<std::streamsize>(n * sizeof(double)));
  }
  bool ok() const { return static_cast<bool>(out_); }

 private:
  std::ofstream out_;
};

// The bag's Imu and PointCloud2 messages, decoded here (ppf_bridge) and written field by field in
// the plain format cyclone_peer.c reads. Returns the number of clouds.
int WriteDump(const std::string& bag, const std::string& dump, int* imus) {
  ppf::bag::Reader reader(bag);
  DumpWriter w(dump);
  ppf::bag::Message m;
  int clouds = 0;
  *imus = 0;
  while (reader.Next(m)) {
    if (m.topic == "/imu") {
      sensor_msgs::msg::Imu imu;
      if (!ppf::bridge::DecodeCdr(m.data, &imu)) continue;
      w.Pod(uint8_t{1});
      w.Pod(m.timestamp_ns);
      w.Pod(imu.header().stamp().sec());
      w.Pod(imu.header().stamp().nanosec());
      w.Str(imu.header().frame_id());
      const double q[4] = {imu.orientation().x(), imu.orientation().y(), imu.orientation().z(),
                           imu.orientation().w()};
      w.Doubles(q, 4);
      w.Doubles(imu.orientation_covariance().data(), 9);
      const double g[3] = {imu.angular_velocity().x(), imu.angular_velocity().y(),
                           imu.angular_velocity().z()};
      w.Doubles(g, 3);
      w.Doubles(imu.angular_velocity_covariance().data(), 9);
      const double a[3] = {imu.linear_acceleration().x(), imu.linear_acceleration().y(),
                           imu.linear_acceleration().z()};
      w.Doubles(a, 3);
      w.Doubles(imu.linear_acceleration_covariance().data(), 9);
      ++*imus;
    } else if (m.topic == "/points") {
      sensor_msgs::msg::PointCloud2 c;
      if (!ppf::bridge::DecodeCdr(m.data, &c)) continue;
      w.Pod(uint8_t{2});
      w.Pod(m.timestamp_ns);
      w.Pod(c.header().stamp().sec());
      w.Pod(c.header().stamp().nanosec());
      w.Str(c.header().frame_id());
      w.Pod(c.height());
      w.Pod(c.width());
      w.Pod(static_cast<uint32_t>(c.fields().size()));
      for (const auto& f : c.fields()) {
        w.Str(f.name());
        w.Pod(f.offset());
        w.Pod(f.datatype());
        w.Pod(f.count());
      }
      w.Pod(static_cast<uint8_t>(c.is_bigendian()));
      w.Pod(c.point_step());
      w.Pod(c.row_step());
      w.Bytes(c.data());
      w.Pod(static_cast<uint8_t>(c.is_dense()));
      ++clouds;
    }
  }
  return w.ok() ? clouds : -1;
}

}  // namespace

TEST(Cyclone, CycloneDdsPeerFeedsNodeAndReceivesOdometryAndPlanes) {
  if (std::string(PPF_CYCLONE_PEER).empty()) {
    GTEST_SKIP() << "Cyclone DDS (cyclonedds-dev + idlc) not found at configure time";
  }
  const std::string sim = ppf::test::FindTool("ppf_sim", PPF_SIM_CONFIGURED);
  if (sim.empty()) GTEST_SKIP() << "ppf_sim not found (PATH or configure time): build ppf_sim";

  char tmpl[] = "/tmp/ppf_dds_cyclone_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  // Short sequence: 2.5 s static (IMU initialization), then hand-held motion indoors; VLP-16
  // clouds (~0.9 MB) so the UDP path between vendors carries them comfortably.
  {
    ChildProcess gen;
    ASSERT_TRUE(gen.Start({sim, "--scene", "indoor", "--lidar", "vlp16", "--duration", "6",
                           "--seed", "2", "--storage", "mcap", "--out", dir + "/bag"},
                          {}, dir + "/sim.log"));
    ASSERT_TRUE(ppf::test::ExitedWith(gen.Wait(60s), 0));
  }
  int imus = 0;
  const int clouds = WriteDump(dir + "/bag", dir + "/seq.dump", &imus);
  std::system(("rm -rf '" + dir + "/bag'").c_str());
  ASSERT_GE(clouds, 55);
  ASSERT_GE(imus, 1000);

  const int domain = ppf::test::TestDomainId(21);
  {
    std::ofstream cfg(dir + "/node.yaml");
    cfg << "dds: {domain_id: " << domain << ", profiles_file: \"" << PPF_DDS_CONFIG_DIR
        << "/shm_udp.xml\", profile_name: ppf_shm_udp}\n"
        // PPF mode, so the skeleton-plane messages carry planes.
        << "core: {config_file: \"" << PPF_CONFIG_DIR << "/vlp16.yaml\", mode: ppf}\n";
  }
  {
    std::ofstream xml(dir + "/cyclone.xml");
    xml << "<CycloneDDS><Domain id=\"any\"><Discovery>"
           "<ParticipantIndex>auto</ParticipantIndex>"
           "<Peers><Peer address=\"127.0.0.1\"/></Peers>"
           "</Discovery></Domain></CycloneDDS>\n";
  }
  ChildProcess node, peer;
  ASSERT_TRUE(node.Start({PPF_NODE_EXE, "--config", dir + "/node.yaml"}, {}, dir + "/node.log"));
  std::string line;
  ASSERT_TRUE(node.WaitForLine("PPF_NODE_READY", &line, 20s)) << "see " << dir << "/node.log";
  ASSERT_TRUE(peer.Start({PPF_CYCLONE_PEER, dir + "/seq.dump", std::to_string(domain), "20"},
                         {"CYCLONEDDS_URI=file://" + dir + "/cyclone.xml"}, dir + "/peer.log"));
  ASSERT_TRUE(peer.WaitForLine("READY", &line, 25s))
      << "Cyclone and Fast DDS did not discover each other (domain " << domain << ")";
  std::string result;
  ASSERT_TRUE(peer.WaitForLine("RESULT", &result, 60s));
  EXPECT_TRUE(ppf::test::ExitedWith(peer.Wait(10s), 0));
  node.Signal(SIGINT);
  std::string summary;
  ASSERT_TRUE(node.WaitForLine("PPF_NODE_SUMMARY", &summary, 30s));
  EXPECT_TRUE(ppf::test::ExitedWith(node.Wait(10s), 0));
  std::printf("%s\n%s\n", result.c_str(), summary.c_str());

  // What Cyclone sent.
  EXPECT_EQ(SummaryField(result, "sent_scans"), clouds);
  EXPECT_EQ(SummaryField(result, "sent_imu"), imus);
  EXPECT_EQ(SummaryField(result, "write_errors"), 0);
  // What the node made of it: Cyclone's XCDR1 payloads decode (nothing malformed), every scan is
  // processed, and the IMU stream arrives whole (reliable writer, loopback UDP).
  const double received = SummaryField(summary, "scans_received");
  EXPECT_EQ(SummaryField(summary, "scans_malformed"), 0);
  EXPECT_EQ(SummaryField(summary, "imu_malformed"), 0);
  EXPECT_EQ(SummaryField(summary, "imu_received"), imus);
  EXPECT_GE(received, clouds - 2) << "more than 2 clouds lost between vendors";
  EXPECT_LE(received, clouds);
  EXPECT_EQ(SummaryField(summary, "scans_processed") + SummaryField(summary, "scans_dropped"),
            received);
  EXPECT_EQ(SummaryField(summary, "resets"), 0);
  // What Cyclone received back: every odometry message the node published (reliable), one per
  // scan with a pose (2.5 s static start: ~10 scans initialize), all finite, right frames, and
  // one skeleton-plane message per odometry message.
  const double published = SummaryField(summary, "odometry_published");
  EXPECT_EQ(SummaryField(result, "odom"), published);
  EXPECT_GE(published, received - 30);
  EXPECT_GT(published, 20);
  EXPECT_EQ(SummaryField(result, "odom_bad"), 0);
  EXPECT_EQ(SummaryField(result, "odom_frames_bad"), 0);
  EXPECT_EQ(SummaryField(result, "odom_not_monotonic"), 0);
  EXPECT_EQ(SummaryField(result, "planes"), published);
  EXPECT_EQ(SummaryField(result, "planes_bad"), 0);
  // Sparse VLP-16 scans do not give a plane in every scan (measured: 24 planes over 50 scans).
  EXPECT_GT(SummaryField(result, "planes_total"), 0);
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());  // the dump is ~50 MB
}
