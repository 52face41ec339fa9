// Driving the Cyclone DDS peer (cyclone/cyclone_peer.c), shared by the interop and the
// hostile-input tests: the plain dump it replays (format in its header comment: the Imu and
// PointCloud2 messages of a ppf_sim bag, decoded with ppf_bridge and written field by field, so the
// peer needs no CDR of ours), its discovery configuration, and one run of node + peer.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "dds_test_util.hpp"
#include "ppf_bag/bag.hpp"
#include "ppf_dds_node/child_process.hpp"
#include "ppf_msgs_cdr/cdr.hpp"
#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/PointCloud2.h"

namespace ppf::test {

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
inline int WriteDump(const std::string& bag, const std::string& dump, int* imus) {
  ppf::bag::Reader reader(bag);
  DumpWriter w(dump);
  ppf::bag::Message m;
  int clouds = 0;
  *imus = 0;
  while (reader.Next(m)) {
    if (m.topic == "/imu") {
      sensor_msgs::msg::Imu imu;
      if (!ppf::msgs::DecodeCdr(m.data, &imu)) continue;
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
      if (!ppf::msgs::DecodeCdr(m.data, &c)) continue;
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

// ppf_sim `args` -> bag -> dump at dir/seq.dump (the bag is removed). Counts in *clouds, *imus.
inline ::testing::AssertionResult SimulateDump(const std::string& sim,
                                               const std::vector<std::string>& args,
                                               const std::string& dir, int* clouds, int* imus) {
  auto sim_ok = SimulateSequence(sim, args, dir + "/bag", dir + "/sim.log");
  if (!sim_ok) return sim_ok;
  *clouds = WriteDump(dir + "/bag", dir + "/seq.dump", imus);
  std::system(("rm -rf '" + dir + "/bag'").c_str());
  if (*clouds <= 0) return ::testing::AssertionFailure() << "cannot write " << dir << "/seq.dump";
  return ::testing::AssertionSuccess();
}

// What one node + peer run left behind.
struct PeerRun {
  std::string result;             // the peer's RESULT line
  std::vector<std::string> peer;  // every line the peer printed
  std::string summary;            // the node's PPF_NODE_SUMMARY line
  std::string log;                // the node's stderr
  long node_hwm_kb = -1;          // node's peak RSS before it was stopped
};

// Starts ppf_node with dir/node.yaml (written from `node_yaml` after the dds line: domain, the
// project's SHM+UDP profile), then the Cyclone peer on dir/seq.dump with `peer_args`; waits for
// the peer's RESULT, stops the node (SIGINT) and reads its summary. Discovery: Fast DDS keeps its
// defaults (multicast + well-known unicast ports); the Cyclone side also lists 127.0.0.1 as a
// peer with a participant index, so discovery works with or without multicast.
inline void RunNodeAndPeer(const std::string& peer_exe, const std::string& dir, int domain,
                           const std::string& node_yaml, const std::vector<std::string>& peer_args,
                           PeerRun* run) {
  using namespace std::chrono_literals;
  {
    std::ofstream cfg(dir + "/node.yaml");
    cfg << "dds: {domain_id: " << domain << ", profiles_file: \"" << PPF_DDS_CONFIG_DIR
        << "/shm_udp.xml\", profile_name: ppf_shm_udp}\n"
        << node_yaml;
  }
  {
    std::ofstream xml(dir + "/cyclone.xml");
    xml << "<CycloneDDS><Domain id=\"any\"><Discovery>"
           "<ParticipantIndex>auto</ParticipantIndex>"
           "<Peers><Peer address=\"127.0.0.1\"/></Peers>"
           "</Discovery></Domain></CycloneDDS>\n";
  }
  ppf::dds::ChildProcess node, peer;
  ASSERT_TRUE(node.Start({PPF_NODE_EXE, "--config", dir + "/node.yaml"}, {}, dir + "/node.log"));
  std::string line;
  ASSERT_TRUE(node.WaitForLine("PPF_NODE_READY", &line, 20s)) << "see " << dir << "/node.log";
  // The peer stops waiting once the last scan's odometry is in: 40 s at most only binds a node
  // far behind (instrumented, loaded).
  std::vector<std::string> argv = {peer_exe, dir + "/seq.dump", std::to_string(domain), "40",
                                   "--go-file", dir + "/go"};
  argv.insert(argv.end(), peer_args.begin(), peer_args.end());
  ASSERT_TRUE(
      peer.Start(argv, {"CYCLONEDDS_URI=file://" + dir + "/cyclone.xml"}, dir + "/peer.log"));
  ASSERT_TRUE(peer.WaitForLine("READY", &line, 25s, &run->peer))
      << "Cyclone and Fast DDS did not discover each other (domain " << domain << ")";
  ASSERT_TRUE(WaitForNodeInputsMatched(dir + "/node.log", 1, 1, 20s))
      << "the node did not discover the peer's writers, see " << dir << "/node.log";
  std::ofstream(dir + "/go").put('\n');
  ASSERT_TRUE(peer.WaitForLine("RESULT", &run->result, 90s, &run->peer));
  EXPECT_TRUE(ppf::dds::ExitedWith(peer.Wait(10s), 0));
  run->node_hwm_kb = ProcStatusKb(node.pid(), "VmHWM");
  ASSERT_TRUE(StopNodeAndReadSummary(node, &run->summary)) << "the peer's " << run->result;
  run->log = ReadTextFile(dir + "/node.log");
  std::printf("%s\n%s\nnode peak RSS %ld kB\n", run->result.c_str(), run->summary.c_str(),
              run->node_hwm_kb);
}

}  // namespace ppf::test
