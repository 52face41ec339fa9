#include "core_executor.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <optional>
#include <sstream>
#include <utility>

#include "ppf_bridge/convert.hpp"
#include "ppf_core/config.hpp"

namespace ppf::dds {

using Clock = std::chrono::steady_clock;

namespace {

double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Time jumps back (a bag replayed in a loop, a clock reset) restart the core once, cleanly:
// scans of the old timeline still in the core are flushed first, then both streams start over
// together. (Left to the core, the IMU jump and the scan jump would each reset it, and the
// second reset would throw away the initialization the first one had begun.) A sample only
// slightly older than what the core already has (< 0.5 s, e.g. from a second publisher) is
// dropped, counted and logged instead of resetting the filter.
constexpr double kJumpS = 0.5;

// An IMU stamp more than kJumpS off the stream (back or ahead) is only believed once the next
// kConfirmSamples samples continue from it: a bag loop or a clock reset restarts the core, a
// real gap reaches the core (which resets on gaps > imu.max_gap), and a single bad stamp is
// dropped instead of throwing away the filter and its map.
constexpr size_t kConfirmSamples = 5;

// A scan far ahead of the IMU stream that does not continue the scan stream either has a broken
// stamp: it would make every later scan look late. (Scans that continue their stream while the
// IMU is silent are the core's IMU loss fallback to handle.)
constexpr double kScanAheadS = 5.0;

}  // namespace

std::unique_ptr<LioPpf> CoreExecutor::CreateCore(const NodeConfig& c, std::string* error) {
  Config core_config;
  for (const std::string& file : {c.core_config_file, c.core_calibration_file}) {
    if (file.empty()) continue;
    ConfigLoadReport rep = LoadConfigYaml(file, &core_config);
    for (const auto& w : rep.warnings) Log(Level::kWarn, "core config " + file + ": " + w);
    if (!rep.ok) {
      *error = "core config '" + file + "': " + rep.error;
      return nullptr;
    }
  }
  if (c.core_mode == "knn") core_config.mode = Mode::kKnn;
  if (c.core_mode == "ppf") core_config.mode = Mode::kPpf;
  // The map (outputs.map_file) is made of the same points: one copy of the scan's downsampled
  // points per result, small beside registering them.
  core_config.output_deskewed_points = c.publish_registered_points || !c.map_file.empty();
  // Everything else, imu.mode among it, comes from the core config files read above and is
  // applied by the core itself (lio_ppf.hpp); the node overrides only the mode and the output of
  // de-skewed points, and routes the core's log lines into its own log below.
  core_config.log = [](LogLevel level, const std::string& msg) {
    const Level l = level == LogLevel::kError  ? Level::kError
                    : level == LogLevel::kWarn ? Level::kWarn
                    : level == LogLevel::kInfo ? Level::kInfo
                                               : Level::kDebug;
    if (l != Level::kDebug) Log(l, "core: " + msg);
  };
  // kPpf: the facade installs the skeleton tracker itself (Config::ppf from the `ppf:` section).
  return std::make_unique<LioPpf>(core_config);
}

CoreExecutor::CoreExecutor(const NodeConfig& c, std::unique_ptr<LioPpf> core, NodeInputs* inputs,
                           NodeOutputs* outputs, NodeMap* map, NodeStats* stats)
    : config_(c),
      core_(std::move(core)),
      scan_queue_(inputs->scans()),
      imu_queue_(inputs->imus()),
      outputs_(*outputs),
      map_(*map),
      stats_(*stats),
      ahead_log_(c.malformed_log_interval_s),
      late_log_(c.malformed_log_interval_s),
      imu_late_log_(c.malformed_log_interval_s),
      imu_dup_log_(c.malformed_log_interval_s),
      outlier_log_(c.malformed_log_interval_s),
      nonfinite_log_(c.malformed_log_interval_s) {}

void CoreExecutor::RequestDrain() {
  drain_requested_ = true;
  scan_queue_.Notify();
}

void CoreExecutor::FlushLogs() {
  for (RateLimitedLog* l : {&ahead_log_, &late_log_, &imu_late_log_, &imu_dup_log_, &outlier_log_,
                            &nonfinite_log_, &status_log_}) {
    l->Flush();
  }
}

void CoreExecutor::Run() {
  uint64_t seen = 0;
  std::deque<std::pair<double, ImuItem>> imus;  // taken from the queue, not yet fed
  // Feeds the IMU samples queued up to `until`. The core sees both streams in the order they
  // arrived, however long it worked on the scans before: it judges an IMU clock offset by the
  // newest sample that arrived before a scan (LioPpf, docs/reliability.md), and a backlog fed
  // all at once would make that sample newer than the scan's arrival. Returns whether any was.
  auto feed_imu_until = [&](Clock::time_point until) {
    imu_queue_.PopAll(&imus);
    bool fed = false;
    while (!imus.empty() && imus.front().second.queued <= until) {
      FeedImu(imus.front().second.sample);
      imus.pop_front();
      fed = true;
    }
    return fed;
  };
  while (true) {
    const bool draining = drain_requested_.load();
    if (!draining) scan_queue_.WaitForChange(&seen, std::chrono::milliseconds(50));
    while (true) {
      const Clock::time_point looked = Clock::now();
      auto scan = scan_queue_.PopFront();
      if (!scan) {
        // The IMU that arrived after the last scan: it may cover the scans still pending. What
        // arrives from now on waits for the scans queued with it.
        if (feed_imu_until(looked) && !pending_.empty()) RunCore(false);
        break;
      }
      // The IMU that arrived before the scan first: a scan is processed once IMU covers its end.
      feed_imu_until(scan->second.queued);
      if (AcceptScanStamp(scan->first)) {
        AddScan(std::move(scan->second));
        // The IMU that arrived after it, up to the next scan, may cover it: no wait for the next
        // wake-up when the core is behind.
        const auto next = scan_queue_.PeekFront();
        feed_imu_until(next ? next->second.queued : Clock::now());
        RunCore(false);
      }
    }
    if (draining && scan_queue_.Size() == 0 && imu_queue_.Size() == 0 && imus.empty()) {
      DropImuCandidates();                   // the stream ended before confirming them
      if (!pending_.empty()) RunCore(true);  // remaining scans, IMU extrapolated
      stats_.SetCoreInputTotals(core_->input_stats());  // IMU fed after the last Process
      break;
    }
  }
}

void CoreExecutor::RestartCore(const std::string& why) {
  if (!pending_.empty()) RunCore(true);
  core_->Reset();
  if (imu_rate_) imu_rate_->OnCoreRestart();
  last_imu_fed_ = last_scan_fed_ = -std::numeric_limits<double>::infinity();
  stats_.Add(&NodeSummary::resets);
  // Not rate limited: restarts are rare and each one matters.
  Log(Level::kWarn, why + ": core restarted (initialization starts over)");
}

void CoreExecutor::FeedImu(const ImuSample& s) {
  const bool have = std::isfinite(last_imu_fed_);
  const bool back = have && s.stamp_s < last_imu_fed_ - kJumpS;
  const bool ahead = have && s.stamp_s > last_imu_fed_ + kJumpS;
  if (back || ahead) {
    if (!imu_candidates_.empty() && !(s.stamp_s > imu_candidates_.back().stamp_s &&
                                      s.stamp_s <= imu_candidates_.back().stamp_s + kJumpS)) {
      DropImuCandidates();
    }
    imu_candidates_.push_back(s);
    if (imu_candidates_.size() < kConfirmSamples) return;
    std::vector<ImuSample> confirmed;
    confirmed.swap(imu_candidates_);
    const double first = confirmed.front().stamp_s;
    if (back) {
      // Scans of the old timeline still queued (they arrived with the samples confirming the jump)
      // are finished first.
      while (auto old =
                 scan_queue_.PopFrontIf([&](double stamp) { return stamp > first + kJumpS; })) {
        if (AcceptScanStamp(old->first)) AddScan(std::move(old->second));
      }
      RestartCore("IMU time jumped back by " + std::to_string(last_imu_fed_ - first) + " s");
    } else {
      Log(Level::kWarn, "IMU stream resumed after " + std::to_string(first - last_imu_fed_) +
                            " s without samples (last at " + std::to_string(last_imu_fed_) + ")");
    }
    for (const ImuSample& c : confirmed) AddImuToCore(c);
    return;
  }
  // The stream went on where it was: what waited for confirmation was an outlier.
  if (!imu_candidates_.empty()) DropImuCandidates();
  // The same stamp again with other values is a conflict: the core decides which copy fits the
  // samples on either side (arrival order says nothing), so it gets them all. An exact copy
  // (a redelivery) is dropped here.
  if (have && s.stamp_s == last_imu_fed_ &&
      (s.angular_velocity != last_imu_.angular_velocity ||
       s.linear_acceleration != last_imu_.linear_acceleration)) {
    AddImuToCore(s);
    return;
  }
  if (have && s.stamp_s == last_imu_fed_) {
    stats_.Add(&NodeSummary::imu_duplicate);
    imu_dup_log_.Log(Level::kError, "IMU sample at " + std::to_string(s.stamp_s) +
                                        " has the stamp of the sample before it (duplicate): "
                                        "dropped");
    return;
  }
  if (have && s.stamp_s < last_imu_fed_) {
    stats_.Add(&NodeSummary::imu_late);
    imu_late_log_.Log(Level::kError, "IMU sample at " + std::to_string(s.stamp_s) +
                                         " arrived after newer ones were integrated: dropped");
    return;
  }
  AddImuToCore(s);
}

void CoreExecutor::AddImuToCore(const ImuSample& s) {
  core_->AddImu(s);
  last_imu_fed_ = s.stamp_s;
  last_imu_ = s;
}

void CoreExecutor::DropImuCandidates() {
  if (imu_candidates_.empty()) return;
  const size_t n = imu_candidates_.size();
  const double off = imu_candidates_.front().stamp_s - last_imu_fed_;
  stats_.Add(&NodeSummary::imu_outliers, n);
  outlier_log_.Log(Level::kError, "dropped " + std::to_string(n) + " IMU sample(s) stamped " +
                                      std::to_string(imu_candidates_.front().stamp_s) + ", " +
                                      std::to_string(std::abs(off)) + " s " +
                                      (off < 0 ? "behind" : "ahead of") +
                                      " the stream, which went on at " +
                                      std::to_string(last_imu_fed_) + ": outlier stamp");
  imu_candidates_.clear();
}

// Scans are fed in time order, each newer than the last. A scan older than that is dropped,
// however far back: only the IMU stream jumping back too (FeedImu) restarts the core, so a
// single stale or misstamped scan cannot reset a moving robot's filter.
bool CoreExecutor::AcceptScanStamp(double stamp) {
  const bool have_imu = std::isfinite(last_imu_fed_);
  const bool continues_scans = std::isfinite(last_scan_fed_) && stamp <= last_scan_fed_ + kScanAheadS;
  if (have_imu && stamp > last_imu_fed_ + kScanAheadS && !continues_scans) {
    stats_.Add(&NodeSummary::scans_bad_stamp);
    ahead_log_.Log(Level::kWarn, "scan at " + std::to_string(stamp) + " is " +
                                     std::to_string(stamp - last_imu_fed_) +
                                     " s ahead of the IMU stream (far-future stamp, not "
                                     "continuing the scans either): skipped");
    return false;
  }
  if (stamp <= last_scan_fed_) {
    stats_.Add(&NodeSummary::scans_late);
    late_log_.Log(Level::kWarn, "scan at " + std::to_string(stamp) + " is " +
                                    std::to_string(last_scan_fed_ - stamp) +
                                    " s older than the last processed one: dropped");
    return false;
  }
  // Before the first IMU sample the core only collects (initializing): such a scan does not
  // set the order, so a misstamped one cannot make the following scans late.
  if (have_imu) last_scan_fed_ = stamp;
  return true;
}

void CoreExecutor::AddScan(ScanItem item) {
  const Clock::time_point t0 = Clock::now();
  std::optional<CloudView> view = bridge::ToCloudView(*item.msg);
  PendingScan p;
  p.id = core_->AddScan(*view);  // the listener checked the view; the core copies what it needs
  p.received = item.received;
  p.decode_ms = MsBetween(item.received, item.queued);
  p.queue_ms = MsBetween(item.queued, t0);
  // Core time completed while this scan waited (a call already running when it was queued
  // counts whole, hence the min).
  p.behind_core_ms = std::min(
      p.queue_ms, 1e-6 * static_cast<double>(stats_.core_busy_ns() - item.core_busy_ns_at_queue));
  p.added = Clock::now();
  p.add_scan_ms = MsBetween(t0, p.added);
  stats_.AddCoreBusy(p.added - t0);
  pending_.push_back(std::move(p));
}

void CoreExecutor::RunCore(bool flush) {
  const Clock::time_point t0 = Clock::now();
  std::vector<ScanResult> results = core_->Process(flush);
  const Clock::time_point t1 = Clock::now();
  stats_.SetCoreInputTotals(core_->input_stats());
  const double process_ms = MsBetween(t0, t1);
  stats_.AddCoreBusy(t1 - t0);
  // Core time of a result: its AddScan plus its share of the Process call (by the core's own
  // per-scan timings when one call returns several scans).
  double total = 0.0;
  size_t scans = 0;
  for (const ScanResult& r : results) {
    total += r.timings.total;
    scans += r.input_id != 0;
  }
  for (const ScanResult& r : results) {
    if (r.input_id == 0) {
      ReportNotice(r);
      continue;
    }
    // The core returns every scan's result once, in input order: entries older than this one
    // were never answered, which would be a core bug worth a loud line rather than a mismatch.
    while (!pending_.empty() && pending_.front().id < r.input_id) {
      Log(Level::kError, "core returned no result for input " +
                             std::to_string(pending_.front().id) + " (internal error)");
      pending_.pop_front();
    }
    if (pending_.empty() || pending_.front().id != r.input_id) {
      Log(Level::kError, "core result for unknown input " + std::to_string(r.input_id) +
                             " (internal error): not published");
      continue;
    }
    PendingScan p = std::move(pending_.front());
    pending_.pop_front();
    const double share = scans == 1   ? 1.0
                         : total > 0.0 ? r.timings.total / total
                                       : 1.0 / static_cast<double>(scans);
    // A scan whose IMU coverage was incomplete waited in the core until this call.
    const double imu_wait_ms = std::max(0.0, MsBetween(p.added, t0));
    Publish(r, p, p.add_scan_ms + share * process_ms, imu_wait_ms);
  }
}

// A result that belongs to no scan: the core reset itself (IMU time went back). An IMU gap too
// long to bridge gives no reset: the core registers the scans LiDAR-only and LIO re-anchors.
void CoreExecutor::ReportNotice(const ScanResult& r) {
  stats_.CountNotice(r);
  if (imu_rate_) imu_rate_->OnResult(r);
  if (r.status == Status::kReset) {
    status_log_.Log(Level::kWarn, std::string("core: ") + StatusName(r.status) + ": " + r.reason);
  }
}

void CoreExecutor::Publish(const ScanResult& r, const PendingScan& p, double core_ms,
                           double imu_wait_ms) {
  ScanTiming t;
  t.publish_start = Clock::now();
  stats_.CountResult(r);
  if (r.dropped_nan > 0) {
    nonfinite_log_.Log(Level::kWarn, "scan at " + std::to_string(r.scan_begin_s) + ": " +
                                         std::to_string(r.dropped_nan) + " of " +
                                         std::to_string(r.input_points) +
                                         " points non-finite (NaN/Inf), dropped");
  }
  if (r.imu_gap_s > 0.0) {
    // Not rate limited: a gap is rare and the operator wants its size and what it cost.
    const auto [scans_lost, imu_lost] = stats_.Lost();
    std::ostringstream os;
    os << std::fixed << std::setprecision(3) << "input gap: no IMU for " << r.imu_gap_s
       << " s before the scan at " << r.stamp_s << "; bridged"
       << (r.lio_resumed ? " (LiDAR-only meanwhile, LIO resumed)" : "")
       << ", odometry continues (lost so far: "
       << scans_lost << " scans, " << imu_lost << " IMU samples)";
    Log(Level::kWarn, os.str());
  }
  if (r.status == Status::kRejected || r.status == Status::kReset) {
    status_log_.Log(Level::kWarn, std::string("core: ") + StatusName(r.status) + ": " + r.reason);
  }
  if (!r.pose_valid) {
    if (imu_rate_) imu_rate_->OnResult(r);  // a reset ends the IMU-rate odometry
    return;
  }
  outputs_.Publish(r);
  t.published = Clock::now();
  if (imu_rate_) imu_rate_->OnResult(r);  // after /odometry, which it never delays
  map_.Add(r);  // after the odometry is out: the map never delays it
  t.received = p.received;
  t.core_ms = core_ms;
  t.imu_wait_ms = imu_wait_ms;
  t.decode_ms = p.decode_ms;
  t.queue_ms = p.queue_ms;
  t.behind_core_ms = p.behind_core_ms;
  stats_.AddPublished(t);
}

}  // namespace ppf::dds
