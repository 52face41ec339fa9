// In-process units of the node: config parsing and the hand-over queue.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <fastdds/rtps/common/SerializedPayload.h>

#include "ppf_core/config_table.hpp"
#include "ppf_dds_node/gap_counter.hpp"
#include "ppf_dds_node/latency_stats.hpp"
#include "ppf_dds_node/logging.hpp"
#include "ppf_dds_node/node_config.hpp"
#include "ppf_dds_node/stall_watch.hpp"
#include "ppf_dds_node/synthetic_scene.hpp"
#include "ppf_dds_node/time_ordered_queue.hpp"
#include "ppf_msgs_cdr/cdr.hpp"
#include "ppf_msgs_cdr/cdr_payload.hpp"
#include "../src/node_map.hpp"    // private to the node: the saved map under test
#include "../src/node_stats.hpp"  // private to the node: its counters under test
#include "test_domain.hpp"

namespace ppf::dds {
namespace {

// IMU loss: an episode of LiDAR-only scans counts once, each scan in it too, and the
// status line says so while it lasts.
TEST(NodeStats, ImuFallbackEpisodesAreCountedAndShownInTheStatusLine) {
  NodeStats stats;
  ScanResult ok;
  ok.status = Status::kOk;
  ok.pose_valid = true;
  ScanResult lost = ok;
  lost.imu_lost = true;
  size_t mark = 0;
  stats.CountResult(ok);
  EXPECT_EQ(stats.PeriodicLine(&mark, QueueFill(), "").find("IMU lost"), std::string::npos);
  stats.CountResult(lost);
  stats.CountResult(lost);
  EXPECT_NE(stats.PeriodicLine(&mark, QueueFill(), "").find("status=ok (IMU lost: LiDAR-only) "),
            std::string::npos);
  stats.CountResult(ok);
  EXPECT_EQ(stats.PeriodicLine(&mark, QueueFill(), "").find("IMU lost"), std::string::npos);
  stats.CountResult(lost);
  const NodeSummary s = stats.Snapshot();
  EXPECT_EQ(s.imu_fallbacks, 2u);
  EXPECT_EQ(s.imu_fallback_scans, 3u);
  EXPECT_NE(NodeStats::FormatSummary(s).find(" imu_fallbacks=2 imu_fallback_scans=3 "),
            std::string::npos);
}

// No IMU at all (imu.mode auto decided none): the status line says so while the poses are
// LiDAR-only, the summary counts those scans and the late IMU's takeover.
TEST(NodeStats, LidarOnlyScansAndALateImuAreCountedAndShownInTheStatusLine) {
  NodeStats stats;
  ScanResult r;
  r.status = Status::kOk;
  r.pose_valid = true;
  r.lidar_only = true;
  size_t mark = 0;
  stats.CountResult(r);
  stats.CountResult(r);
  EXPECT_NE(stats.PeriodicLine(&mark, QueueFill(), "").find("status=ok (no IMU: LiDAR-only) "),
            std::string::npos);
  r.lidar_only = false;
  r.lio_started_late = true;
  stats.CountResult(r);
  EXPECT_EQ(stats.PeriodicLine(&mark, QueueFill(), "").find("no IMU"), std::string::npos);
  EXPECT_NE(NodeStats::FormatSummary(stats.Snapshot()).find(" lidar_only_scans=2 lio_started_late=1 "),
            std::string::npos);
}

// The consistency check's searches are counted whether a guess won or the pose was kept; the
// overruled ones are counted apart.
TEST(NodeStats, ConsistencySearchesAreCountedBesideTheOverruledScans) {
  NodeStats stats;
  ScanResult r;
  r.status = Status::kOk;
  r.pose_valid = true;
  stats.CountResult(r);
  r.consistency_search = ConsistencySearch::kScanStep;
  stats.CountResult(r);
  r.consistency_search = ConsistencySearch::kPoorFit;
  r.overruled = true;
  stats.CountResult(r);
  const NodeSummary s = stats.Snapshot();
  EXPECT_EQ(s.consistency_searches, 2u);
  EXPECT_EQ(s.lidar_overruled, 1u);
  EXPECT_NE(NodeStats::FormatSummary(s).find(" lidar_overruled=1 consistency_searches=2 "),
            std::string::npos);
}

// Scans arriving for more than a second without one processed (a stuck core, or every scan
// refused): the status line says stalled with the seconds instead of the core's last "ok", the
// episode is counted once with what the scans became, and it ends with the next result. Before
// the first result, and for scans left waiting after the stream stopped, it is no stall.
TEST(NodeStats, ScansArrivingWithoutResultsForASecondAreAStall) {
  using std::chrono::milliseconds;
  NodeStats stats;
  ScanResult ok;
  ok.status = Status::kOk;
  ok.pose_valid = true;
  size_t mark = 0;
  auto t = std::chrono::steady_clock::now();
  // No result yet (the core may hold scans on purpose): not a stall.
  for (int i = 0; i < 20; ++i) stats.AddScanReceived(t + milliseconds(100 * i));
  EXPECT_FALSE(stats.CheckCoreStall(t + milliseconds(2000)).stalled);
  stats.CountResult(ok);
  t = std::chrono::steady_clock::now();
  // Two scans left waiting 0.1 s apart (the stream stopped), long after: not a stall. Nor
  // when the data resumes after that silence, until scans have arrived for a second again.
  stats.AddScanReceived(t - milliseconds(3000));
  stats.AddScanReceived(t - milliseconds(2900));
  EXPECT_FALSE(stats.CheckCoreStall(t - milliseconds(100)).stalled);
  stats.AddScanReceived(t);
  stats.AddScanReceived(t + milliseconds(100));
  EXPECT_FALSE(stats.CheckCoreStall(t + milliseconds(150)).stalled);
  for (int i = 2; i <= 10; ++i) stats.AddScanReceived(t + milliseconds(100 * i));
  EXPECT_FALSE(stats.CheckCoreStall(t + milliseconds(1000)).stalled) << "1.0 s is not more";
  EXPECT_NE(stats.PeriodicLine(&mark, QueueFill(), "").find("status=ok "), std::string::npos);
  stats.Add(&NodeSummary::scans_malformed, 3);
  stats.Add(&NodeSummary::scans_late);
  stats.AddScanReceived(t + milliseconds(1200));
  CoreStallPoll p = stats.CheckCoreStall(t + milliseconds(1300));
  EXPECT_TRUE(p.stalled);
  EXPECT_EQ(p.event, CoreStallPoll::Event::kStarted);
  EXPECT_EQ(p.episode, 1u);
  EXPECT_EQ(p.received, 14u);
  EXPECT_EQ(p.refused, 3u);
  EXPECT_EQ(p.dropped, 1u);
  EXPECT_GE(p.seconds, 1.29);
  const std::string line = stats.PeriodicLine(&mark, QueueFill(), "");
  EXPECT_EQ(line.find("status=ok"), std::string::npos) << line;
  EXPECT_NE(line.find("status=stalled (no scan processed for 1."), std::string::npos) << line;
  // Still stalled: not counted again. A stream stall names the silent stream instead.
  p = stats.CheckCoreStall(t + milliseconds(2500));
  EXPECT_EQ(p.event, CoreStallPoll::Event::kNone);
  EXPECT_TRUE(p.stalled);
  EXPECT_NE(
      stats.PeriodicLine(&mark, QueueFill(), "").find("status=stalled (no scan processed for 2."),
      std::string::npos);
  EXPECT_NE(
      stats.PeriodicLine(&mark, QueueFill(), "points").find("status=stalled (no data on points)"),
      std::string::npos);
  stats.CountResult(ok);
  p = stats.CheckCoreStall(std::chrono::steady_clock::now());
  EXPECT_EQ(p.event, CoreStallPoll::Event::kEnded);
  EXPECT_FALSE(p.stalled);
  EXPECT_NE(stats.PeriodicLine(&mark, QueueFill(), "").find("status=ok "), std::string::npos);
  EXPECT_EQ(stats.Snapshot().core_stalls, 1u);
  EXPECT_NE(NodeStats::FormatSummary(stats.Snapshot()).find(" core_stalls=1 "), std::string::npos);
}

TEST(NodeConfig, EmptyYamlGivesDocumentedDefaults) {
  NodeConfig c;
  const auto r = LoadNodeConfigString("", &c);
  ASSERT_TRUE(r.ok);
  EXPECT_TRUE(r.warnings.empty());
  EXPECT_EQ(c.points_topic, "/points");
  EXPECT_EQ(c.imu_topic, "/imu");
  EXPECT_EQ(c.odometry_topic, "/odometry");
  EXPECT_EQ(c.odom_frame, "odom");
  EXPECT_EQ(c.base_frame, "base_link");
  EXPECT_EQ(c.sensor_reliability, Reliability::kBestEffort);
  EXPECT_FALSE(c.publish_registered_points);
  EXPECT_TRUE(c.publish_tf);
  EXPECT_EQ(c.participant.domain_id, 0);
  EXPECT_EQ(c.max_cloud_points, 4000000);
  EXPECT_TRUE(c.publish_odometry_imu_rate);
  EXPECT_EQ(c.odometry_imu_rate_topic, "/odometry/imu");
}

TEST(NodeConfig, MaxCloudPointsIsReadAndKeptPositive) {
  NodeConfig c;
  auto r = LoadNodeConfigString("queues: {max_cloud_points: 500000}\n", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.warnings.empty());
  EXPECT_EQ(c.max_cloud_points, 500000);
  r = LoadNodeConfigString("queues: {max_cloud_points: 0}\n", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(c.max_cloud_points, 1);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("queues.max_cloud_points"), std::string::npos);
}

// A burst inside the interval prints its first line; the rest is counted and carried by the next
// line, or by Flush() when no line follows (the tail of a burst was lost before Flush existed).
TEST(RateLimitedLog, SuppressedLinesAreCountedAndFlushed) {
  RateLimitedLog log(3600.0);
  testing::internal::CaptureStderr();
  for (int i = 0; i < 5; ++i) log.Log(Level::kWarn, "bad input " + std::to_string(i));
  log.Flush();
  log.Flush();  // nothing left: no line
  const std::string out = testing::internal::GetCapturedStderr();
  EXPECT_NE(out.find("[WARN] bad input 0\n"), std::string::npos) << out;
  EXPECT_NE(out.find("[WARN] (+4 similar since the last line) last: bad input 4\n"),
            std::string::npos)
      << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 2) << out;
}

// A matched stream going silent: one event when the episode starts, more only as the silence
// doubles, one when data resumes; counted only once data had flowed since the publishers
// matched, so a replay not yet sending is not a stall in the summary.
TEST(StallWatch, EpisodesStartGrowAndEndAndCountOnlyAfterDataFlowed) {
  using E = StallWatch::Event;
  const auto t0 = StallWatch::Clock::now();
  auto at = [t0](double s) {
    return t0 + std::chrono::duration_cast<StallWatch::Clock::duration>(
                    std::chrono::duration<double>(s));
  };
  StallWatch w(2.0);
  EXPECT_EQ(w.Check(at(100)).event, E::kNone) << "nothing matched: silence is no stall";
  w.OnMatched(1, at(100));
  EXPECT_EQ(w.Check(at(101.9)).event, E::kNone);
  StallWatch::Poll p = w.Check(at(102.1));
  EXPECT_EQ(p.event, E::kStalled);
  EXPECT_FALSE(p.counted) << "never sent since it matched";
  EXPECT_TRUE(w.stalled());
  w.OnSample(at(103));
  p = w.Check(at(103.1));
  EXPECT_EQ(p.event, E::kResumed);
  EXPECT_FALSE(w.stalled());

  w.OnSample(at(104));
  EXPECT_EQ(w.Check(at(105.9)).event, E::kNone);
  p = w.Check(at(106.2));
  EXPECT_EQ(p.event, E::kStalled);
  EXPECT_TRUE(p.counted) << "data had flowed, then stopped";
  EXPECT_NEAR(p.silent_s, 2.2, 1e-6);
  EXPECT_TRUE(w.counted());
  EXPECT_EQ(w.Check(at(108.0)).event, E::kNone) << "no line per poll";
  p = w.Check(at(108.5));
  EXPECT_EQ(p.event, E::kStillStalled) << "silence doubled (4.4 s)";
  EXPECT_EQ(w.Check(at(112.0)).event, E::kNone);
  EXPECT_EQ(w.Check(at(113.1)).event, E::kStillStalled) << "doubled again (9 s)";
  w.OnMatched(0, at(114));
  p = w.Check(at(114.1));
  EXPECT_EQ(p.event, E::kEnded) << "publisher gone: no longer a stall";
  EXPECT_EQ(w.Check(at(130)).event, E::kNone);

  // A publisher matching again starts afresh: silent before its first sample, not counted.
  w.OnMatched(1, at(130));
  p = w.Check(at(132.5));
  EXPECT_EQ(p.event, E::kStalled);
  EXPECT_FALSE(p.counted);

  StallWatch off(0.0);
  off.OnMatched(1, at(100));
  EXPECT_EQ(off.Check(at(1000)).event, E::kNone);
}

TEST(NodeConfig, PartialSectionsKeepOtherDefaults) {
  NodeConfig c;
  const auto r = LoadNodeConfigString(
      "dds: {domain_id: 7}\ntopics: {points: /velodyne_points}\nqos: {sensor_reliability: "
      "reliable}\nframes: {odom_frame: map}\n",
      &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(c.participant.domain_id, 7);
  EXPECT_EQ(c.points_topic, "/velodyne_points");
  EXPECT_EQ(c.imu_topic, "/imu");
  EXPECT_EQ(c.sensor_reliability, Reliability::kReliable);
  EXPECT_EQ(c.odom_frame, "map");
  EXPECT_EQ(c.base_frame, "base_link");
}

TEST(NodeConfig, WrongTypesAndValuesAreErrorsNamingTheKey) {
  NodeConfig c;
  auto r = LoadNodeConfigString("dds: {domain_id: [1, 2]}\n", &c);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("dds.domain_id"), std::string::npos) << r.error;
  r = LoadNodeConfigString("qos: {sensor_reliability: maybe}\n", &c);
  EXPECT_FALSE(r.ok);
  r = LoadNodeConfigString("dds: {domain_id: 400}\n", &c);
  EXPECT_FALSE(r.ok);
  r = LoadNodeConfigString("topics: [a, b]\n", &c);
  EXPECT_FALSE(r.ok);
  r = LoadNodeConfigString("{{{", &c);
  EXPECT_FALSE(r.ok);
  r = LoadNodeConfigString("core: {mode: fast}\n", &c);
  EXPECT_FALSE(r.ok);
  r = LoadNodeConfigString("core: {omp_wait_policy: lazy}\n", &c);
  EXPECT_FALSE(r.ok);
}

// outputs.map_file picks the format by its extension, as ppf_offline --map-out: any other name is
// refused before the node starts (not found out at the first save); a voxel size no map can have
// falls back to the default with a warning.
TEST(NodeConfig, MapFileNeedsAPcdOrPlyNameAndTheVoxelARange) {
  NodeConfig c;
  auto r = LoadNodeConfigString("outputs: {map_file: run/map.PLY, map_voxel: 0.25}\n", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.warnings.empty());
  EXPECT_EQ(c.map_file, "run/map.PLY");
  EXPECT_EQ(c.map_voxel, 0.25);
  NodeConfig d;
  r = LoadNodeConfigString("outputs: {map_file: map.xyz}\n", &d);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error, "outputs.map_file 'map.xyz' must end in .pcd or .ply");
  EXPECT_TRUE(d.map_file.empty());  // all or nothing
  r = LoadNodeConfigString("outputs: {map_file: map.pcd, map_voxel: 0}\n", &d);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_EQ(r.warnings[0], "outputs.map_voxel must be in 0.01..100 m: using 0.1");
  EXPECT_EQ(d.map_voxel, 0.1);
}

// The node's map: only trusted poses go in; a save on request and the one at shutdown each write
// the file with what was added before them and log one line; a file that cannot be written is
// one ERROR line per attempt and the map goes on.
TEST(NodeMap, TrustedScansOnlySavedOnRequestAndAtShutdownAndAFailedWriteIsOneLine) {
  const std::string dir = ::testing::TempDir() + "/ppf_node_map";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  ScanResult r;
  r.status = Status::kOk;
  r.pose_valid = true;
  r.T_world_lidar.translation() = Eigen::Vector3d(5.0, 0.0, 0.0);
  for (int i = 0; i < 10; ++i) r.deskewed_points_lidar.push_back(Eigen::Vector3f(i, 0.f, 0.f));
  auto header_points = [](const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("POINTS ", 0) == 0) return std::atoi(line.c_str() + 7);
    }
    return -1;
  };

  NodeConfig c;
  c.map_file = dir + "/map.pcd";
  c.map_voxel = 0.5;
  testing::internal::CaptureStderr();
  {
    NodeMap map(c);
    ASSERT_TRUE(map.enabled());
    map.Add(r);  // 10 voxels
    ScanResult untrusted = r;
    untrusted.T_world_lidar.translation().x() = 100.0;  // would add voxels of its own
    untrusted.pose_valid = false;
    map.Add(untrusted);
    untrusted.pose_valid = true;
    untrusted.status = Status::kInitializing;
    map.Add(untrusted);
    untrusted.status = Status::kOk;
    untrusted.relocalized = true;  // found again after a long gap: extends no map
    map.Add(untrusted);
    map.RequestSave();
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (map.saves() == 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ASSERT_EQ(map.saves(), 1u);
    EXPECT_EQ(header_points(c.map_file), 10);
    r.status = Status::kDegenerate;
    r.T_world_lidar.translation().y() = 3.0;  // 10 more voxels
    map.Add(r);
    map.Finish();
    EXPECT_EQ(map.saves(), 2u);
    EXPECT_EQ(map.save_errors(), 0u);
    EXPECT_EQ(map.scans_skipped(), 0u);
  }
  EXPECT_EQ(header_points(c.map_file), 20);
  EXPECT_FALSE(std::filesystem::exists(c.map_file + ".tmp"));
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("map saved on request (SIGUSR1): 10 points (0.5 m voxels, 1 scans) -> " +
                     c.map_file + "\n"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("map saved at shutdown: 20 points (0.5 m voxels, 2 scans) -> " + c.map_file +
                     "\n"),
            std::string::npos)
      << log;

  c.map_file = dir + "/no/such/dir/map.ply";
  testing::internal::CaptureStderr();
  {
    NodeMap map(c);
    map.Add(r);
    map.Finish();
    EXPECT_EQ(map.saves(), 0u);
    EXPECT_EQ(map.save_errors(), 1u);
  }
  const std::string error = testing::internal::GetCapturedStderr();
  EXPECT_EQ(std::count(error.begin(), error.end(), '\n'), 1) << error;
  EXPECT_NE(error.find("[ERROR] map not saved at shutdown: cannot write " + c.map_file + ".tmp"),
            std::string::npos)
      << error;

  NodeConfig off;  // no map_file: no thread, nothing written
  NodeMap none(off);
  EXPECT_FALSE(none.enabled());
  none.Add(r);
  none.RequestSave();
  none.Finish();
  EXPECT_EQ(none.saves(), 0u);
  std::filesystem::remove_all(dir);
}

// Found by fuzz_node_config: a key that is itself a list or a map (YAML allows it, a typo such as
// "? sensor_depth: 2" produces one) threw out of the loader and aborted ppf_node at start-up.
TEST(NodeConfig, NonScalarKeysAreRefusedWithAReason) {
  for (const char* yaml : {"? [a]\n: 1\n", "[a]: 1\n", "dds:\n  {x: 1}: 2\n",
                           "dds: {domain_id: 1}\n? {qos: 1}\n: 2\n"}) {
    NodeConfig c;
    NodeConfigReport r;
    ASSERT_NO_THROW(r = LoadNodeConfigString(yaml, &c)) << yaml;
    EXPECT_FALSE(r.ok) << yaml;
    EXPECT_NE(r.error.find("key"), std::string::npos) << r.error;
  }
}

TEST(NodeConfig, UnknownKeysWarnAndNonsenseIsClamped) {
  NodeConfig c;
  const auto r =
      LoadNodeConfigString("topic: {points: /x}\nqueues: {scan_capacity: 0, imu_capcity: 5}\n", &c);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.warnings.size(), 3u);  // 'topic', 'queues.imu_capcity', scan_capacity raised
  EXPECT_EQ(c.scan_queue_capacity, 1);
  EXPECT_EQ(c.points_topic, "/points");
}

TEST(NodeConfig, ShippedPresetsLoadWithoutWarnings) {
  for (const char* f : {"node.yaml", "node_hdl64.yaml", "node_vlp16.yaml", "node_hdl32.yaml",
                        "node_container.yaml"}) {
    NodeConfig c;
    const auto r = LoadNodeConfig(std::string(PPF_CONFIG_DIR) + "/" + f, &c);
    EXPECT_TRUE(r.ok) << f << ": " << r.error;
    EXPECT_TRUE(r.warnings.empty()) << f << ": " << r.warnings.front();
    // Relative paths resolve next to the config file.
    EXPECT_EQ(c.participant.profiles_file.rfind(PPF_CONFIG_DIR, 0), 0u) << f;
  }
}

// A core preset passed as the node config has no node key at all: every key would only be
// warned about and the node would start on defaults (Fast DDS transport included).
TEST(NodeConfig, FileWithNoNodeKeyIsRefusedNamingTheMistake) {
  for (const char* f : {"vlp16.yaml", "hdl32.yaml", "hdl64.yaml"}) {
    NodeConfig c;
    const auto r = LoadNodeConfig(std::string(PPF_CONFIG_DIR) + "/" + f, &c);
    EXPECT_FALSE(r.ok) << f;
    EXPECT_NE(r.error.find("not a ppf_node config"), std::string::npos) << f << ": " << r.error;
    EXPECT_NE(r.error.find("core.config_file"), std::string::npos) << f << ": " << r.error;
  }
  NodeConfig c;
  auto r = LoadNodeConfigString("topic: {points: /x}\nmode: ppf\n", &c);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("topic, mode"), std::string::npos) << r.error;
  // One known key is enough to be a node config; the rest stays a warning.
  r = LoadNodeConfigString("mode: ppf\ncore: {mode: ppf}\n", &c);
  EXPECT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.warnings.size(), 1u);
  // Empty files and empty maps are all-defaults configs, not wrong files.
  EXPECT_TRUE(LoadNodeConfigString("{}\n", &c).ok);
  EXPECT_TRUE(LoadNodeConfigString("# nothing\n", &c).ok);
}

TEST(NodeConfig, CalibrationFileIsLayeredAndResolvedNextToTheConfig) {
  const std::string dir = ::testing::TempDir() + "/ppf_node_cfg_calib";
  std::filesystem::create_directories(dir);
  {
    std::ofstream f(dir + "/node.yaml");
    f << "core: {config_file: core.yaml, calibration_file: robot/calibration.yaml}\n";
  }
  NodeConfig c;
  const auto r = LoadNodeConfig(dir + "/node.yaml", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.warnings.empty());
  EXPECT_EQ(c.core_config_file, dir + "/core.yaml");
  EXPECT_EQ(c.core_calibration_file, dir + "/robot/calibration.yaml");
}

// config/node.yaml is the node's reference file: every key of the loader's table, each with the
// NodeConfig default, except the transport it exists to select (the struct leaves that to Fast
// DDS: a relative profile file needs a config file to be relative to). Fails when a default
// changes without the file, or a key is added to the table without documenting it there.
TEST(NodeConfig, ReferenceFileHoldsEveryKeyWithTheDefault) {
  std::ifstream in(std::string(PPF_CONFIG_DIR) + "/node.yaml");
  ASSERT_TRUE(in) << "config/node.yaml not found at " << PPF_CONFIG_DIR;
  std::stringstream text;
  text << in.rdbuf();
  NodeConfig loaded, defaults;
  const auto r = LoadNodeConfigString(text.str(), &loaded);  // paths as written, not resolved
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();
  const YAML::Node root = YAML::Load(text.str());
  const ConfigTable got = NodeConfigTable(&loaded), want = NodeConfigTable(&defaults);
  std::vector<std::string> diffs;
  for (const std::string& key : want.Keys()) {
    const size_t dot = key.find('.');  // node keys are all section.name
    const YAML::Node section = root[key.substr(0, dot)];
    if (!section || !section.IsMap() || !section[key.substr(dot + 1)] ||
        section[key.substr(dot + 1)].IsNull()) {
      diffs.push_back(key + ": missing");
    } else if (got.ShowValue(key) != want.ShowValue(key)) {
      diffs.push_back(key + ": " + got.ShowValue(key) + " in the file, " + want.ShowValue(key) +
                      " in the struct");
    }
  }
  EXPECT_EQ(diffs, (std::vector<std::string>{
                       "dds.profiles_file: 'dds/shm_udp.xml' in the file, '' in the struct",
                       "dds.profile_name: 'ppf_shm_udp' in the file, '' in the struct"}));
}

TEST(TimeOrderedQueue, KeepsTimeOrderAndEvictsOldestWhenFull) {
  TimeOrderedQueue<int> q(3);
  EXPECT_FALSE(q.Push(0.1, 1).evicted);
  EXPECT_FALSE(q.Push(0.3, 3).evicted);
  const auto late = q.Push(0.2, 2);  // arrives late: sorted in, flagged
  EXPECT_TRUE(late.out_of_order);
  EXPECT_FALSE(late.evicted);
  const auto full = q.Push(0.4, 4);
  ASSERT_TRUE(full.evicted);
  EXPECT_EQ(*full.evicted, 1);  // oldest goes first
  std::deque<std::pair<double, int>> out;
  EXPECT_EQ(q.PopAll(&out), 3u);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0].second, 2);
  EXPECT_EQ(out[1].second, 3);
  EXPECT_EQ(out[2].second, 4);
  EXPECT_EQ(q.Size(), 0u);
  EXPECT_FALSE(q.PopFront());
}

TEST(TimeOrderedQueue, BigJumpBackIsAppendedNotSortedIn) {
  TimeOrderedQueue<int> q(10, 0.5);
  q.Push(10.0, 1);
  q.Push(10.1, 2);
  const auto jump = q.Push(0.0, 3);  // the bag looped
  EXPECT_TRUE(jump.time_jump);
  EXPECT_FALSE(jump.out_of_order);
  const auto small = q.Push(-0.2, 4);  // reordered within the new timeline
  EXPECT_FALSE(small.time_jump);
  EXPECT_TRUE(small.out_of_order);
  std::deque<std::pair<double, int>> out;
  q.PopAll(&out);
  ASSERT_EQ(out.size(), 4u);
  EXPECT_EQ(out[0].second, 1);
  EXPECT_EQ(out[1].second, 2);
  EXPECT_EQ(out[2].second, 4);
  EXPECT_EQ(out[3].second, 3);
}

TEST(GapCounter, CountsMissingSequenceNumbersPerWriter) {
  GapCounter g;
  eprosima::fastrtps::rtps::GUID_t a, b;
  a.guidPrefix.value[0] = 1;
  b.guidPrefix.value[0] = 2;
  EXPECT_EQ(g.Count(a, 5), 0u);  // baseline: a late joiner does not count the past
  EXPECT_EQ(g.Count(a, 6), 0u);
  EXPECT_EQ(g.Count(a, 9), 2u);  // 7 and 8 never arrived
  EXPECT_EQ(g.Count(b, 1), 0u);  // another writer, its own sequence
  EXPECT_EQ(g.Count(b, 3), 1u);
  EXPECT_EQ(g.Count(a, 8), 0u);  // late arrival of an older one: not a gap
  EXPECT_EQ(g.Count(a, 10), 0u);
}

TEST(LatencyStats, NearestRankPercentiles) {
  LatencyStats s;
  EXPECT_TRUE(std::isnan(s.Percentile(50)));
  for (int i = 1; i <= 100; ++i) s.Add(i);
  s.Add(std::nan(""));  // ignored
  EXPECT_EQ(s.count(), 100u);
  EXPECT_DOUBLE_EQ(s.Percentile(50), 50);
  EXPECT_DOUBLE_EQ(s.Percentile(99), 99);
  EXPECT_DOUBLE_EQ(s.Percentile(100), 100);
  EXPECT_DOUBLE_EQ(s.Max(), 100);
}

// The IMU-rate latency's bounded series: percentiles exact to one bin (the bin's upper edge),
// samples beyond the range in the last bin, the maximum exact.
TEST(LatencyHistogram, PercentilesToOneBinAndAnExactMaximum) {
  LatencyHistogram h(0.01, 1.0);
  EXPECT_TRUE(std::isnan(h.Percentile(99)));
  for (int i = 0; i < 98; ++i) h.Add(0.104);
  h.Add(0.5);
  h.Add(7.25);  // beyond the range
  h.Add(std::nan(""));
  EXPECT_EQ(h.count(), 100u);
  EXPECT_NEAR(h.Percentile(50), 0.11, 1e-12);
  EXPECT_NEAR(h.Percentile(98), 0.11, 1e-12);
  EXPECT_NEAR(h.Percentile(99), 0.51, 1e-12);
  EXPECT_DOUBLE_EQ(h.Percentile(100), 7.25);
  EXPECT_DOUBLE_EQ(h.Max(), 7.25);
}

// The listener's in-place decode must accept and reject exactly what DecodeCdr does.
TEST(DecodeCdrPayload, AgreesWithDecodeCdrOnValidAndMalformedPayloads) {
  sensor_msgs::msg::PointCloud2 c;
  c.header().frame_id("lidar");
  c.width(3);
  c.height(1);
  c.point_step(4);
  c.row_step(12);
  c.data() = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  const std::vector<uint8_t> good = msgs::EncodeCdr(c);
  std::vector<uint8_t> padded = good;
  while (padded.size() % 4) padded.push_back(0);
  std::vector<uint8_t> truncated(good.begin(), good.begin() + static_cast<long>(good.size() / 2));
  std::vector<uint8_t> bad_encapsulation = good;
  bad_encapsulation[1] = 0x07;  // XCDR2: not what ROS 2 writes
  const std::vector<uint8_t> garbage = {0x00, 0x01, 0x00, 0x00, 0xff, 0xff, 0xff, 0x7f, 0x01};
  const std::vector<uint8_t> tiny = {0x00, 0x01};
  const std::vector<const std::vector<uint8_t>*> cases = {
      &good, &padded, &truncated, &bad_encapsulation, &garbage, &tiny};
  for (const auto* bytes : cases) {
    eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<uint32_t>(bytes->size()));
    std::copy(bytes->begin(), bytes->end(), payload.data);
    payload.length = static_cast<uint32_t>(bytes->size());
    sensor_msgs::msg::PointCloud2 a, b;
    std::string ea, eb;
    const bool ok_a = msgs::DecodeCdr(*bytes, &a, &ea);
    const bool ok_b = msgs::DecodeCdrPayload(&payload, &b, &eb);
    EXPECT_EQ(ok_a, ok_b) << ea << " / " << eb;
    if (ok_a && ok_b) {
      EXPECT_EQ(a, b);
    }
    if (!ok_b) {
      EXPECT_FALSE(eb.empty());
    }
  }
}

}  // namespace
}  // namespace ppf::dds

// Two test processes at once must not share a DDS domain (each would see the other's node): a
// domain another process has claimed (its lock file flocked) is skipped, and the same salt keeps
// its domain within a process.
TEST(TestDomain, ADomainClaimedElsewhereIsSkippedAndASaltKeepsItsDomain) {
  const int salt = 77;
  const unsigned start = (static_cast<unsigned>(getpid()) * 7u + static_cast<unsigned>(salt)) % 100u;
  const int first_choice = 1 + static_cast<int>(start);
  const char* tmp = std::getenv("TMPDIR");
  const std::string dir = tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
  const std::string path =
      dir + "/ppf_dds_test_domain_" + std::to_string(first_choice) + ".lock";
  // Another holder: a separate open file description, as another process would have.
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0) << "lock file held by another test process";
  const int domain = ppf::test::TestDomainId(salt);
  EXPECT_NE(domain, first_choice);
  EXPECT_GE(domain, 1);
  EXPECT_LE(domain, 100);
  EXPECT_EQ(ppf::test::TestDomainId(salt), domain);
  EXPECT_NE(ppf::test::TestDomainId(salt + 1), domain);
  ::close(fd);
}

// The room test_node feeds (synthetic_scene.cpp): each beam hits a wall, the floor, the ceiling or a pillar
// (corner rays too: the simulator's walls overlap at the edges), nothing beyond the room's box
// (x -15..9, y -8..6, z -1.8..2.7 m from the sensor), and the pillar at x 3..4, y 1.5..2.5 m
// shadows the wall behind it.
TEST(SyntheticRoom, EveryBeamHitsTheRoomAndThePillarCastsAShadow) {
  ppf::dds::SyntheticLidar lidar;
  lidar.rings = 16;
  lidar.columns = 720;
  const sensor_msgs::msg::PointCloud2 m = ppf::dds::MakeRoomScan(lidar, 1000);
  ASSERT_EQ(m.width(), 16u * 720u);
  ASSERT_EQ(m.point_step(), 24u);
  int in_pillar_direction = 0, on_pillar = 0;
  for (uint32_t i = 0; i < m.width(); ++i) {
    float p[3];
    std::memcpy(p, m.data().data() + static_cast<size_t>(i) * 24, sizeof(p));
    ASSERT_TRUE(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) << i;
    EXPECT_GE(p[0], -15.001f);
    EXPECT_LE(p[0], 9.001f);
    EXPECT_GE(p[1], -8.001f);
    EXPECT_LE(p[1], 6.001f);
    EXPECT_GE(p[2], -1.801f);
    EXPECT_LE(p[2], 2.701f);
    // Beams towards the pillar's centre (3.5, 2.0) within a degree, below the ceiling's reach.
    const double az = std::atan2(p[1], p[0]), az_pillar = std::atan2(2.0, 3.5);
    if (std::abs(az - az_pillar) < M_PI / 180.0 && std::abs(p[2]) < 1.0) {
      ++in_pillar_direction;
      on_pillar += std::hypot(p[0], p[1]) < 4.5;
    }
  }
  EXPECT_GT(in_pillar_direction, 0);
  EXPECT_EQ(on_pillar, in_pillar_direction);
}
