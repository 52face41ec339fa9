// One ppf_node under test and the driver that feeds it: the node's directory, config and log, a
// participant with /points and /imu writers and an /odometry collector on the loopback test
// profile, and a static synthetic room driven in real time. Includers define PPF_NODE_EXE and
// PPF_DDS_CONFIG_DIR and build src/synthetic_scene.cpp in.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "dds_test_util.hpp"
#include "nav_msgs/msg/OdometryPubSubTypes.h"
#include "ppf_dds_node/child_process.hpp"
#include "ppf_dds_node/synthetic_scene.hpp"
#include "ppf_msgs_cdr/time.hpp"
#include "sensor_msgs/msg/ImuPubSubTypes.h"
#include "sensor_msgs/msg/PointCloud2PubSubTypes.h"
#include "test_domain.hpp"

namespace ppf::test {

// A VLP-16-sized scan of the synthetic room; NodeRig::Drive stamps it.
inline sensor_msgs::msg::PointCloud2 Vlp16RoomScan() {
  ppf::dds::SyntheticLidar lidar;
  lidar.rings = 16;
  lidar.columns = 1024;
  lidar.min_elevation_deg = -15;
  lidar.max_elevation_deg = 15;
  return ppf::dds::MakeRoomScan(lidar, 0);
}

inline constexpr int64_t kT0 = 1700000000LL * 1000000000LL;

// The set-up every node test repeated: the node's directory and log, and the driver's side with
// the static room it drives. Members are declared so that the participant goes before its
// listeners and the node after both (destruction runs in reverse): no listener is destroyed while
// an entity can still call it.
struct NodeRig {
  explicit NodeRig(int salt)
      : domain(ppf::test::TestDomainId(salt)),
        dir(TempDir("ppf_node_test")),
        log(dir + "/node.log") {}

  // Starts ppf_node on <dir>/node.yaml: the loopback test profile on `domain`, then the YAML lines
  // `more`; its log goes to `log`. Returns once the node is ready.
  void StartNode(const std::string& more) {
    const std::string cfg = dir + "/node.yaml";
    {
      std::ofstream out(cfg);
      out << "dds: {domain_id: " << domain << ", profiles_file: \"" << kProfiles
          << "\", profile_name: " << kProfile << "}\n"
          << more;
    }
    ASSERT_TRUE(node.Start({PPF_NODE_EXE, "--config", cfg}, {}, log));
    std::string line;
    ASSERT_TRUE(node.WaitForLine("PPF_NODE_READY", &line, std::chrono::seconds(20)))
        << "see " << log;
  }

  // Writers with these QoS and the odometry reader.
  void OpenDriver(const fdds::DataWriterQos& cloud_qos, const fdds::DataWriterQos& imu_qos) {
    driver = std::make_unique<TestParticipant>(domain, kProfiles, kProfile, "test_driver");
    ASSERT_TRUE(driver->ok()) << driver->error;
    cloud_w = driver->Writer(new sensor_msgs::msg::PointCloud2PubSubType(), "rt/points", cloud_qos,
                             &cloud_m);
    imu_w = driver->Writer(new sensor_msgs::msg::ImuPubSubType(), "rt/imu", imu_qos, &imu_m);
    ASSERT_NE(driver->Reader(new nav_msgs::msg::OdometryPubSubType(), "rt/odometry",
                             ppf::dds::KeepAllReaderQos(), &odom),
              nullptr);
    ASSERT_TRUE(cloud_w && imu_w);
  }

  // Until our writers and reader matched (and `also` holds), then until the node's log says its
  // readers matched `points_writers` /points writers and our /imu writer.
  void WaitMatched(int points_writers, const std::function<bool()>& also) {
    ASSERT_TRUE(WaitUntil(
        [&] { return cloud_m.matched > 0 && imu_m.matched > 0 && odom.matched > 0 && also(); },
        std::chrono::seconds(20)));
    ASSERT_TRUE(WaitForNodeInputsMatched(log, points_writers, 1, std::chrono::seconds(20)))
        << "see " << log;
  }

  // The node with `more`, reliable writers (depth 50 for clouds, 1000 for IMU), all matched.
  void Start(const std::string& more) {
    ASSERT_NO_FATAL_FAILURE(StartNode(more));
    ASSERT_NO_FATAL_FAILURE(
        OpenDriver(ppf::dds::SensorWriterQos(ppf::dds::Reliability::kReliable, 50),
                   ppf::dds::SensorWriterQos(ppf::dds::Reliability::kReliable, 1000)));
    ASSERT_NO_FATAL_FAILURE(WaitMatched(1, [] { return true; }));
  }

  // Publishes a static drive in real time, stamps from kT0: resting IMU every 5 ms and, after
  // 1.5 s of rest (initialization), `scans` scans at 10 Hz: `cloud` again each time, stamped with
  // that scan's start. `seq` numbers the IMU samples; `imu_t` ends as the next IMU sample's
  // stamp. With `first` > 0 the stamps go on from `imu_t` with scan `first` (the call before
  // ended with scan first - 1), as a paused replay resumes.
  void Drive(int scans, int first = 0) {
    const auto wall0 = std::chrono::steady_clock::now();
    if (first == 0) imu_t = kT0;
    const int64_t t_begin = imu_t;
    for (int s = first; s <= scans; ++s) {
      const int64_t scan_end = kT0 + 1500000000LL + s * 100000000LL;
      while (imu_t <= scan_end) {
        if (imu_t >= imu_begin) {
          sensor_msgs::msg::Imu imu = ppf::dds::MakeRestingImu(imu_t, seq++);
          ASSERT_TRUE(imu_w->write(&imu));
        }
        imu_t += 5000000;
      }
      std::this_thread::sleep_until(wall0 + std::chrono::nanoseconds(scan_end - t_begin));
      if (s == 0) continue;
      cloud.header().stamp(ppf::msgs::TimeFromNanoseconds(scan_end - 100000000LL));
      ASSERT_TRUE(cloud_w->write(&cloud));
    }
  }

  // SIGINT; the node prints its summary (returned in *summary, echoed to the test log), exits 0.
  void Stop(std::string* summary) {
    ASSERT_TRUE(ppf::test::StopNodeAndReadSummary(node, summary));
    std::printf("%s\n", summary->c_str());
  }

  void RemoveDirUnless(bool failed) const {
    if (!failed) std::system(("rm -rf '" + dir + "'").c_str());
  }

  const int domain;
  const std::string dir;
  const std::string log;
  ppf::dds::ChildProcess node;
  WriterMatches cloud_m, imu_m;
  Collector<nav_msgs::msg::Odometry> odom;
  std::unique_ptr<TestParticipant> driver;
  fdds::DataWriter* cloud_w = nullptr;
  fdds::DataWriter* imu_w = nullptr;
  sensor_msgs::msg::PointCloud2 cloud = Vlp16RoomScan();
  int64_t imu_t = 0;  // the next IMU stamp
  int64_t imu_begin = 0;  // Drive writes no IMU sample stamped before this: a driver starting late
  uint64_t seq = 0;   // IMU samples sent
};

}  // namespace ppf::test
