#include "ppf_dds_node/ppf_node.hpp"

#include <cmath>
#include <condition_variable>
#include <deque>
#include <limits>
#include <mutex>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "node_inputs.hpp"
#include "node_outputs.hpp"
#include "node_stats.hpp"
#include "ppf_bridge/convert.hpp"
#include "ppf_bridge/msg_traits.hpp"
#include "ppf_core/config_yaml.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_dds_node/logging.hpp"

namespace ppf::dds {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;

namespace {

double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Per scan handed to the core, in AddScan order (the core returns results in input order).
struct PendingScan {
  Clock::time_point received;
  Clock::time_point added;      // AddScan returned
  double decode_ms = 0.0;       // listener: take + CDR decode + checks
  double queue_ms = 0.0;        // waiting in the scan queue for the executor
  double behind_core_ms = 0.0;  // part of queue_ms during which the executor ran the core
  double add_scan_ms = 0.0;
  std::shared_ptr<sensor_msgs::msg::PointCloud2> msg;  // kept only for /registered_points
};

}  // namespace

struct PpfNode::Impl {
  explicit Impl(const NodeConfig& c)
      : config(c),
        inputs(c, &stats),
        ahead_log(c.malformed_log_interval_s),
        nonfinite_log(c.malformed_log_interval_s),
        late_log(c.malformed_log_interval_s),
        imu_late_log(c.malformed_log_interval_s),
        imu_dup_log(c.malformed_log_interval_s),
        outlier_log(c.malformed_log_interval_s) {}

  // ---- executor thread ------------------------------------------------------------------------
  void ExecutorLoop() {
    uint64_t seen = 0;
    while (true) {
      const bool draining = drain_requested.load();
      if (!draining) scan_queue().WaitForChange(&seen, std::chrono::milliseconds(50));
      // IMU first: a scan can only be processed once IMU covers its end.
      std::deque<std::pair<double, ImuSample>> imus;
      imu_queue().PopAll(&imus);
      for (auto& [stamp, sample] : imus) FeedImu(sample);
      if (!imus.empty() && !pending.empty()) RunCore(false);
      while (auto scan = scan_queue().PopFront()) {
        if (AcceptScanStamp(scan->first)) {
          AddScan(std::move(scan->second));
          RunCore(false);
        }
        // IMU that arrived while the core worked: feed it before the next scan.
        imus.clear();
        imu_queue().PopAll(&imus);
        for (auto& [stamp, sample] : imus) FeedImu(sample);
      }
      if (draining && scan_queue().Size() == 0 && imu_queue().Size() == 0) {
        DropImuCandidates();                  // the stream ended before confirming them
        if (!pending.empty()) RunCore(true);  // remaining scans, IMU extrapolated
        break;
      }
    }
  }

  // Time jumps back (a bag replayed in a loop, a clock reset) restart the core once, cleanly:
  // scans of the old timeline still in the core are flushed first, then both streams start over
  // together. (Left to the core, the IMU jump and the scan jump would each reset it, and the
  // second reset would throw away the initialization the first one had begun.) A sample only
  // slightly older than what the core already has (< 0.5 s, e.g. from a second publisher) is
  // dropped, counted and logged instead of resetting the filter.
  static constexpr double kJumpS = 0.5;

  void RestartCore(const std::string& why) {
    if (!pending.empty()) RunCore(true);
    core->Reset();
    last_imu_fed = last_scan_fed = -std::numeric_limits<double>::infinity();
    stats.Add(&NodeSummary::resets);
    // Not rate limited: restarts are rare and each one matters.
    Log(Level::kWarn, why + ": core restarted (initialization starts over)");
  }

  // An IMU stamp more than kJumpS off the stream (back or ahead) is only believed once the next
  // kConfirmSamples samples continue from it: a bag loop or a clock reset restarts the core, a
  // real gap reaches the core (which resets on gaps > max_imu_gap), and a single bad stamp is
  // dropped instead of throwing away the filter and its map.
  static constexpr size_t kConfirmSamples = 5;

  void FeedImu(const ImuSample& s) {
    const bool have = std::isfinite(last_imu_fed);
    const bool back = have && s.stamp_s < last_imu_fed - kJumpS;
    const bool ahead = have && s.stamp_s > last_imu_fed + kJumpS;
    if (back || ahead) {
      if (!imu_candidates.empty() && !(s.stamp_s > imu_candidates.back().stamp_s &&
                                       s.stamp_s <= imu_candidates.back().stamp_s + kJumpS)) {
        DropImuCandidates();
      }
      imu_candidates.push_back(s);
      if (imu_candidates.size() < kConfirmSamples) return;
      std::vector<ImuSample> confirmed;
      confirmed.swap(imu_candidates);
      const double first = confirmed.front().stamp_s;
      if (back) {
        // Scans of the old timeline still queued (IMU is fed before scans) are finished first.
        while (auto old =
                   scan_queue().PopFrontIf([&](double stamp) { return stamp > first + kJumpS; })) {
          if (AcceptScanStamp(old->first)) AddScan(std::move(old->second));
        }
        RestartCore("IMU time jumped back by " + std::to_string(last_imu_fed - first) + " s");
      } else {
        Log(Level::kWarn, "IMU stream resumed after " + std::to_string(first - last_imu_fed) +
                              " s without samples (last at " + std::to_string(last_imu_fed) + ")");
      }
      for (const ImuSample& c : confirmed) AddImuToCore(c);
      return;
    }
    // The stream went on where it was: what waited for confirmation was an outlier.
    if (!imu_candidates.empty()) DropImuCandidates();
    if (have && s.stamp_s == last_imu_fed) {
      stats.Add(&NodeSummary::imu_duplicate);
      imu_dup_log.Log(Level::kError, "IMU sample at " + std::to_string(s.stamp_s) +
                                         " has the stamp of the sample before it (duplicate): "
                                         "dropped");
      return;
    }
    if (have && s.stamp_s < last_imu_fed) {
      stats.Add(&NodeSummary::imu_late);
      imu_late_log.Log(Level::kError, "IMU sample at " + std::to_string(s.stamp_s) +
                                          " arrived after newer ones were integrated: dropped");
      return;
    }
    AddImuToCore(s);
  }

  void AddImuToCore(const ImuSample& s) {
    core->AddImu(s);
    last_imu_fed = s.stamp_s;
    last_gyro = s.angular_velocity;
  }

  void DropImuCandidates() {
    if (imu_candidates.empty()) return;
    const size_t n = imu_candidates.size();
    const double off = imu_candidates.front().stamp_s - last_imu_fed;
    stats.Add(&NodeSummary::imu_outliers, n);
    outlier_log.Log(Level::kError, "dropped " + std::to_string(n) + " IMU sample(s) stamped " +
                                       std::to_string(imu_candidates.front().stamp_s) + ", " +
                                       std::to_string(std::abs(off)) + " s " +
                                       (off < 0 ? "behind" : "ahead of") +
                                       " the stream, which went on at " +
                                       std::to_string(last_imu_fed) + ": outlier stamp");
    imu_candidates.clear();
  }

  // Scans are fed in time order, each newer than the last. A scan older than that is dropped,
  // however far back: only the IMU stream jumping back too (FeedImu) restarts the core, so a
  // single stale or misstamped scan cannot reset a moving robot's filter. A scan far ahead of
  // the IMU stream has a broken stamp (or the IMU fell silent): it would make every later scan
  // look late.
  static constexpr double kScanAheadS = 5.0;

  bool AcceptScanStamp(double stamp) {
    const bool have_imu = std::isfinite(last_imu_fed);
    if (have_imu && stamp > last_imu_fed + kScanAheadS) {
      stats.Add(&NodeSummary::scans_bad_stamp);
      ahead_log.Log(Level::kWarn, "scan at " + std::to_string(stamp) + " is " +
                                      std::to_string(stamp - last_imu_fed) +
                                      " s ahead of the IMU stream (far-future stamp, or the IMU "
                                      "fell silent): skipped");
      return false;
    }
    if (stamp <= last_scan_fed) {
      stats.Add(&NodeSummary::scans_late);
      late_log.Log(Level::kWarn, "scan at " + std::to_string(stamp) + " is " +
                                     std::to_string(last_scan_fed - stamp) +
                                     " s older than the last processed one: dropped");
      return false;
    }
    // Before the first IMU sample the core only collects (initializing): such a scan does not
    // set the order, so a misstamped one cannot make the following scans late.
    if (have_imu) last_scan_fed = stamp;
    return true;
  }

  void AddScan(ScanItem item) {
    const Clock::time_point t0 = Clock::now();
    std::optional<CloudView> view = bridge::ToCloudView(*item.msg);
    core->AddScan(*view);  // listener checked the view; the core copies what it needs
    PendingScan p;
    p.received = item.received;
    p.decode_ms = MsBetween(item.received, item.queued);
    p.queue_ms = MsBetween(item.queued, t0);
    // Core time completed while this scan waited (a call already running when it was queued
    // counts whole, hence the min).
    p.behind_core_ms = std::min(
        p.queue_ms, 1e-6 * static_cast<double>(stats.core_busy_ns() - item.core_busy_ns_at_queue));
    p.added = Clock::now();
    p.add_scan_ms = MsBetween(t0, p.added);
    stats.AddCoreBusy(p.added - t0);
    if (config.publish_registered_points) p.msg = std::move(item.msg);
    pending.push_back(std::move(p));
  }

  void RunCore(bool flush) {
    const Clock::time_point t0 = Clock::now();
    std::vector<ScanResult> results = core->Process(flush);
    const Clock::time_point t1 = Clock::now();
    const double process_ms = MsBetween(t0, t1);
    stats.AddCoreBusy(t1 - t0);
    // Core time of a result: its AddScan plus its share of the Process call (by the core's own
    // per-scan timings when one call returns several scans).
    double total = 0.0;
    for (const ScanResult& r : results) total += r.timings.total;
    for (const ScanResult& r : results) {
      if (pending.empty()) break;  // cannot happen: one result per AddScan
      PendingScan p = std::move(pending.front());
      pending.pop_front();
      const double share = results.size() == 1 ? 1.0
                           : total > 0.0       ? r.timings.total / total
                                               : 1.0 / static_cast<double>(results.size());
      // A scan whose IMU coverage was incomplete waited in the core until this call.
      const double imu_wait_ms = std::max(0.0, MsBetween(p.added, t0));
      Publish(r, p, p.add_scan_ms + share * process_ms, imu_wait_ms);
    }
  }

  void Publish(const ScanResult& r, const PendingScan& p, double core_ms, double imu_wait_ms) {
    ScanTiming t;
    t.publish_start = Clock::now();
    stats.CountResult(r);
    if (r.dropped_nan > 0) {
      nonfinite_log.Log(Level::kWarn, "scan at " + std::to_string(r.scan_begin_s) + ": " +
                                          std::to_string(r.dropped_nan) + " of " +
                                          std::to_string(r.input_points) +
                                          " points non-finite (NaN/Inf), dropped");
    }
    if (r.status == Status::kRejected || r.status == Status::kReset) {
      status_log.Log(Level::kWarn, std::string("core: ") + StatusName(r.status) + ": " + r.reason);
    }
    if (!r.pose_valid) return;
    outputs.Publish(r, last_gyro - r.gyro_bias, p.msg.get());
    t.published = Clock::now();
    t.received = p.received;
    t.core_ms = core_ms;
    t.imu_wait_ms = imu_wait_ms;
    t.decode_ms = p.decode_ms;
    t.queue_ms = p.queue_ms;
    t.behind_core_ms = p.behind_core_ms;
    stats.AddPublished(t);
  }

  void FlushInputLogs() {
    inputs.FlushLogs();
    for (RateLimitedLog* l : {&ahead_log, &nonfinite_log, &status_log, &late_log, &imu_late_log,
                              &imu_dup_log, &outlier_log}) {
      l->Flush();
    }
  }

  void LogPeriodic(size_t* latency_mark) {
    FlushInputLogs();
    Log(Level::kInfo, stats.PeriodicLine(latency_mark, inputs.Fill()));
  }

  NodeConfig config;
  NodeStats stats;
  NodeInputs inputs;
  NodeOutputs outputs{config};
  std::unique_ptr<LioPpf> core;

  fdds::DomainParticipant* participant = nullptr;
  fdds::Publisher* publisher = nullptr;
  fdds::Subscriber* subscriber = nullptr;
  ScanQueue& scan_queue() { return inputs.scans(); }
  ImuQueue& imu_queue() { return inputs.imus(); }
  std::atomic<bool> drain_requested{false};
  std::atomic<bool> stop_requested{false};
  std::mutex stop_mutex;
  std::condition_variable stop_cv;

  // Executor-thread state.
  double last_imu_fed = -std::numeric_limits<double>::infinity();
  double last_scan_fed = -std::numeric_limits<double>::infinity();
  std::vector<ImuSample> imu_candidates;  // off the timeline, waiting for confirmation
  std::deque<PendingScan> pending;
  Eigen::Vector3d last_gyro = Eigen::Vector3d::Zero();

  // One limiter per kind of defect, so that one kind's burst does not hide another's line.
  RateLimitedLog ahead_log, nonfinite_log, late_log, imu_late_log, imu_dup_log, outlier_log;
  RateLimitedLog status_log{1.0};
  bool torn_down = false;

  void TearDown() {
    if (torn_down) return;
    torn_down = true;
    if (participant) {
      participant->delete_contained_entities();
      fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
      participant = nullptr;
    }
  }
};

PpfNode::PpfNode(const NodeConfig& config) : impl_(std::make_unique<Impl>(config)) {}

PpfNode::~PpfNode() { impl_->TearDown(); }

bool PpfNode::init(std::string* error) {
  Impl& m = *impl_;
  const NodeConfig& c = m.config;

  // Core first: a bad core config must fail before we appear on the network.
  Config core_config;
  for (const std::string& file : {c.core_config_file, c.core_calibration_file}) {
    if (file.empty()) continue;
    ConfigLoadReport rep = LoadConfigYaml(file, &core_config);
    for (const auto& w : rep.warnings) Log(Level::kWarn, "core config " + file + ": " + w);
    if (!rep.ok) {
      *error = "core config '" + file + "': " + rep.error;
      return false;
    }
  }
  if (c.core_mode == "knn") core_config.mode = Mode::kKnn;
  if (c.core_mode == "ppf") core_config.mode = Mode::kPpf;
  for (const auto& note : ValidateConfig(&core_config)) Log(Level::kWarn, "core config: " + note);
  core_config.log = [](LogLevel level, const std::string& msg) {
    const Level l = level == LogLevel::kError  ? Level::kError
                    : level == LogLevel::kWarn ? Level::kWarn
                    : level == LogLevel::kInfo ? Level::kInfo
                                               : Level::kDebug;
    if (l != Level::kDebug) Log(l, "core: " + msg);
  };
  m.core = std::make_unique<LioPpf>(core_config);
  // kPpf: the facade installs the skeleton tracker itself (Config::ppf from the `ppf:` section).

  m.participant = CreateParticipant(c.participant, error);
  if (!m.participant) return false;

  m.publisher = m.participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  m.subscriber = m.participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (!m.publisher || !m.subscriber) {
    *error = "cannot create publisher/subscriber";
    return false;
  }

  if (!m.outputs.Create(m.participant, m.publisher, m.inputs.cloud_type(), error)) return false;

  // Readers last: data may flow as soon as they exist.
  if (!m.inputs.Create(m.participant, m.subscriber, error)) return false;
  Log(Level::kInfo,
      "ppf_node up: domain " + std::to_string(c.participant.domain_id) + ", in " +
          RosTopicToDds(c.points_topic) + " + " + RosTopicToDds(c.imu_topic) + " (" +
          (c.sensor_reliability == Reliability::kBestEffort ? "best effort" : "reliable") +
          "), out " + RosTopicToDds(c.odometry_topic) + " [" + c.odom_frame + " -> " +
          c.base_frame + "]");
  return true;
}

void PpfNode::run() {
  Impl& m = *impl_;
  std::thread executor([&m] { m.ExecutorLoop(); });
  size_t latency_mark = 0;
  auto next_log = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(m.config.diagnostics_period_s));
  {
    std::unique_lock<std::mutex> lock(m.stop_mutex);
    while (!m.stop_requested.load()) {
      m.stop_cv.wait_until(lock, next_log, [&m] { return m.stop_requested.load(); });
      if (m.stop_requested.load()) break;
      if (Clock::now() >= next_log) {
        lock.unlock();
        m.LogPeriodic(&latency_mark);
        lock.lock();
        next_log += std::chrono::duration_cast<Clock::duration>(
            std::chrono::duration<double>(m.config.diagnostics_period_s));
      }
    }
  }
  // Drain: stop accepting, process what is queued, flush the core.
  m.inputs.StopAccepting();
  m.drain_requested = true;
  m.scan_queue().Notify();
  executor.join();
  m.FlushInputLogs();  // the counts of bursts no later line reported
  if (!m.config.tum_file.empty()) {
    std::string error;
    if (m.outputs.WriteTum(&error)) {
      Log(Level::kInfo, "trajectory: " + std::to_string(m.outputs.trajectory_size()) +
                            " poses -> " + m.config.tum_file);
    } else {
      Log(Level::kError, error);
    }
  }
  // Give reliable readers a moment to receive the last outputs before the writers go away.
  m.outputs.WaitForAcknowledgments();
  m.TearDown();
}

void PpfNode::stop() {
  {
    std::lock_guard<std::mutex> lock(impl_->stop_mutex);
    impl_->stop_requested = true;
  }
  impl_->stop_cv.notify_all();
}

NodeSummary PpfNode::summary() const { return impl_->stats.Snapshot(); }

std::string PpfNode::FormatSummary(const NodeSummary& s) { return NodeStats::FormatSummary(s); }

}  // namespace ppf::dds
