// Hostile inputs through DDS from an independent peer: the Cyclone DDS program
// (cyclone/cyclone_peer.c, --hostile) replays a simulated sequence into ppf_node and, once the
// node is initialized, injects one defect per scan: every PointCloud2 and Imu defect of
// docs/reliability.md's table. Per defect the node must refuse (or, for a valid but unusual
// cloud, process) it, say so in a clear rate-limited log line, count it in its summary, stay
// alive and publish odometry for the next valid scan; the peer checks that odometry arrived for
// the scan after each defect.
#include <gtest/gtest.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <regex>
#include <sstream>
#include <string>

#include "cyclone_peer_util.hpp"
#include "dds_test_util.hpp"
#include "ppf_trajectory/trajectory_io.hpp"
#include "test_domain.hpp"
#include "tool_paths.hpp"

using ppf::test::CountLinesWith;
using ppf::test::kUnderTsan;
using ppf::test::SummaryField;

namespace {

std::string SimOrSkipReason(std::string* sim) {
  if (std::string(PPF_CYCLONE_PEER).empty()) {
    return "Cyclone DDS (cyclonedds-dev + idlc) not found at configure time";
  }
  *sim = ppf::test::FindTool("ppf_sim", PPF_SIM_CONFIGURED);
  return sim->empty() ? "ppf_sim not found (PATH or configure time): build ppf_sim" : "";
}

// The peer's "HOSTILE name=<name> ..." line.
std::string PeerLine(const ppf::test::PeerRun& run, const std::string& name) {
  for (const auto& l : run.peer) {
    if (l.rfind("HOSTILE name=" + name + " ", 0) == 0 || l == "HOSTILE name=" + name) return l;
  }
  return "";
}

// Sum of N over "(+N similar since the last line)" in lines containing `needle`.
int SuppressedIn(const std::string& log, const std::string& needle) {
  std::stringstream ss(log);
  std::string line;
  int sum = 0;
  const std::regex re("\\(\\+([0-9]+) similar since the last line\\)");
  while (std::getline(ss, line)) {
    std::smatch m;
    if (line.find(needle) != std::string::npos && std::regex_search(line, m, re)) {
      sum += std::stoi(m[1]);
    }
  }
  return sum;
}

// A rate limiter's flush line (RateLimitedLog::Flush): "(+N similar since the last line) last:
// <latest message>". It reports a suppressed tail that no later line carried; it is not an event
// of its own, and it restarts the limiter's interval without waiting for it.
bool IsFlushLine(const std::string& line) {
  return line.find("similar since the last line) last: ") != std::string::npos;
}

// Lines containing `needle` that the rate limiter let through as events (no flush lines).
int EventLinesWith(const std::string& log, const std::string& needle) {
  std::stringstream ss(log);
  std::string line;
  int n = 0;
  while (std::getline(ss, line)) n += line.find(needle) != std::string::npos && !IsFlushLine(line);
  return n;
}

// Seconds of the log line's "[HH:MM:SS.mmm]" stamp, or -1 without one.
double LogStampSeconds(const std::string& line) {
  int h = 0, m = 0, s = 0, ms = 0;
  if (std::sscanf(line.c_str(), "[%d:%d:%d.%d]", &h, &m, &s, &ms) != 4) return -1.0;
  return h * 3600.0 + m * 60.0 + s + ms * 1e-3;
}

// Smallest time from any line containing `needle` to the next one that the rate limiter let
// through as an event (a flush line may follow an event at once). Infinity when fewer than two
// lines.
double MinGapBetweenLimitedLines(const std::string& log, const std::string& needle) {
  std::stringstream ss(log);
  std::string line;
  double previous = -1.0, min_gap = std::numeric_limits<double>::infinity();
  while (std::getline(ss, line)) {
    if (line.find(needle) == std::string::npos) continue;
    const double t = LogStampSeconds(line);
    if (t < 0.0) continue;
    if (previous >= 0.0 && !IsFlushLine(line)) {
      double gap = t - previous;
      if (gap < -43200.0) gap += 86400.0;  // past midnight
      min_gap = std::min(min_gap, gap);
    }
    previous = t;
  }
  return min_gap;
}

}  // namespace

TEST(Hostile, EveryCloudAndImuDefectIsRefusedCountedLoggedAndTheNextScanGetsOdometry) {
  std::string sim;
  const std::string skip = SimOrSkipReason(&sim);
  if (!skip.empty()) GTEST_SKIP() << skip;
  const std::string dir = ppf::test::TempDir("ppf_dds_hostile");
  // 2.5 s at rest (initialization), then hand-held motion: defects hit a moving robot, where a
  // needless filter reset would end odometry (a restart needs rest).
  int clouds = 0, imus = 0;
  ASSERT_TRUE(ppf::test::SimulateDump(sim,
                                      {"--scene", "indoor", "--lidar", "vlp16", "--duration", "9",
                                       "--seed", "2", "--storage", "mcap"},
                                      dir, &clouds, &imus));
  // After cloud 28: 18 clouds alternating cloud and IMU defects, 18 more defects one per cloud
  // (the stall takes 20 clouds), and the scan that checks the last one.
  ASSERT_GE(clouds, 28 + 18 + 18 + 19 + 1);

  ppf::test::PeerRun run;
  // Reliable sensor QoS: the ~67 MB "several million points" cloud must not be lost to a
  // dropped UDP fragment. Deep reader histories and scan queue: while the listener decodes that
  // cloud and the core registers it (seconds under ThreadSanitizer), the burst of 30 and the IMU
  // stream must neither overwrite unread samples nor evict valid scans. A short log interval
  // (defects are 0.1 s apart) so each defect's own line shows; the burst of 30 is still
  // suppressed. A status line every 0.25 s, so the 2 s stall shows in them.
  ASSERT_NO_FATAL_FAILURE(
      ppf::test::RunNodeAndPeer(PPF_CYCLONE_PEER, dir, ppf::test::TestDomainId(31),
                                "core: {config_file: \"" PPF_CONFIG_DIR "/vlp16.yaml\"}\n"
                                "qos: {sensor_reliability: reliable, sensor_depth: 200}\n"
                                "queues: {scan_capacity: 100}\n"
                                "diagnostics: {malformed_log_interval_s: 0.05, period_s: 0.25}\n",
                                {"--hostile", "28", "--imu-gap", "1.8", "0.4"}, &run));
  const std::string& s = run.summary;
  const std::string& log = run.log;

  // Every defect went out, and for each one the peer got odometry for the scan after it (or for
  // the replacing cloud itself).
  EXPECT_EQ(SummaryField(run.result, "write_errors"), 0);
  EXPECT_EQ(SummaryField(run.result, "hostile_checks"), 36);
  EXPECT_EQ(SummaryField(run.result, "hostile_checks_failed"), 0);
  for (const auto& l : run.peer) {
    if (l.rfind("HOSTILE_CHECK", 0) == 0) {
      EXPECT_NE(l.find(" odom=1"), std::string::npos) << l;
    }
  }

  // PointCloud2 layout defects: refused in the listener, one reason each.
  const std::string bad = "rejected malformed PointCloud2 on rt/points";
  EXPECT_EQ(CountLinesWith(log, "lies beyond point_step 8"), 1) << "point_step < its fields";
  EXPECT_EQ(CountLinesWith(log, "(need "), 1) << "data shorter than declared";
  EXPECT_EQ(CountLinesWith(log, "header declares"), 1) << "data longer than declared";
  EXPECT_EQ(CountLinesWith(log, "< width * point_step"), 1) << "row_step mismatch";
  EXPECT_EQ(CountLinesWith(log, "big-endian point clouds are not supported"), 1);
  EXPECT_EQ(CountLinesWith(log, "duplicate field 'x'"), 1);
  EXPECT_EQ(CountLinesWith(log, "cloud lacks an x, y or z field"), 1);
  // Offsets beyond point_step: the last field moved to offset point_step, plus the point_step 8.
  EXPECT_EQ(CountLinesWith(log, "lies beyond point_step"), 2);
  // Unknown datatype: once alone, then a burst of 30 and one more 0.2 s later. Rate limited: the
  // burst shows as a few lines, the rest as "(+N similar ...)" on the next line; nothing hidden.
  // A flush line reports a burst's tail that no later line carried; it is not an event of its own.
  const int unknown_lines = EventLinesWith(log, "has unknown datatype 42");
  // How many lines pass depends on how fast the node takes the burst in (a loaded or
  // instrumented node spreads it over more intervals, and the tail may come within an interval
  // of a periodic flush, which then reports it), so the count is not the test beyond the lone
  // defect's line and the burst's first (seconds apart): the limit is. No two lines of the
  // limiter come closer than its interval (0.05 s; 0.02 asserted, as the log stamps a line after
  // the limiter read its clock, late on a loaded machine), and the sum below still accounts for
  // every one of the 32.
  constexpr bool kInstrumented = kUnderTsan || ppf::test::kUnderAsan;
  EXPECT_GE(unknown_lines, 2);
  const double min_gap = MinGapBetweenLimitedLines(log, bad);
  EXPECT_GE(min_gap, 0.02) << "lines closer than the log interval";
  EXPECT_LT(min_gap, 0.5) << "the log's stamps were not read";  // defects come 0.1 s apart
  std::cout << "closest rate-limited lines: " << min_gap << " s apart\n";
  EXPECT_GE(SuppressedIn(log, bad), kInstrumented ? 2 : 8) << "the burst was not rate limited";
  // Every malformed cloud accounted for, in a line of its own or a "+N" (the stall's share the
  // same limiter as the burst's).
  EXPECT_EQ(EventLinesWith(log, bad) + SuppressedIn(log, bad), SummaryField(s, "scans_malformed"));
  EXPECT_EQ(SummaryField(s, "scans_malformed"), 8 + 2 + 20 + 32);

  // Header stamp with nanosec 4e9 (read as seconds ahead, it would declare the IMU lost and drop
  // the next scans as late): refused as malformed, cloud and IMU alike.
  EXPECT_EQ(CountLinesWith(log, ": header.stamp.nanosec 4000000000 is out of range"), 1);
  EXPECT_EQ(CountLinesWith(log, "Imu on rt/imu: IMU sample's header.stamp.nanosec 4000000000"), 1);
  // No field table at all: said so, not as a missing x/y/z.
  EXPECT_EQ(CountLinesWith(log, "cloud declares no fields (x, y and z are needed)"), 1);
  // Usable but unusual clouds (processed in place of a scan, odometry checked above): each kind
  // named once. row_step 0 is read as width * point_step (drivers have published it).
  EXPECT_EQ(CountLinesWith(log, "has row_step 0: read as width * point_step"), 1);
  EXPECT_EQ(CountLinesWith(log, "fields: only x, y, z and the time field are read"), 1);
  EXPECT_TRUE(std::regex_search(log, std::regex("declares 50[0-9][0-9] fields")));
  EXPECT_EQ(CountLinesWith(log, "has a frame_id of 200000 bytes"), 1);
  EXPECT_EQ(SummaryField(s, "scans_unusual"), 3);

  // Point times off the sweep, in place of a valid scan (one point far ahead must not stop the
  // core, nor points far back reset it): the bad points dropped and counted, a scan made
  // only of them rejected with the reason; no reset, odometry for the next scans (checked above).
  const std::string past = PeerLine(run, "point_time_past");
  ASSERT_FALSE(past.empty());
  const double past_points = SummaryField(" " + past, "points");
  EXPECT_GT(past_points, 1000) << past;
  EXPECT_EQ(SummaryField(s, "points_bad_time"), 1 + past_points);
  EXPECT_EQ(SummaryField(s, "scans_rejected"), 1);
  EXPECT_GE(CountLinesWith(log, "point times outside the plausible sweep window"), 1);
  EXPECT_EQ(CountLinesWith(log, "went backwards"), 0);

  // 2 s of clouds each refused (x as int8): scans arrive, none is processed. The node says so
  // once, with what the scans became, its status lines say stalled and never ok meanwhile, and
  // the next valid scan gives odometry (HOSTILE_CHECK stall, above).
  EXPECT_GE(CountLinesWith(log, "field 'x' must be float32 or float64"), 1);
  const std::string stall_warn = "stalled: no scan processed for ";
  // The 67 MB cloud keeps the core busy while the scans the peer held back behind it arrive: a
  // true stall too, when that takes over a second (under a sanitizer, for seconds).
  EXPECT_GE(SummaryField(s, "core_stalls"), 1);
  EXPECT_LE(SummaryField(s, "core_stalls"), kInstrumented ? 10 : 2);
  EXPECT_EQ(CountLinesWith(log, stall_warn), SummaryField(s, "core_stalls")) << log;
  // Every episode ends in the log: by a result, or (under a sanitizer the core may still be
  // behind when the peer is done) said to be open when the node stops.
  EXPECT_EQ(CountLinesWith(log, "scans processed again after") +
                CountLinesWith(log, " still open at the stop: no scan processed for the last "),
            SummaryField(s, "core_stalls"));
  // The stall's WARN says what the scans became: those refused at input named, none dropped, the
  // rest waiting for the core. Only refused ones when the core keeps up; on a loaded machine
  // valid scans from before the refused ones may still wait behind a slow core ("15 arrived (10
  // refused at input, 0 dropped ..., 5 waiting for the core)" beside two busy processes).
  std::string stall_lines;
  bool refused_named = false;
  {
    const std::regex counts(
        "while ([0-9]+) arrived \\(([0-9]+) refused at input, ([0-9]+) dropped as late or from the "
        "full queue, ([0-9]+) waiting for the core\\)");
    std::stringstream ls(log);
    std::string line;
    while (std::getline(ls, line)) {
      if (line.find(stall_warn) == std::string::npos) continue;
      stall_lines += line + "\n";
      std::smatch m;
      if (!std::regex_search(line, m, counts)) continue;
      const int arrived = std::stoi(m[1]), refused = std::stoi(m[2]);
      const int dropped = std::stoi(m[3]), waiting = std::stoi(m[4]);
      refused_named |= refused >= 1 && dropped == 0 && refused + waiting == arrived;
    }
  }
  EXPECT_TRUE(refused_named) << "no stall WARN names the refused scans; the stall lines:\n"
                             << stall_lines;
  {
    std::stringstream ls(log);
    std::string line;
    bool in_stall = false, seen_stall = false;
    int stalled_lines = 0;
    while (std::getline(ls, line)) {
      if (line.find(stall_warn) != std::string::npos) in_stall = seen_stall = true;
      if (line.find("scans processed again after") != std::string::npos) in_stall = false;
      if (in_stall && line.find("] status=") != std::string::npos) {
        EXPECT_NE(line.find("status=stalled (no scan processed for "), std::string::npos) << line;
        ++stalled_lines;
      }
    }
    EXPECT_TRUE(seen_stall);
    EXPECT_GE(stalled_lines, 1) << "no status line during the stall";
  }

  // Well-formed clouds the node cannot use: empty, declared 5M points, stamp 0, stamp 11.6 days
  // ahead, stamp 3 s older than the scan before.
  EXPECT_EQ(SummaryField(s, "scans_empty"), 1);
  EXPECT_EQ(CountLinesWith(log, "empty PointCloud2 on rt/points"), 1);
  EXPECT_EQ(SummaryField(s, "scans_too_large"), 1);
  EXPECT_EQ(CountLinesWith(log,
                           "5000000-point PointCloud2 on rt/points exceeds "
                           "queues.max_cloud_points 4000000: skipped"),
            1);
  EXPECT_EQ(SummaryField(s, "scans_bad_stamp"), 2);
  EXPECT_EQ(CountLinesWith(log, "PointCloud2 on rt/points has stamp 0.000000 (unset clock?)"), 1);
  EXPECT_EQ(CountLinesWith(log, "s ahead of the IMU stream (far-future stamp"), 1);
  EXPECT_EQ(SummaryField(s, "scans_late"), 1);
  EXPECT_EQ(CountLinesWith(log, "is 3.000000 s older than the last processed one: dropped"), 1);

  // Valid but unusual clouds, processed in place of a scan (checked above: odometry for each).
  const std::string huge = PeerLine(run, "huge");
  ASSERT_FALSE(huge.empty());
  EXPECT_GE(SummaryField(" " + huge, "points"), 2e6) << huge;  // "several million points"
  const std::string nan_line = PeerLine(run, "nan_points");
  const double nonfinite = SummaryField(" " + nan_line, "nonfinite");
  EXPECT_GT(nonfinite, 1000) << nan_line;
  EXPECT_EQ(SummaryField(s, "points_nonfinite"), nonfinite);
  // One line naming the count (the sequence itself has no non-finite points).
  EXPECT_EQ(CountLinesWith(log, ": " + std::to_string(static_cast<int>(nonfinite)) + " of "), 1);
  EXPECT_EQ(CountLinesWith(log, "points non-finite (NaN/Inf), dropped"), 1);

  // The IMU silent for 0.4 s at rest, after initialization: one gap over the core's
  // imu.max_gap_warn (0.1 s), named once and counted, no reset.
  EXPECT_NEAR(SummaryField(run.result, "skipped_imu"), 80, 2);  // 0.4 s of 200 Hz
  EXPECT_EQ(SummaryField(s, "imu_gaps"), 1);
  EXPECT_NEAR(SummaryField(s, "imu_gap_warn_max_s"), 0.405, 0.01);
  EXPECT_EQ(CountLinesWith(log, "> imu.max_gap_warn"), 1);

  // Imu defects: NaN, 1e5 m/s^2, all zeros refused in the listener; a duplicate, a swapped pair,
  // one sample 10 s back and one 1000 s ahead dropped by the executor without a reset.
  EXPECT_EQ(SummaryField(s, "imu_malformed"), 4);
  EXPECT_EQ(CountLinesWith(log, "rejected malformed Imu on rt/imu: IMU sample has non-finite"), 1);
  EXPECT_EQ(CountLinesWith(log, "IMU sample beyond any IMU's range"), 1);
  EXPECT_EQ(CountLinesWith(log, "IMU sample is all zeros"), 1);
  EXPECT_EQ(SummaryField(s, "imu_duplicate"), 1);
  EXPECT_EQ(CountLinesWith(log, "has the stamp of the sample before it (duplicate): dropped"), 1);
  // 0.5 s of samples each preceded by a copy with its stamp and other values (+5 m/s^2,
  // +1 rad/s). Before: the first by arrival was kept, the valid ones dropped as duplicates
  // (imu_duplicate 100) and the pose drifted off. Now every stamp is a conflict the core
  // decides by the samples on either side, counted and named; no duplicates, no reset.
  EXPECT_EQ(SummaryField(s, "imu_conflicts"), 100);
  EXPECT_EQ(SummaryField(s, "imu_conflicts_unresolved"), 0);
  EXPECT_GE(CountLinesWith(log, "IMU samples in conflict"), 1);
  // The swapped pair is sorted back in the listener's queue, or, if the executor had already
  // integrated the later sample, dropped as late (logged): one of the two, never both.
  EXPECT_EQ(SummaryField(s, "imu_out_of_order") + SummaryField(s, "imu_late"), 1);
  EXPECT_EQ(CountLinesWith(log, "arrived after newer ones were integrated"),
            SummaryField(s, "imu_late"));
  EXPECT_EQ(SummaryField(s, "imu_outliers"), 2);
  EXPECT_EQ(CountLinesWith(log, "10.000000 s behind the stream"), 1);
  EXPECT_EQ(CountLinesWith(log, "1000.000000 s ahead of the stream"), 1);
  // Each stamp off the timeline is seen once by a listener queue (stale and future scan, IMU
  // back and ahead); none restarted the core.
  EXPECT_EQ(SummaryField(s, "time_jumps"), 4);
  EXPECT_EQ(SummaryField(s, "resets"), 0);
  EXPECT_EQ(CountLinesWith(log, "core restarted"), 0);

  // Nothing else went missing or wrong: every valid (and replacing) cloud was processed, each
  // after initialization gave one odometry message, all received by the peer, finite, in order.
  // Nothing vanished unseen: what did not arrive is counted lost (sequence gaps). 47 cloud
  // defects follow valid clouds; 8 IMU defects (the swapped sample is not in sent_imu) and the
  // 100 conflicting copies.
  EXPECT_EQ(SummaryField(s, "scans_received") + SummaryField(s, "scans_lost"),
            SummaryField(run.result, "sent_scans") + 47);
  EXPECT_EQ(SummaryField(s, "imu_received") + SummaryField(s, "imu_lost"),
            SummaryField(run.result, "sent_imu") + 8 + 100);
  // And nothing was lost (loopback, reliable, deep histories), instrumented node included: while
  // its listener decodes the 67 MB cloud (seconds under a sanitizer) IMU datagrams overflow its
  // socket buffer, and the peer's 10 s IMU history lets them be sent again.
  EXPECT_EQ(SummaryField(s, "scans_lost"), 0);
  EXPECT_EQ(SummaryField(s, "imu_lost"), 0);
  EXPECT_EQ(SummaryField(s, "scans_dropped"), 0);
  EXPECT_EQ(SummaryField(run.result, "sent_scans"), clouds);
  EXPECT_EQ(SummaryField(s, "scans_processed"), clouds - 20);  // the stall's 20 refused
  EXPECT_EQ(SummaryField(s, "scans_received"), clouds + 8 + 2 + 32 + 5);
  const double published = SummaryField(s, "odometry_published");
  EXPECT_EQ(published, clouds - 20 - SummaryField(s, "scans_initializing") - 1)
      << "odometry for every processed scan but the one rejected for its point times";
  EXPECT_EQ(SummaryField(run.result, "odom"), published);
  EXPECT_EQ(SummaryField(run.result, "odom_bad"), 0);
  EXPECT_EQ(SummaryField(run.result, "odom_not_monotonic"), 0);
  // Memory bounded: the 2.1M-point cloud (~67 MB) passes through the node's buffers once, the
  // 5M-point one is refused before its data is used. Measured peak RSS: 277 MB; 695 MB under
  // ThreadSanitizer, whose shadow memory multiplies what the node touches.
  EXPECT_GT(run.node_hwm_kb, 0);
  EXPECT_LT(run.node_hwm_kb, (kUnderTsan || ppf::test::kUnderAsan ? 2000 : 600) * 1024)
      << "node peak RSS";
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

// The IMU falls silent for 2 s mid-run while the LiDAR goes on (a dropout, a 2 s gap). The core
// bridges the gap (state and map kept, uncertainty widened: imu.max_gap_bridge) and says so; the
// node publishes odometry for every scan, with no reset and no jump. The platform stays at rest,
// so the pose after the gap must equal the pose before it.
TEST(Hostile, ImuDropoutOfTwoSecondsIsBridgedWithoutResetOrJump) {
  std::string sim;
  const std::string skip = SimOrSkipReason(&sim);
  if (!skip.empty()) GTEST_SKIP() << skip;
  const std::string dir = ppf::test::TempDir("ppf_dds_imu_gap");
  int clouds = 0, imus = 0;
  ASSERT_TRUE(ppf::test::SimulateDump(sim,
                                      {"--scene", "indoor", "--lidar", "vlp16", "--duration", "8",
                                       "--static", "8", "--seed", "3", "--storage", "mcap"},
                                      dir, &clouds, &imus));
  ppf::test::PeerRun run;
  ASSERT_NO_FATAL_FAILURE(
      ppf::test::RunNodeAndPeer(PPF_CYCLONE_PEER, dir, ppf::test::TestDomainId(32),
                                "core: {config_file: \"" PPF_CONFIG_DIR "/vlp16.yaml\"}\n"
                                "trajectory: {tum_file: \"" +
                                    dir + "/node.tum\"}\n",
                                {"--imu-gap", "3", "2"}, &run));
  const std::string& s = run.summary;
  const std::string& log = run.log;
  EXPECT_NEAR(SummaryField(run.result, "skipped_imu"), 400, 2);  // 2 s of 200 Hz
  EXPECT_EQ(SummaryField(s, "imu_received"), imus - SummaryField(run.result, "skipped_imu"));
  // Said what happened: the stream came back after 2 s and the core bridged the gap.
  EXPECT_EQ(CountLinesWith(log, "IMU stream resumed after 2.0"), 1) << log;
  EXPECT_GE(CountLinesWith(log, "core: IMU gap of 2.0"), 1) << log;
  EXPECT_GE(CountLinesWith(log, "input gap: no IMU for 2.0"), 1) << log;
  EXPECT_EQ(CountLinesWith(log, "IMU initialized at"), 1) << log;
  EXPECT_EQ(SummaryField(s, "resets"), 0);
  EXPECT_EQ(SummaryField(s, "imu_gaps_bridged"), 1);
  EXPECT_NEAR(SummaryField(s, "imu_gap_max_s"), 2.0, 0.05);
  EXPECT_EQ(SummaryField(s, "scans_lost"), 0);
  EXPECT_EQ(SummaryField(s, "imu_outliers"), 0);
  EXPECT_EQ(SummaryField(s, "odometry_published"), clouds - SummaryField(s, "scans_initializing"))
      << "a scan without odometry";
  // Odometry before, across and after the gap, to the end, and no jump: at rest, the last pose
  // before the gap and the last pose of the run coincide.
  const std::string tum = ppf::test::ReadTextFile(dir + "/node.tum");
  std::stringstream ss(tum);
  const double t0 = 1700000000.0;  // ppf_sim's default start time
  double t, x, y, z, last = -1, before = 0, after = 0;
  Eigen::Vector3d p_before(0, 0, 0), p_last(0, 0, 0);
  std::string rest;
  while (ss >> t >> x >> y >> z && std::getline(ss, rest)) {
    if (t < t0 + 3.0) {
      ++before;
      p_before = Eigen::Vector3d(x, y, z);
    }
    if (t > t0 + 6.0) ++after;
    last = t;
    p_last = Eigen::Vector3d(x, y, z);
  }
  EXPECT_GE(before, 15) << "odometry before the gap";
  EXPECT_GE(after, 15) << "odometry after the gap (6..8 s)";
  EXPECT_GT(last, t0 + 7.8);
  EXPECT_LT((p_last - p_before).norm(), 0.05) << "the pose jumped across the gap";
  EXPECT_EQ(SummaryField(run.result, "odom"), SummaryField(s, "odometry_published"));
  EXPECT_EQ(SummaryField(run.result, "odom_bad"), 0);
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

// The IMU falls silent for 3 s while the robot drives on at 10 m/s (a driver crash).
// The core continues LiDAR-only over the dropout and resumes LIO when the IMU is back; the node
// says both, counts the fallback and publishes odometry for every scan, with no reset and no
// step of the pose more than 0.2 m off the true one.
TEST(Hostile, ImuDropoutOfThreeSecondsWhileDrivingFallsBackToLidarOnlyAndResumes) {
  std::string sim;
  const std::string skip = SimOrSkipReason(&sim);
  if (!skip.empty()) GTEST_SKIP() << skip;
  const std::string dir = ppf::test::TempDir("ppf_dds_imu_loss");
  ASSERT_TRUE(ppf::test::SimulateSequence(sim,
                                          {"--scene", "urban", "--lidar", "vlp16", "--duration",
                                           "12", "--seed", "1", "--storage", "mcap"},
                                          dir + "/bag", dir + "/sim.log"));
  ppf::Trajectory gt;
  std::string error;
  ASSERT_TRUE(ppf::ReadTum(dir + "/bag/groundtruth.tum", &gt, &error)) << error;
  ASSERT_FALSE(gt.empty());
  std::system(("cp '" + dir + "/bag/calibration.yaml' '" + dir + "/calibration.yaml'").c_str());
  int imus = 0;
  const int clouds = ppf::test::WriteDump(dir + "/bag", dir + "/seq.dump", &imus);
  ASSERT_GT(clouds, 0);
  std::system(("rm -rf '" + dir + "/bag'").c_str());
  ppf::test::PeerRun run;
  ASSERT_NO_FATAL_FAILURE(ppf::test::RunNodeAndPeer(
      PPF_CYCLONE_PEER, dir, ppf::test::TestDomainId(33),
      "core: {config_file: \"" PPF_CONFIG_DIR "/vlp16.yaml\", calibration_file: \"" + dir +
          "/calibration.yaml\"}\ntrajectory: {tum_file: \"" + dir + "/node.tum\"}\n",
      {"--imu-gap", "6", "3"}, &run));
  const std::string& s = run.summary;
  const std::string& log = run.log;
  EXPECT_NEAR(SummaryField(run.result, "skipped_imu"), 600, 2);  // 3 s of 200 Hz
  EXPECT_EQ(CountLinesWith(log, "continuing LiDAR-only"), 1) << log;
  EXPECT_EQ(CountLinesWith(log, "core: IMU back: LIO resumed after 3.0"), 1) << log;
  EXPECT_EQ(SummaryField(s, "resets"), 0);
  EXPECT_EQ(SummaryField(s, "imu_fallbacks"), 1);
  EXPECT_GE(SummaryField(s, "imu_fallback_scans"), 20);
  EXPECT_EQ(SummaryField(s, "scans_bad_stamp"), 0);
  // Odometry for every scan the core was given. The Release node keeps up and drops none; under
  // ThreadSanitizer the instrumented node dropped 7 of 120 from its queue (counted) in a
  // fresh-clone CI run while another build ran beside it.
  const double dropped = SummaryField(s, "scans_dropped");
  if (kUnderTsan) {
    EXPECT_LE(dropped, 0.1 * clouds);
  } else {
    EXPECT_EQ(dropped, 0);
  }
  EXPECT_EQ(SummaryField(s, "odometry_published"),
            clouds - dropped - SummaryField(s, "scans_initializing"))
      << "a scan without odometry";
  ppf::Trajectory est;
  ASSERT_TRUE(ppf::ReadTum(dir + "/node.tum", &est, &error)) << error;
  const auto nearest = [&gt](double t) {
    auto it = std::lower_bound(gt.begin(), gt.end(), t,
                               [](const ppf::StampedPose& p, double x) { return p.stamp_s < x; });
    if (it == gt.end()) --it;
    if (it != gt.begin() && t - (it - 1)->stamp_s < it->stamp_s - t) --it;
    return *it;
  };
  double worst = 0.0, worst_t = 0.0;
  for (size_t i = 1; i < est.size(); ++i) {
    const ppf::StampedPose g0 = nearest(est[i - 1].stamp_s), g1 = nearest(est[i].stamp_s);
    const Eigen::Vector3d d_est = (est[i - 1].T.inverse() * est[i].T).translation();
    const Eigen::Vector3d d_gt = (g0.T.inverse() * g1.T).translation();
    if ((d_est - d_gt).norm() > worst) {
      worst = (d_est - d_gt).norm();
      worst_t = est[i].stamp_s - gt.front().stamp_s;
    }
  }
  std::cout << "[ IMU loss over DDS ] " << SummaryField(s, "imu_fallback_scans")
            << " scans LiDAR-only, max pose jump " << worst << " m at t=" << worst_t << " s\n";
  EXPECT_LE(worst, 0.2);
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

// The IMU's clock falls 5 s behind the LiDAR's at 3 s and stays there (a persistent clock
// offset, docs/reliability.md). The node takes the IMU's jump back for a bag loop and restarts
// the core once; the core then sees both streams live, the IMU seconds behind every scan, names
// the offset in one WARN, sets the IMU aside (counted) and registers LiDAR-only: odometry again
// within a few scans of the restart, to the end of the run, never stuck initializing.
TEST(Hostile, ImuClockBehindTheLidarIsNamedAndTheNodeGoesOnLidarOnly) {
  std::string sim;
  const std::string skip = SimOrSkipReason(&sim);
  if (!skip.empty()) GTEST_SKIP() << skip;
  const std::string dir = ppf::test::TempDir("ppf_dds_imu_offset");
  int clouds = 0, imus = 0;
  ASSERT_TRUE(ppf::test::SimulateDump(sim,
                                      {"--scene", "indoor", "--lidar", "vlp16", "--duration", "6",
                                       "--static", "6", "--seed", "3", "--storage", "mcap"},
                                      dir, &clouds, &imus));
  ppf::test::PeerRun run;
  ASSERT_NO_FATAL_FAILURE(
      ppf::test::RunNodeAndPeer(PPF_CYCLONE_PEER, dir, ppf::test::TestDomainId(35),
                                "core: {config_file: \"" PPF_CONFIG_DIR "/vlp16.yaml\"}\n"
                                "trajectory: {tum_file: \"" +
                                    dir +
                                    "/node.tum\"}\n"
                                    "diagnostics: {period_s: 0.25}\n",
                                {"--imu-clock-offset", "3", "5"}, &run));
  const std::string& s = run.summary;
  const std::string& log = run.log;
  const double shifted = SummaryField(run.result, "offset_imu");
  EXPECT_NEAR(shifted, 600, 2);  // 3 s of 200 Hz
  // The one restart the node makes for an IMU time jump back.
  EXPECT_EQ(SummaryField(s, "resets"), 1);
  EXPECT_EQ(CountLinesWith(log, "core restarted"), 1) << log;
  // The offset named once, with its size (scan end minus the newest IMU sample). A core slow
  // enough (a sanitizer build beside other tests) may have initialized LIO on the restarted
  // stream before its 10 judged scans: the WARN is then the IMU-loss one naming the offset.
  const std::regex warn_re("IMU clock ([0-9.]+) s behind the LiDAR's");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(log, m, warn_re)) << log;
  EXPECT_NEAR(std::stod(m[1]), 5.0, 0.2) << m[0];
  EXPECT_EQ(CountLinesWith(log, "s behind the LiDAR's"), 1);
  EXPECT_EQ(CountLinesWith(log, "clocks agree again"), 0);
  EXPECT_EQ(CountLinesWith(log, "moving-start initialization restarts"), 0);
  // Counted: every sample after the WARN set aside; those before it were being judged.
  const double set_aside = SummaryField(s, "imu_clock_offset_dropped");
  EXPECT_LE(set_aside, shifted);
  EXPECT_GE(set_aside, shifted - 1.5 * 200) << "the offset took more than 1.5 s to see";
  // Odometry again within a few scans of the restart (the 10 judged ones and the one after),
  // and to the end of the run.
  ppf::Trajectory est;
  std::string error;
  ASSERT_TRUE(ppf::ReadTum(dir + "/node.tum", &est, &error)) << error;
  const double t0 = 1700000000.0;  // ppf_sim's default start time
  double first_after = 0.0;
  int after = 0;
  for (const ppf::StampedPose& p : est) {
    if (p.stamp_s <= t0 + 3.05) continue;
    if (after++ == 0) first_after = p.stamp_s - t0;
  }
  std::cout << "[ IMU clock offset ] " << m[0] << ", " << set_aside
            << " samples set aside; odometry again at t=" << first_after << " s, " << after
            << " poses after the restart\n";
  EXPECT_GE(after, 15) << "odometry after the restart (3..6 s)";
  EXPECT_LE(first_after, 3.0 + 1.3) << "first odometry after the restart";
  ASSERT_FALSE(est.empty());
  EXPECT_GT(est.back().stamp_s, t0 + 5.8);
  // Not stuck initializing: the status lines after the WARN say LiDAR-only odometry.
  {
    std::stringstream ls(log);
    std::string line;
    bool warned = false;
    int lines = 0;
    while (std::getline(ls, line)) {
      if (line.find("s behind the LiDAR's") != std::string::npos) warned = true;
      if (!warned || line.find("] status=") == std::string::npos) continue;
      ++lines;
      EXPECT_EQ(line.find("status=initializing"), std::string::npos) << line;
    }
    EXPECT_GE(lines, 2) << "no status line after the WARN";
  }
  EXPECT_NE(s.find("last_status=ok"), std::string::npos) << s;
  EXPECT_EQ(SummaryField(run.result, "odom"), SummaryField(s, "odometry_published"));
  EXPECT_EQ(SummaryField(run.result, "odom_bad"), 0);
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}
