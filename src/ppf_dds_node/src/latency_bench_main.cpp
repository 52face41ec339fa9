// ppf_latency_bench: node overhead for HDL-64-sized clouds over shared memory.
//
// Starts ppf_node as a separate process (same host, SHM profile), publishes a static synthetic
// room (64 x 2048 points, 3 MB per scan) at 10 Hz with 200 Hz IMU like a driver would, listens to
// /odometry, stops the node with SIGINT and prints a table from the node's own SUMMARY line
// (latency = DDS receive -> odometry published, overhead = latency - core time) next to the
// end-to-end latency seen here (scan written -> odometry received).
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "nav_msgs/msg/OdometryPubSubTypes.h"
#include "ppf_bridge/convert.hpp"
#include "ppf_dds_node/child_process.hpp"
#include "ppf_dds_node/dds_common.hpp"
#include "ppf_dds_node/latency_stats.hpp"
#include "ppf_dds_node/synthetic_scene.hpp"
#include "ppf_msgs_cdr/time.hpp"
#include "sensor_msgs/msg/ImuPubSubTypes.h"
#include "sensor_msgs/msg/PointCloud2PubSubTypes.h"

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

namespace {

std::string ExeDir() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (n <= 0) return ".";
  std::string p(buf, static_cast<size_t>(n));
  return p.substr(0, p.rfind('/'));
}

class Matches : public fdds::DataWriterListener {
 public:
  void on_publication_matched(fdds::DataWriter*, const fdds::PublicationMatchedStatus& s) override {
    matched = s.current_count;
  }
  std::atomic<int> matched{0};
};

class OdomListener : public fdds::DataReaderListener {
 public:
  void on_data_available(fdds::DataReader* reader) override {
    nav_msgs::msg::Odometry msg;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&msg, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      const auto now = Clock::now();
      std::lock_guard<std::mutex> lock(mutex);
      received[ppf::msgs::ToNanoseconds(msg.header().stamp())] = now;
    }
  }
  std::mutex mutex;
  std::map<int64_t, Clock::time_point> received;  // odometry stamp -> receive time
};

double Field(const std::string& line, const std::string& key) {
  const size_t p = line.find(" " + key + "=");
  if (p == std::string::npos) return std::nan("");
  return std::atof(line.c_str() + p + key.size() + 2);
}

struct BenchOptions {
  int scans = 100, rings = 64, columns = 2048;
  double rate_hz = 10.0;
  std::string node_exe = ExeDir() + "/ppf_node";
  std::string profiles = ppf::dds::ProjectShmUdpProfile();
  std::string profile = "ppf_shm_udp";
  int domain = 1 + static_cast<int>(getpid() % 200);
  std::string omp_policy;  // "" = the node's own default (core.omp_wait_policy: passive)
  int node_nice = 0;
};

// False (after the usage text) on an argument it does not know.
bool ParseArgs(int argc, char** argv, BenchOptions* o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--scans")
      o->scans = std::atoi(next().c_str());
    else if (a == "--rate")
      o->rate_hz = std::atof(next().c_str());
    else if (a == "--rings")
      o->rings = std::atoi(next().c_str());
    else if (a == "--columns")
      o->columns = std::atoi(next().c_str());
    else if (a == "--node")
      o->node_exe = next();
    else if (a == "--profiles")
      o->profiles = next();
    else if (a == "--profile")
      o->profile = next();
    else if (a == "--domain")
      o->domain = std::atoi(next().c_str());
    else if (a == "--omp-wait-policy")
      o->omp_policy = next();
    else if (a == "--node-nice")
      o->node_nice = std::atoi(next().c_str());
    else {
      std::fprintf(stderr,
                   "usage: ppf_latency_bench [--scans N=100] [--rate HZ=10] [--rings 64] "
                   "[--columns 2048]\n  [--node PATH] [--profiles XML] [--profile NAME] "
                   "[--domain ID] [--omp-wait-policy passive|active] [--node-nice N]\n"
                   "  --omp-wait-policy P  OMP_WAIT_POLICY for the node (default: the node's\n"
                   "                       core.omp_wait_policy, passive)\n"
                   "  --node-nice N  run the node under nice -n N (negative: higher priority)\n");
      return false;
    }
  }
  return true;
}

// Starts the node on config `cfg` (written here: same profile, unique domain, quiet
// diagnostics) and waits until it is ready. False (logged) if it does not come up.
bool StartNode(const BenchOptions& o, const std::string& cfg, ppf::dds::ChildProcess* node) {
  {
    std::ofstream out(cfg);
    out << "dds: {domain_id: " << o.domain << ", profiles_file: \"" << o.profiles
        << "\", profile_name: \"" << o.profile << "\"}\n"
        << "queues: {scan_capacity: 2}\n";
  }
  std::vector<std::string> node_env;
  if (!o.omp_policy.empty()) node_env.push_back("OMP_WAIT_POLICY=" + o.omp_policy);
  std::vector<std::string> node_argv = {o.node_exe, "--config", cfg};
  if (o.node_nice != 0) {
    node_argv.insert(node_argv.begin(), {"/usr/bin/nice", "-n", std::to_string(o.node_nice)});
  }
  if (!node->Start(node_argv, node_env,
                   "/tmp/ppf_latency_bench_node_" + std::to_string(getpid()) + ".log")) {
    std::fprintf(stderr, "cannot start %s\n", o.node_exe.c_str());
    return false;
  }
  std::string line;
  if (!node->WaitForLine("PPF_NODE_READY", &line, 20s)) {
    std::fprintf(stderr, "ppf_node did not come up (see /tmp/ppf_latency_bench_node_%d.log)\n",
                 getpid());
    return false;
  }
  return true;
}

// Publishes the static room in real time from an arbitrary epoch: IMU at 200 Hz, 1.5 s of rest,
// then `scans` scans at rate_hz. Returns when each scan (by its end stamp) was written.
std::map<int64_t, Clock::time_point> Publish(const BenchOptions& o, fdds::DataWriter* imu_w,
                                             fdds::DataWriter* cloud_w,
                                             sensor_msgs::msg::PointCloud2* cloud) {
  const int64_t t0_ns = 1700000000LL * 1000000000LL;
  const int64_t imu_dt = 5000000;  // 200 Hz
  const int64_t scan_dt = static_cast<int64_t>(1e9 / o.rate_hz);
  const int64_t warmup_ns = 1500000000LL;
  const auto wall0 = Clock::now();
  std::map<int64_t, Clock::time_point> written;  // scan end stamp -> write time
  uint64_t imu_seq = 0;
  int64_t imu_next = t0_ns;
  const int64_t end_ns = t0_ns + warmup_ns + o.scans * scan_dt;
  int64_t scan_start = t0_ns + warmup_ns;
  while (imu_next <= end_ns || scan_start + scan_dt <= end_ns) {
    // Next event in simulated time: an IMU sample or the end of the current scan.
    const int64_t scan_end = scan_start + scan_dt;
    const bool imu_first = imu_next <= scan_end;
    const int64_t event = imu_first ? imu_next : scan_end;
    std::this_thread::sleep_until(wall0 + std::chrono::nanoseconds(event - t0_ns));
    if (imu_first) {
      sensor_msgs::msg::Imu imu = ppf::dds::MakeRestingImu(imu_next, imu_seq++);
      imu_w->write(&imu);
      imu_next += imu_dt;
    } else {
      cloud->header().stamp(ppf::msgs::TimeFromNanoseconds(scan_start));
      written[scan_end] = Clock::now();  // before write: with SHM the node may get it first
      cloud_w->write(cloud);
      scan_start = scan_end;
    }
  }
  return written;
}

// End-to-end: scan written here -> its odometry received here. The pose refers to the scan end
// (ScanResult::stamp_s), which is the last point's time: match within 1 ms of the nominal end.
ppf::dds::LatencyStats EndToEnd(OdomListener& odom,
                                const std::map<int64_t, Clock::time_point>& written) {
  ppf::dds::LatencyStats e2e;
  std::lock_guard<std::mutex> lock(odom.mutex);
  for (const auto& [stamp, rx] : odom.received) {
    auto it = written.lower_bound(stamp - 2000000);
    if (it != written.end() && std::llabs(it->first - stamp) < 2000000) {
      e2e.Add(std::chrono::duration<double, std::milli>(rx - it->second).count());
    }
  }
  return e2e;
}

void PrintTable(const BenchOptions& o, const sensor_msgs::msg::PointCloud2& cloud, double cloud_mb,
                const std::string& summary, const ppf::dds::LatencyStats& e2e) {
  std::printf(
      "ppf_latency_bench: %d scans x %u points (%.1f MB, HDL-64 size) at %.0f Hz, "
      "profile %s, OMP_WAIT_POLICY %s, node nice %d\n\n",
      o.scans, cloud.width(), cloud_mb, o.rate_hz, o.profile.c_str(),
      !o.omp_policy.empty()            ? o.omp_policy.c_str()
      : std::getenv("OMP_WAIT_POLICY") ? std::getenv("OMP_WAIT_POLICY")
                                       : "passive (node default)",
      o.node_nice);
  std::printf("| %-52s | %8s | %8s | %8s |\n", "metric (ms)", "p50", "p99", "max");
  std::printf("|%s|%s|%s|%s|\n", std::string(54, '-').c_str(), std::string(10, '-').c_str(),
              std::string(10, '-').c_str(), std::string(10, '-').c_str());
  std::printf("| %-52s | %8.3f | %8.3f | %8.3f |\n", "node overhead (latency - core - waits)",
              Field(summary, "overhead_p50_ms"), Field(summary, "overhead_p99_ms"),
              Field(summary, "overhead_max_ms"));
  std::printf("| %-52s | %8.3f | %8.3f | %8.3f |\n",
              "node latency (DDS receive -> odometry published)", Field(summary, "latency_p50_ms"),
              Field(summary, "latency_p99_ms"), Field(summary, "latency_max_ms"));
  std::printf("| %-52s | %8.3f | %8.3f | %8s |\n", "core time (decode + pipeline)",
              Field(summary, "core_p50_ms"), Field(summary, "core_p99_ms"), "");
  std::printf("| %-52s | %8.3f | %8.3f | %8s |\n", "  of which: listener take + CDR decode",
              Field(summary, "decode_p50_ms"), Field(summary, "decode_p99_ms"), "");
  std::printf("| %-52s | %8.3f | %8.3f | %8s |\n", "  of which: scan queue -> executor",
              Field(summary, "queue_p50_ms"), Field(summary, "queue_p99_ms"), "");
  std::printf("| %-52s | %8.3f | %8.3f | %8s |\n",
              "  of which: conversion + publishing all outputs", Field(summary, "publish_p50_ms"),
              Field(summary, "publish_p99_ms"), "");
  std::printf("| %-52s | %8.3f | %8.3f | %8s |\n", "scan queued behind the core (older scans)",
              Field(summary, "behind_core_p50_ms"), Field(summary, "behind_core_p99_ms"), "");
  std::printf("| %-52s | %8.3f | %8.3f | %8s |\n", "scan waiting in core for IMU coverage",
              Field(summary, "imu_wait_p50_ms"), Field(summary, "imu_wait_p99_ms"), "");
  std::printf("| %-52s | %8.3f | %8.3f | %8.3f |\n",
              "end to end (bench write -> odometry received)", e2e.Percentile(50),
              e2e.Percentile(99), e2e.Max());
  std::printf(
      "\nscans written %d, received %.0f, processed %.0f, odometry %.0f, dropped %.0f; "
      "odometry matched here %zu\n",
      o.scans, Field(summary, "scans_received"), Field(summary, "scans_processed"),
      Field(summary, "odometry_published"), Field(summary, "scans_dropped"), e2e.count());
  const double p99 = Field(summary, "overhead_p99_ms");
  std::printf("target node overhead p99 < 2 ms: %s\n", p99 < 2.0 ? "met" : "NOT met");
}

}  // namespace

int main(int argc, char** argv) {
  BenchOptions o;
  if (!ParseArgs(argc, argv, &o)) return 2;
  const std::string cfg = "/tmp/ppf_latency_bench_" + std::to_string(getpid()) + ".yaml";
  ppf::dds::ChildProcess node;
  if (!StartNode(o, cfg, &node)) return 1;

  ppf::dds::ParticipantOptions popt{o.domain, o.profiles, o.profile, "ppf_latency_bench"};
  std::string error;
  fdds::DomainParticipant* participant = ppf::dds::CreateParticipant(popt, &error);
  if (!participant) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 1;
  }
  fdds::TypeSupport cloud_type(new sensor_msgs::msg::PointCloud2PubSubType());
  fdds::TypeSupport imu_type(new sensor_msgs::msg::ImuPubSubType());
  fdds::TypeSupport odom_type(new nav_msgs::msg::OdometryPubSubType());
  cloud_type.register_type(participant);
  imu_type.register_type(participant);
  odom_type.register_type(participant);
  auto* pub = participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  auto* sub = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  Matches cloud_m, imu_m;
  // Driver-like QoS: sensor data, best effort.
  auto* cloud_w = pub->create_datawriter(
      participant->create_topic("rt/points", cloud_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT),
      ppf::dds::SensorWriterQos(ppf::dds::Reliability::kBestEffort), &cloud_m);
  auto* imu_w = pub->create_datawriter(
      participant->create_topic("rt/imu", imu_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT),
      ppf::dds::SensorWriterQos(ppf::dds::Reliability::kBestEffort, 100), &imu_m);
  OdomListener odom;
  sub->create_datareader(
      participant->create_topic("rt/odometry", odom_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT),
      ppf::dds::DefaultReaderQos(100), &odom);
  const auto match_deadline = Clock::now() + 15s;
  while ((cloud_m.matched < 1 || imu_m.matched < 1) && Clock::now() < match_deadline) {
    std::this_thread::sleep_for(10ms);
  }
  if (cloud_m.matched < 1 || imu_m.matched < 1) {
    std::fprintf(stderr, "ppf_node never matched our writers\n");
    return 1;
  }

  ppf::dds::SyntheticLidar lidar;
  lidar.rings = o.rings;
  lidar.columns = o.columns;
  sensor_msgs::msg::PointCloud2 cloud = ppf::dds::MakeRoomScan(lidar, 0);
  const double cloud_mb = static_cast<double>(cloud.data().size()) / (1 << 20);
  std::fprintf(stderr, "ppf_latency_bench: %d scans of %u points (%.1f MB) at %.1f Hz, domain %d\n",
               o.scans, cloud.width(), cloud_mb, o.rate_hz, o.domain);
  const auto written = Publish(o, imu_w, cloud_w, &cloud);
  std::this_thread::sleep_for(1500ms);  // let the node finish the last scans
  node.Signal(SIGINT);
  std::string summary;
  const bool got = node.WaitForLine("PPF_NODE_SUMMARY", &summary, 30s);
  const int status = node.Wait(10s);
  std::remove(cfg.c_str());

  const ppf::dds::LatencyStats e2e = EndToEnd(odom, written);
  participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
  if (!got || !ppf::dds::ExitedWith(status, 0)) {
    std::fprintf(stderr, "ppf_node did not report a summary / exit 0\n");
    return 1;
  }
  PrintTable(o, cloud, cloud_mb, summary, e2e);
  return 0;
}
