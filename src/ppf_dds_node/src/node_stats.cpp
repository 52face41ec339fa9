#include "node_stats.hpp"

#include <algorithm>
#include <iomanip>
#include <sstream>

namespace ppf::dds {

namespace {

double MsBetween(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

uint64_t NodeStats::Add(uint64_t NodeSummary::*counter, uint64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  summary_.*counter += n;
  return summary_.*counter;
}

void NodeStats::AddScanReceived(std::chrono::steady_clock::time_point t) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++summary_.scans_received;
  // The span of arrivals without a result starts again after a silence: scans left waiting
  // while both streams paused are not a stall once the data resumes.
  if (unanswered_++ == 0 ||
      std::chrono::duration<double>(t - last_received_).count() > kCoreStallS) {
    first_unanswered_ = t;
  }
  last_received_ = t;
}

namespace {

uint64_t Refused(const NodeSummary& s) {
  return s.scans_malformed + s.scans_too_large + s.scans_empty + s.scans_bad_stamp;
}
uint64_t Dropped(const NodeSummary& s) { return s.scans_late + s.scans_dropped; }

}  // namespace

CoreStallPoll NodeStats::CheckCoreStall(std::chrono::steady_clock::time_point now) {
  std::lock_guard<std::mutex> lock(mutex_);
  CoreStallPoll p;
  // Before the first result the status says "waiting" anyway, and the core may be holding scans
  // on purpose (imu.auto_wait). One or two scans waiting since the stream stopped are no stall:
  // the arrivals themselves must span the interval.
  const bool stalled =
      have_result_ && unanswered_ >= 2 &&
      std::chrono::duration<double>(last_received_ - first_unanswered_).count() > kCoreStallS;
  using Seconds = std::chrono::duration<double>;
  if (stalled && !core_stalled_) {
    p.event = CoreStallPoll::Event::kStarted;
    ++summary_.core_stalls;
    stall_since_ = last_result_;
  } else if (!stalled && core_stalled_) {
    // Ended by a result: how long none came.
    p.event = CoreStallPoll::Event::kEnded;
    p.seconds = Seconds(last_result_ - stall_since_).count();
  }
  core_stalled_ = stalled;
  p.stalled = stalled;
  if (stalled) p.seconds = core_stall_s_ = Seconds(now - last_result_).count();
  p.episode = summary_.core_stalls;
  p.received = summary_.scans_received - at_last_result_.scans_received;
  p.refused = Refused(summary_) - Refused(at_last_result_);
  p.dropped = Dropped(summary_) - Dropped(at_last_result_);
  return p;
}

void NodeStats::CountResult(const ScanResult& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  have_result_ = true;
  last_result_ = std::chrono::steady_clock::now();
  unanswered_ = 0;
  at_last_result_ = summary_;
  ++summary_.scans_processed;
  summary_.last_status = StatusName(r.status);
  if (r.status == Status::kRejected) ++summary_.scans_rejected;
  if (r.status == Status::kInitializing) ++summary_.scans_initializing;
  if (r.status == Status::kReset) ++summary_.resets;
  if (r.status == Status::kDegenerate) ++summary_.degenerate;
  summary_.points_nonfinite += r.dropped_nan;
  summary_.points_bad_time += r.points_bad_time;
  summary_.lidar_overruled += r.overruled;
  summary_.consistency_searches += r.consistency_search != ConsistencySearch::kNone;
  summary_.relocalized += r.relocalized;
  CountImuInput(r);
  if (r.imu_gap_s > 0.0) {
    ++summary_.imu_gaps_bridged;
    summary_.imu_gap_max_s = std::max(summary_.imu_gap_max_s, r.imu_gap_s);
  }
  if (r.imu_lost) {
    if (!summary_.imu_fallback_active) ++summary_.imu_fallbacks;
    ++summary_.imu_fallback_scans;
  }
  if (r.lidar_only) ++summary_.lidar_only_scans;
  if (r.lio_started_late) ++summary_.lio_started_late;
  // Notices and rejected scans say nothing about the IMU: the episode lasts until a pose says.
  if (r.pose_valid) {
    summary_.imu_fallback_active = r.imu_lost;
    summary_.lidar_only_active = r.lidar_only;
  }
}

void NodeStats::CountNotice(const ScanResult& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (r.status == Status::kReset) ++summary_.resets;
  CountImuInput(r);
}

// The core reports its IMU input counts since the previous result on whichever result comes
// next, a notice included: each is summed once.
void NodeStats::CountImuInput(const ScanResult& r) {
  summary_.imu_conflicts += r.imu_conflicts;
  summary_.imu_conflicts_unresolved += r.imu_conflicts_unresolved;
  summary_.imu_gaps += r.imu_gaps;
  summary_.imu_gap_warn_max_s = std::max(summary_.imu_gap_warn_max_s, r.imu_gap_longest_s);
}

void NodeStats::SetCoreInputTotals(const InputStats& totals) {
  std::lock_guard<std::mutex> lock(mutex_);
  summary_.imu_clock_offset_dropped = totals.imu_clock_offset_dropped;
}

std::pair<uint64_t, uint64_t> NodeStats::Lost() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return {summary_.scans_lost, summary_.imu_lost};
}

void NodeStats::AddPublished(const ScanTiming& t) {
  const double latency = MsBetween(t.received, t.published);
  std::lock_guard<std::mutex> lock(mutex_);
  ++summary_.odometry_published;
  latency_ms_.Add(latency);
  core_time_ms_.Add(t.core_ms);
  imu_wait_ms_.Add(t.imu_wait_ms);
  decode_ms_.Add(t.decode_ms);
  queue_ms_.Add(t.queue_ms);
  behind_core_ms_.Add(t.behind_core_ms);
  publish_ms_.Add(MsBetween(t.publish_start, t.published));
  // Node overhead: everything between DDS receive and publish that is not the core working on
  // this scan, waiting for the core to finish earlier scans, or waiting for the IMU that covers
  // the scan end (the last two are reported apart).
  overhead_ms_.Add(latency - t.core_ms - t.imu_wait_ms - t.behind_core_ms);
}

void NodeStats::AddImuRatePublished(double latency_ms) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++summary_.odometry_imu_rate_published;
  imu_rate_latency_ms_.Add(latency_ms);
}

NodeSummary NodeStats::Snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  NodeSummary s = summary_;
  s.latency_p50_ms = latency_ms_.Percentile(50);
  s.latency_p99_ms = latency_ms_.Percentile(99);
  s.latency_max_ms = latency_ms_.Max();
  s.core_p50_ms = core_time_ms_.Percentile(50);
  s.core_p99_ms = core_time_ms_.Percentile(99);
  s.overhead_p50_ms = overhead_ms_.Percentile(50);
  s.overhead_p99_ms = overhead_ms_.Percentile(99);
  s.overhead_max_ms = overhead_ms_.Max();
  s.imu_wait_p50_ms = imu_wait_ms_.Percentile(50);
  s.imu_wait_p99_ms = imu_wait_ms_.Percentile(99);
  s.decode_p50_ms = decode_ms_.Percentile(50);
  s.decode_p99_ms = decode_ms_.Percentile(99);
  s.queue_p50_ms = queue_ms_.Percentile(50);
  s.queue_p99_ms = queue_ms_.Percentile(99);
  s.behind_core_p50_ms = behind_core_ms_.Percentile(50);
  s.behind_core_p99_ms = behind_core_ms_.Percentile(99);
  s.publish_p50_ms = publish_ms_.Percentile(50);
  s.publish_p99_ms = publish_ms_.Percentile(99);
  s.imu_rate_latency_p50_ms = imu_rate_latency_ms_.Percentile(50);
  s.imu_rate_latency_p99_ms = imu_rate_latency_ms_.Percentile(99);
  s.imu_rate_latency_max_ms = imu_rate_latency_ms_.Max();
  return s;
}

std::string NodeStats::PeriodicLine(size_t* latency_mark, const QueueFill& queues,
                                    const std::string& stalled) const {
  NodeSummary s;
  double lat50, lat99, ovh99, core_stall_s;
  size_t n;
  bool core_stalled;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    s = summary_;
    core_stalled = core_stalled_;
    core_stall_s = core_stall_s_;
    n = latency_ms_.count();
    lat50 = latency_ms_.PercentileSince(*latency_mark, 50);
    lat99 = latency_ms_.PercentileSince(*latency_mark, 99);
    ovh99 = overhead_ms_.PercentileSince(*latency_mark, 99);
  }
  std::ostringstream o;
  std::ostringstream stall;
  stall << std::fixed << std::setprecision(1) << "stalled (no scan processed for " << core_stall_s
        << " s while scans arrive)";
  o << std::fixed << std::setprecision(2) << "status="
    << (!stalled.empty() ? "stalled (no data on " + stalled + ")"
        : core_stalled   ? stall.str()
                         : (s.last_status.empty() ? "waiting" : s.last_status))
    << (s.imu_fallback_active ? " (IMU lost: LiDAR-only)" : "")
    << (s.lidar_only_active ? " (no IMU: LiDAR-only)" : "") << " scans rx=" << s.scans_received
    << " proc=" << s.scans_processed << " odom=" << s.odometry_published
    << " dropped=" << s.scans_dropped << " malformed=" << s.scans_malformed + s.imu_malformed
    << " imu rx=" << s.imu_received << " queues scan=" << queues.scans << "/"
    << queues.scan_capacity << " imu=" << queues.imus << " | last " << (n - *latency_mark)
    << " scans: latency p50=" << lat50 << " p99=" << lat99 << " ms, overhead p99=" << ovh99
    << " ms";
  *latency_mark = n;
  return o.str();
}

std::string NodeStats::FormatSummary(const NodeSummary& s) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(3) << "scans_received=" << s.scans_received
    << " scans_processed=" << s.scans_processed << " odometry_published=" << s.odometry_published
    << " scans_dropped=" << s.scans_dropped << " scans_malformed=" << s.scans_malformed
    << " scans_rejected=" << s.scans_rejected << " scans_initializing=" << s.scans_initializing
    << " resets=" << s.resets << " degenerate=" << s.degenerate
    << " imu_received=" << s.imu_received << " imu_malformed=" << s.imu_malformed
    << " imu_overflow=" << s.imu_overflow << " imu_out_of_order=" << s.imu_out_of_order
    << " time_jumps=" << s.time_jumps << " scans_late=" << s.scans_late
    << " imu_late=" << s.imu_late << " scans_lost=" << s.scans_lost << " imu_lost=" << s.imu_lost
    << " scans_empty=" << s.scans_empty << " scans_too_large=" << s.scans_too_large
    << " scans_bad_stamp=" << s.scans_bad_stamp << " points_nonfinite=" << s.points_nonfinite
    << " imu_duplicate=" << s.imu_duplicate << " imu_outliers=" << s.imu_outliers
    << " imu_gaps_bridged=" << s.imu_gaps_bridged << " imu_gap_max_s=" << s.imu_gap_max_s
    << " imu_fallbacks=" << s.imu_fallbacks << " imu_fallback_scans=" << s.imu_fallback_scans
    << " lidar_only_scans=" << s.lidar_only_scans << " lio_started_late=" << s.lio_started_late
    << " points_stalls=" << s.points_stalls << " imu_stalls=" << s.imu_stalls
    << " core_stalls=" << s.core_stalls << " scans_unusual=" << s.scans_unusual
    << " points_bad_time=" << s.points_bad_time << " imu_conflicts=" << s.imu_conflicts
    << " imu_conflicts_unresolved=" << s.imu_conflicts_unresolved << " imu_gaps=" << s.imu_gaps
    << " imu_gap_warn_max_s=" << s.imu_gap_warn_max_s
    << " imu_clock_offset_dropped=" << s.imu_clock_offset_dropped
    << " lidar_overruled=" << s.lidar_overruled
    << " consistency_searches=" << s.consistency_searches << " relocalized=" << s.relocalized
    << " latency_p50_ms=" << s.latency_p50_ms << " latency_p99_ms=" << s.latency_p99_ms
    << " latency_max_ms=" << s.latency_max_ms << " core_p50_ms=" << s.core_p50_ms
    << " core_p99_ms=" << s.core_p99_ms << " overhead_p50_ms=" << s.overhead_p50_ms
    << " overhead_p99_ms=" << s.overhead_p99_ms << " overhead_max_ms=" << s.overhead_max_ms
    << " imu_wait_p50_ms=" << s.imu_wait_p50_ms << " imu_wait_p99_ms=" << s.imu_wait_p99_ms
    << " decode_p50_ms=" << s.decode_p50_ms << " decode_p99_ms=" << s.decode_p99_ms
    << " queue_p50_ms=" << s.queue_p50_ms << " queue_p99_ms=" << s.queue_p99_ms
    << " behind_core_p50_ms=" << s.behind_core_p50_ms
    << " behind_core_p99_ms=" << s.behind_core_p99_ms << " publish_p50_ms=" << s.publish_p50_ms
    << " publish_p99_ms=" << s.publish_p99_ms
    << " odometry_imu_rate_published=" << s.odometry_imu_rate_published
    << " imu_rate_latency_p50_ms=" << s.imu_rate_latency_p50_ms
    << " imu_rate_latency_p99_ms=" << s.imu_rate_latency_p99_ms
    << " imu_rate_latency_max_ms=" << s.imu_rate_latency_max_ms
    << " last_status=" << (s.last_status.empty() ? "none" : s.last_status);
  return o.str();
}

}  // namespace ppf::dds
