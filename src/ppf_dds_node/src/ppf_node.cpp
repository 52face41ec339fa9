#include "ppf_dds_node/ppf_node.hpp"

#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "ppf_bridge/cdr.hpp"
#include "ppf_bridge/convert.hpp"
#include "ppf_bridge/msg_traits.hpp"
#include "ppf_bridge/odometry.hpp"
#include "ppf_bridge/skeleton_planes.hpp"
#include "ppf_core/config_yaml.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_dds_node/gap_counter.hpp"
#include "ppf_dds_node/latency_stats.hpp"
#include "ppf_dds_node/logging.hpp"
#include "ppf_dds_node/time_ordered_queue.hpp"
#include "ppf_dds_node/validating_type.hpp"

namespace ppf::dds {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;

namespace {

double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

struct ScanItem {
  std::shared_ptr<sensor_msgs::msg::PointCloud2> msg;
  Clock::time_point received;         // listener entry, before the sample is taken and decoded
  Clock::time_point queued;           // pushed into the scan queue
  int64_t core_busy_ns_at_queue = 0;  // Impl::core_busy_ns when queued
};

struct ImuItem {
  ImuSample sample;
};

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

template <typename MsgT>
fdds::DataWriter* CreateWriter(fdds::DomainParticipant* participant, fdds::Publisher* publisher,
                               fdds::TypeSupport* type, const std::string& ros_topic,
                               const fdds::DataWriterQos& qos, std::string* error) {
  // A name already registered with another type support would silently use that one's
  // (de)serializer on our samples: refuse instead.
  if (type->register_type(participant) != ReturnCode_t::RETCODE_OK) {
    *error = "type " + type->get_type_name() + " already registered differently";
    return nullptr;
  }
  fdds::Topic* topic = participant->create_topic(RosTopicToDds(ros_topic), type->get_type_name(),
                                                 fdds::TOPIC_QOS_DEFAULT);
  if (!topic) {
    *error = "cannot create topic " + RosTopicToDds(ros_topic);
    return nullptr;
  }
  fdds::DataWriter* w = publisher->create_datawriter(topic, qos);
  if (!w) *error = "cannot create writer on " + RosTopicToDds(ros_topic);
  return w;
}

}  // namespace

struct PpfNode::Impl {
  // Cloud buffers are recycled: a fresh multi-MB vector per scan costs page faults and a memset
  // in the listener (measured: the bulk of its p99). Declared first so that it outlives every
  // queue and pending scan holding a pooled message.
  std::mutex pool_mutex;
  std::vector<std::unique_ptr<sensor_msgs::msg::PointCloud2>> pool;
  static constexpr size_t kPoolMax = 8;

  std::unique_ptr<sensor_msgs::msg::PointCloud2> TakeFromPool() {
    std::lock_guard<std::mutex> lock(pool_mutex);
    if (pool.empty()) return std::make_unique<sensor_msgs::msg::PointCloud2>();
    auto m = std::move(pool.back());
    pool.pop_back();
    return m;
  }
  void ReturnToPool(sensor_msgs::msg::PointCloud2* m) {
    std::lock_guard<std::mutex> lock(pool_mutex);
    if (pool.size() < kPoolMax) {
      pool.emplace_back(m);
    } else {
      delete m;
    }
  }

  explicit Impl(const NodeConfig& c)
      : config(c),
        scan_queue(static_cast<size_t>(c.scan_queue_capacity)),
        imu_queue(static_cast<size_t>(c.imu_queue_capacity)),
        malformed_log(c.malformed_log_interval_s),
        imu_malformed_log(c.malformed_log_interval_s),
        drop_log(c.malformed_log_interval_s),
        empty_log(c.malformed_log_interval_s),
        large_log(c.malformed_log_interval_s),
        stamp_log(c.malformed_log_interval_s),
        nonfinite_log(c.malformed_log_interval_s),
        jump_log(c.malformed_log_interval_s),
        late_log(c.malformed_log_interval_s),
        imu_late_log(c.malformed_log_interval_s),
        imu_dup_log(c.malformed_log_interval_s),
        outlier_log(c.malformed_log_interval_s) {}

  // ---- listeners (DDS threads) ----------------------------------------------------------------
  class CloudListener : public fdds::DataReaderListener {
   public:
    explicit CloudListener(Impl* impl) : impl_(impl) {}
    void on_data_available(fdds::DataReader* reader) override { impl_->OnClouds(reader); }
    void on_subscription_matched(fdds::DataReader*,
                                 const fdds::SubscriptionMatchedStatus& s) override {
      Log(Level::kInfo, "points: " + std::to_string(s.current_count) + " publisher(s) matched");
    }
    void on_requested_incompatible_qos(fdds::DataReader*,
                                       const fdds::RequestedIncompatibleQosStatus&) override {
      Log(Level::kWarn, "points: a publisher with incompatible QoS was ignored (reliability?)");
    }

   private:
    Impl* impl_;
  };
  class ImuListener : public fdds::DataReaderListener {
   public:
    explicit ImuListener(Impl* impl) : impl_(impl) {}
    void on_data_available(fdds::DataReader* reader) override { impl_->OnImu(reader); }
    void on_subscription_matched(fdds::DataReader*,
                                 const fdds::SubscriptionMatchedStatus& s) override {
      Log(Level::kInfo, "imu: " + std::to_string(s.current_count) + " publisher(s) matched");
    }
    void on_requested_incompatible_qos(fdds::DataReader*,
                                       const fdds::RequestedIncompatibleQosStatus&) override {
      Log(Level::kWarn, "imu: a publisher with incompatible QoS was ignored (reliability?)");
    }

   private:
    Impl* impl_;
  };

  void OnClouds(fdds::DataReader* reader) {
    while (true) {
      const Clock::time_point received = Clock::now();
      Validated<sensor_msgs::msg::PointCloud2> sample;
      std::unique_ptr<sensor_msgs::msg::PointCloud2> buffer = TakeFromPool();
      sample.msg = std::move(*buffer);  // moves keep the data vector's capacity
      fdds::SampleInfo info;
      const bool taken = reader->take_next_sample(&sample, &info) == ReturnCode_t::RETCODE_OK;
      *buffer = std::move(sample.msg);
      if (!taken) {
        ReturnToPool(buffer.release());
        break;
      }
      if (!info.valid_data || !accepting.load()) {
        ReturnToPool(buffer.release());
        continue;
      }
      if (const uint64_t missing =
              cloud_gaps.Count(info.sample_identity.writer_guid(),
                               info.sample_identity.sequence_number().to64long())) {
        {
          std::lock_guard<std::mutex> lock(stats_mutex);
          summary.scans_lost += missing;
        }
        lost_log.Log(Level::kWarn, "points: " + std::to_string(missing) +
                                       " scan(s) never reached the node (transport loss or "
                                       "reader history overwritten)");
      }
      {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++summary.scans_received;
      }
      // Size first: a cloud declaring more points than the bound is refused before anything
      // looks at its data.
      if (sample.valid && !CheckCloudSize(*buffer)) {
        ReturnToPool(buffer.release());
        continue;
      }
      std::string error;
      if (sample.valid) {
        if (!bridge::ToCloudView(*buffer, &error)) sample.valid = false;
      } else {
        error = sample.error;
      }
      if (!sample.valid) {
        {
          std::lock_guard<std::mutex> lock(stats_mutex);
          ++summary.scans_malformed;
        }
        malformed_log.Log(Level::kWarn, "rejected malformed PointCloud2 on " +
                                            RosTopicToDds(config.points_topic) + " (" +
                                            std::to_string(sample.payload_size) +
                                            " bytes): " + error);
        ReturnToPool(buffer.release());
        continue;
      }
      const double stamp = bridge::ToSeconds(buffer->header().stamp());
      if (!CheckCloudUsable(*buffer, stamp)) {
        ReturnToPool(buffer.release());
        continue;
      }
      std::shared_ptr<sensor_msgs::msg::PointCloud2> msg(
          buffer.release(), [this](sensor_msgs::msg::PointCloud2* m) { ReturnToPool(m); });
      auto pushed = scan_queue.Push(
          stamp, ScanItem{std::move(msg), received, Clock::now(), core_busy_ns.load()});
      if (pushed.time_jump) {
        {
          std::lock_guard<std::mutex> lock(stats_mutex);
          ++summary.time_jumps;
        }
        jump_log.Log(Level::kWarn,
                     "scan time jumped back to " + std::to_string(stamp) +
                         " (bag loop? clock reset? a stale scan?): the core restarts only if "
                         "the IMU stream jumps back too, otherwise the scan is dropped as late");
      }
      if (pushed.evicted) {
        {
          std::lock_guard<std::mutex> lock(stats_mutex);
          ++summary.scans_dropped;
        }
        drop_log.Log(Level::kWarn,
                     "core behind: dropped the oldest queued scan (stamp " +
                         std::to_string(bridge::ToSeconds(pushed.evicted->msg->header().stamp())) +
                         ")");
      }
    }
  }

  bool CheckCloudSize(const sensor_msgs::msg::PointCloud2& m) {
    const uint64_t n = static_cast<uint64_t>(m.width()) * m.height();
    if (n <= static_cast<uint64_t>(config.max_cloud_points)) return true;
    {
      std::lock_guard<std::mutex> lock(stats_mutex);
      ++summary.scans_too_large;
    }
    large_log.Log(Level::kWarn, std::to_string(n) + "-point PointCloud2 on " +
                                    RosTopicToDds(config.points_topic) +
                                    " exceeds queues.max_cloud_points " +
                                    std::to_string(config.max_cloud_points) + ": skipped");
    return false;
  }

  // Well-formed clouds the core cannot use (listener thread). Refused here, before the scan queue:
  // queued, they would evict good scans, and their stamps would move the queue's timeline.
  bool CheckCloudUsable(const sensor_msgs::msg::PointCloud2& m, double stamp) {
    const uint64_t n = static_cast<uint64_t>(m.width()) * m.height();
    const std::string on = " PointCloud2 on " + RosTopicToDds(config.points_topic);
    if (n == 0) {
      {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++summary.scans_empty;
      }
      empty_log.Log(Level::kWarn, "empty" + on + " (stamp " + std::to_string(stamp) +
                                      "): nothing to register, skipped");
      return false;
    }
    if (!(stamp > 0.0)) {
      {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++summary.scans_bad_stamp;
      }
      stamp_log.Log(Level::kWarn, on.substr(1) + " has stamp " + std::to_string(stamp) +
                                      " (unset clock?): skipped");
      return false;
    }
    return true;
  }

  void OnImu(fdds::DataReader* reader) {
    OnImuSamples(reader);
    // Wake the executor: a queued scan may be waiting for IMU that covers its end.
    scan_queue.Notify();
  }

  void OnImuSamples(fdds::DataReader* reader) {
    while (true) {
      Validated<sensor_msgs::msg::Imu> sample;
      fdds::SampleInfo info;
      if (reader->take_next_sample(&sample, &info) != ReturnCode_t::RETCODE_OK) break;
      if (!info.valid_data) continue;
      if (!accepting.load()) continue;
      if (const uint64_t missing =
              imu_gaps.Count(info.sample_identity.writer_guid(),
                             info.sample_identity.sequence_number().to64long())) {
        uint64_t total;
        {
          std::lock_guard<std::mutex> lock(stats_mutex);
          summary.imu_lost += missing;
          total = summary.imu_lost;
        }
        // Loud: the filter integrates every IMU sample (the core also sees the time gap).
        Log(Level::kError, "imu: " + std::to_string(missing) +
                               " sample(s) never reached the node (transport loss or reader "
                               "history overwritten; total " +
                               std::to_string(total) + ")");
      }
      std::string error = sample.error;
      std::optional<ImuSample> imu;
      if (sample.valid) imu = bridge::ToImuSample(sample.msg, &error);
      if (!imu) {
        {
          std::lock_guard<std::mutex> lock(stats_mutex);
          ++summary.imu_received;
          ++summary.imu_malformed;
        }
        imu_malformed_log.Log(Level::kWarn, "rejected malformed Imu on " +
                                                RosTopicToDds(config.imu_topic) + ": " + error);
        continue;
      }
      auto pushed = imu_queue.Push(imu->stamp_s, ImuItem{*imu});
      std::lock_guard<std::mutex> lock(stats_mutex);
      ++summary.imu_received;
      if (pushed.out_of_order) ++summary.imu_out_of_order;
      if (pushed.time_jump) {
        ++summary.time_jumps;
        jump_log.Log(Level::kWarn, "IMU time jumped back to " + std::to_string(imu->stamp_s) +
                                       " (bag loop? clock reset? an outlier?): the core restarts "
                                       "once the following samples continue from there");
      }
      if (pushed.evicted) {
        ++summary.imu_overflow;
        // Loud on purpose: losing IMU silently would corrupt the state estimate.
        Log(Level::kError, "IMU queue full (" + std::to_string(imu_queue.capacity()) +
                               "): dropped IMU sample at " +
                               std::to_string(pushed.evicted->sample.stamp_s) +
                               "; the core is stalled (total IMU dropped: " +
                               std::to_string(summary.imu_overflow) + ")");
      }
    }
  }

  // ---- executor thread ------------------------------------------------------------------------
  void ExecutorLoop() {
    uint64_t seen = 0;
    while (true) {
      const bool draining = drain_requested.load();
      if (!draining) scan_queue.WaitForChange(&seen, std::chrono::milliseconds(50));
      // IMU first: a scan can only be processed once IMU covers its end.
      std::deque<std::pair<double, ImuItem>> imus;
      imu_queue.PopAll(&imus);
      for (auto& [stamp, item] : imus) FeedImu(item.sample);
      if (!imus.empty() && !pending.empty()) RunCore(false);
      while (auto scan = scan_queue.PopFront()) {
        if (AcceptScanStamp(scan->first)) {
          AddScan(std::move(scan->second));
          RunCore(false);
        }
        // IMU that arrived while the core worked: feed it before the next scan.
        imus.clear();
        imu_queue.PopAll(&imus);
        for (auto& [stamp, item] : imus) FeedImu(item.sample);
      }
      if (draining && scan_queue.Size() == 0 && imu_queue.Size() == 0) {
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
    {
      std::lock_guard<std::mutex> lock(stats_mutex);
      ++summary.resets;
    }
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
                   scan_queue.PopFrontIf([&](double stamp) { return stamp > first + kJumpS; })) {
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
      {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++summary.imu_duplicate;
      }
      imu_dup_log.Log(Level::kError, "IMU sample at " + std::to_string(s.stamp_s) +
                                         " has the stamp of the sample before it (duplicate): "
                                         "dropped");
      return;
    }
    if (have && s.stamp_s < last_imu_fed) {
      {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++summary.imu_late;
      }
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
    {
      std::lock_guard<std::mutex> lock(stats_mutex);
      summary.imu_outliers += n;
    }
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
      {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++summary.scans_bad_stamp;
      }
      stamp_log.Log(Level::kWarn, "scan at " + std::to_string(stamp) + " is " +
                                      std::to_string(stamp - last_imu_fed) +
                                      " s ahead of the IMU stream (far-future stamp, or the IMU "
                                      "fell silent): skipped");
      return false;
    }
    if (stamp <= last_scan_fed) {
      {
        std::lock_guard<std::mutex> lock(stats_mutex);
        ++summary.scans_late;
      }
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
        p.queue_ms, 1e-6 * static_cast<double>(core_busy_ns.load() - item.core_busy_ns_at_queue));
    p.added = Clock::now();
    p.add_scan_ms = MsBetween(t0, p.added);
    core_busy_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(p.added - t0).count();
    if (config.publish_registered_points) p.msg = std::move(item.msg);
    pending.push_back(std::move(p));
  }

  void RunCore(bool flush) {
    const Clock::time_point t0 = Clock::now();
    std::vector<ScanResult> results = core->Process(flush);
    const Clock::time_point t1 = Clock::now();
    const double process_ms = MsBetween(t0, t1);
    core_busy_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count();
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
    const Clock::time_point publish_start = Clock::now();
    uint64_t scans_lost = 0, imu_lost = 0;
    {
      std::lock_guard<std::mutex> lock(stats_mutex);
      scans_lost = summary.scans_lost;
      imu_lost = summary.imu_lost;
      ++summary.scans_processed;
      summary.last_status = StatusName(r.status);
      if (r.status == Status::kRejected) ++summary.scans_rejected;
      if (r.status == Status::kInitializing) ++summary.scans_initializing;
      if (r.status == Status::kReset) ++summary.resets;
      if (r.status == Status::kDegenerate) ++summary.degenerate;
      summary.points_nonfinite += r.dropped_nan;
      if (r.imu_gap_s > 0.0) {
        ++summary.imu_gaps_bridged;
        summary.imu_gap_max_s = std::max(summary.imu_gap_max_s, r.imu_gap_s);
      }
    }
    if (r.dropped_nan > 0) {
      nonfinite_log.Log(Level::kWarn, "scan at " + std::to_string(r.scan_begin_s) + ": " +
                                          std::to_string(r.dropped_nan) + " of " +
                                          std::to_string(r.input_points) +
                                          " points non-finite (NaN/Inf), dropped");
    }
    if (r.imu_gap_s > 0.0) {
      // Not rate limited: a gap is rare and the operator wants its size and what it cost.
      std::ostringstream os;
      os << std::fixed << std::setprecision(3) << "input gap: no IMU for " << r.imu_gap_s
         << " s before the scan at " << r.stamp_s << "; bridged, odometry continues (lost so far: "
         << scans_lost << " scans, " << imu_lost << " IMU samples)";
      Log(Level::kWarn, os.str());
    }
    if (r.status == Status::kRejected || r.status == Status::kReset) {
      status_log.Log(Level::kWarn, std::string("core: ") + StatusName(r.status) + ": " + r.reason);
    }
    if (!r.pose_valid) return;
    bridge::OdometryFrames frames{config.odom_frame, config.base_frame};
    nav_msgs::msg::Odometry odom = bridge::ToOdometryMsg(r, frames, last_gyro - r.gyro_bias);
    odometry_writer->write(&odom);
    if (tf_writer) {
      tf2_msgs::msg::TFMessage tf = bridge::ToTfMessage(r, frames);
      tf_writer->write(&tf);
    }
    if (path_writer) {
      path.poses().push_back(bridge::ToPoseStamped(r, config.odom_frame));
      if (path.poses().size() > static_cast<size_t>(config.path_max_poses)) {
        path.poses().erase(path.poses().begin());
      }
      path.header() = path.poses().back().header();
      path_writer->write(&path);
    }
    if (planes_writer) {
      // The facade's built-in skeleton tracker (kPpf) reports its world-frame window after each
      // scan; the message carries the planes fitted in this scan (missed_scans == 0), world = odom
      // frame. In kNN mode the message is empty, still one per scan.
      std::vector<SkeletonPlane> fitted;
      for (const SkeletonPlane& sp : r.skeleton_planes) {
        if (sp.missed_scans == 0) fitted.push_back(sp);
      }
      ppf_msgs::msg::SkeletonPlaneArray planes =
          bridge::ToSkeletonPlaneArray(fitted, r.stamp_s, config.odom_frame);
      planes_writer->write(&planes);
    }
    if (registered_writer && p.msg) PublishRegistered(r, *p.msg);
    const Clock::time_point published = Clock::now();
    trajectory.push_back(r);

    const double latency = MsBetween(p.received, published);
    std::lock_guard<std::mutex> lock(stats_mutex);
    ++summary.odometry_published;
    latency_ms.Add(latency);
    core_time_ms.Add(core_ms);
    imu_wait_stats.Add(imu_wait_ms);
    decode_stats.Add(p.decode_ms);
    queue_stats.Add(p.queue_ms);
    behind_core_stats.Add(p.behind_core_ms);
    publish_stats.Add(MsBetween(publish_start, published));
    // Node overhead: everything between DDS receive and publish that is not the core working on
    // this scan, waiting for the core to finish earlier scans, or waiting for the IMU that covers
    // the scan end (the last two are reported apart).
    overhead_ms.Add(latency - core_ms - imu_wait_ms - p.behind_core_ms);
  }

  // Input points moved to the odom frame with the scan-end pose (not de-skewed: the core keeps
  // its de-skewed cloud internal). x, y, z float32 only.
  void PublishRegistered(const ScanResult& r, const sensor_msgs::msg::PointCloud2& in) {
    int ox = -1, oy = -1, oz = -1;
    for (const auto& f : in.fields()) {
      if (f.datatype() != 7) continue;
      if (f.name() == "x") ox = static_cast<int>(f.offset());
      if (f.name() == "y") oy = static_cast<int>(f.offset());
      if (f.name() == "z") oz = static_cast<int>(f.offset());
    }
    if (ox < 0 || oy < 0 || oz < 0 || in.is_bigendian()) return;
    const size_t n = static_cast<size_t>(in.width()) * in.height();
    const size_t step = in.point_step();
    if (step == 0 || in.data().size() < n * step) return;
    // The registered cloud goes out through the input's validating type: one type name can only
    // be registered once per participant, and the reader must keep the validating one.
    Validated<sensor_msgs::msg::PointCloud2> wrapped;
    sensor_msgs::msg::PointCloud2& out = wrapped.msg;
    out.header().stamp(bridge::TimeFromSeconds(r.stamp_s));
    out.header().frame_id(config.odom_frame);
    out.height(1);
    const char* names[] = {"x", "y", "z"};
    for (uint32_t i = 0; i < 3; ++i) {
      sensor_msgs::msg::PointField f;
      f.name(names[i]);
      f.offset(4 * i);
      f.datatype(7);
      f.count(1);
      out.fields().push_back(f);
    }
    out.point_step(12);
    out.is_bigendian(false);
    out.is_dense(true);
    std::vector<uint8_t>& data = out.data();
    data.resize(n * 12);
    const Eigen::Isometry3d& T = r.T_world_lidar;
    size_t kept = 0;
    for (size_t i = 0; i < n; ++i) {
      const uint8_t* p = in.data().data() + i * step;
      float v[3];
      std::memcpy(&v[0], p + ox, 4);
      std::memcpy(&v[1], p + oy, 4);
      std::memcpy(&v[2], p + oz, 4);
      if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) continue;
      const Eigen::Vector3d w = T * Eigen::Vector3d(v[0], v[1], v[2]);
      const float o[3] = {static_cast<float>(w.x()), static_cast<float>(w.y()),
                          static_cast<float>(w.z())};
      std::memcpy(data.data() + kept * 12, o, 12);
      ++kept;
    }
    data.resize(kept * 12);
    out.width(static_cast<uint32_t>(kept));
    out.row_step(static_cast<uint32_t>(kept * 12));
    registered_writer->write(&wrapped);
  }

  bool WriteTum(std::string* error) {
    std::ofstream out(config.tum_file);
    if (!out) {
      *error = "cannot write trajectory file '" + config.tum_file + "'";
      return false;
    }
    out << std::fixed;
    for (const ScanResult& r : trajectory) {
      const Eigen::Vector3d p = r.T_world_imu.translation();
      Eigen::Quaterniond q(r.T_world_imu.linear());
      q.normalize();
      out << std::setprecision(9) << r.stamp_s << ' ' << p.x() << ' ' << p.y() << ' ' << p.z()
          << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
    }
    out.flush();
    if (!out) {
      *error = "error writing '" + config.tum_file + "'";
      return false;
    }
    return true;
  }

  NodeSummary Snapshot() const {
    std::lock_guard<std::mutex> lock(stats_mutex);
    NodeSummary s = summary;
    s.latency_p50_ms = latency_ms.Percentile(50);
    s.latency_p99_ms = latency_ms.Percentile(99);
    s.latency_max_ms = latency_ms.Max();
    s.core_p50_ms = core_time_ms.Percentile(50);
    s.core_p99_ms = core_time_ms.Percentile(99);
    s.overhead_p50_ms = overhead_ms.Percentile(50);
    s.overhead_p99_ms = overhead_ms.Percentile(99);
    s.overhead_max_ms = overhead_ms.Max();
    s.imu_wait_p50_ms = imu_wait_stats.Percentile(50);
    s.imu_wait_p99_ms = imu_wait_stats.Percentile(99);
    s.decode_p50_ms = decode_stats.Percentile(50);
    s.decode_p99_ms = decode_stats.Percentile(99);
    s.queue_p50_ms = queue_stats.Percentile(50);
    s.queue_p99_ms = queue_stats.Percentile(99);
    s.behind_core_p50_ms = behind_core_stats.Percentile(50);
    s.behind_core_p99_ms = behind_core_stats.Percentile(99);
    s.publish_p50_ms = publish_stats.Percentile(50);
    s.publish_p99_ms = publish_stats.Percentile(99);
    return s;
  }

  void FlushInputLogs() {
    for (RateLimitedLog* l : {&malformed_log, &imu_malformed_log, &drop_log, &empty_log, &large_log,
                              &stamp_log, &nonfinite_log, &status_log, &lost_log, &jump_log,
                              &late_log, &imu_late_log, &imu_dup_log, &outlier_log}) {
      l->Flush();
    }
  }

  void LogPeriodic(size_t* latency_mark) {
    FlushInputLogs();
    NodeSummary s;
    double lat50, lat99, ovh99;
    size_t n;
    {
      std::lock_guard<std::mutex> lock(stats_mutex);
      s = summary;
      n = latency_ms.count();
      lat50 = latency_ms.PercentileSince(*latency_mark, 50);
      lat99 = latency_ms.PercentileSince(*latency_mark, 99);
      ovh99 = overhead_ms.PercentileSince(*latency_mark, 99);
    }
    std::ostringstream o;
    o << std::fixed << std::setprecision(2)
      << "status=" << (s.last_status.empty() ? "waiting" : s.last_status)
      << " scans rx=" << s.scans_received << " proc=" << s.scans_processed
      << " odom=" << s.odometry_published << " dropped=" << s.scans_dropped
      << " malformed=" << s.scans_malformed + s.imu_malformed << " imu rx=" << s.imu_received
      << " queues scan=" << scan_queue.Size() << "/" << scan_queue.capacity()
      << " imu=" << imu_queue.Size() << " | last " << (n - *latency_mark)
      << " scans: latency p50=" << lat50 << " p99=" << lat99 << " ms, overhead p99=" << ovh99
      << " ms";
    Log(Level::kInfo, o.str());
    *latency_mark = n;
  }

  NodeConfig config;
  std::unique_ptr<LioPpf> core;

  fdds::DomainParticipant* participant = nullptr;
  fdds::Publisher* publisher = nullptr;
  fdds::Subscriber* subscriber = nullptr;
  fdds::DataWriter* odometry_writer = nullptr;
  fdds::DataWriter* tf_writer = nullptr;
  fdds::DataWriter* path_writer = nullptr;
  fdds::DataWriter* planes_writer = nullptr;
  fdds::DataWriter* registered_writer = nullptr;
  fdds::DataReader* points_reader = nullptr;
  fdds::DataReader* imu_reader = nullptr;
  fdds::TypeSupport odom_type{new nav_msgs::msg::OdometryPubSubType()};
  fdds::TypeSupport tf_type{new tf2_msgs::msg::TFMessagePubSubType()};
  fdds::TypeSupport path_type{new nav_msgs::msg::PathPubSubType()};
  fdds::TypeSupport planes_type{new ppf_msgs::msg::SkeletonPlaneArrayPubSubType()};
  fdds::TypeSupport cloud_in_type{new ValidatingPubSubType<sensor_msgs::msg::PointCloud2>()};
  fdds::TypeSupport imu_in_type{new ValidatingPubSubType<sensor_msgs::msg::Imu>()};
  std::unique_ptr<CloudListener> cloud_listener;
  std::unique_ptr<ImuListener> imu_listener;

  TimeOrderedQueue<ScanItem> scan_queue;
  TimeOrderedQueue<ImuItem> imu_queue;
  std::atomic<bool> accepting{true};
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
  nav_msgs::msg::Path path;
  std::vector<ScanResult> trajectory;

  RateLimitedLog malformed_log;
  RateLimitedLog imu_malformed_log;
  RateLimitedLog drop_log;
  RateLimitedLog empty_log, large_log, stamp_log, nonfinite_log;
  RateLimitedLog status_log{1.0};
  RateLimitedLog lost_log{1.0};
  // Input defects, one limiter per kind so that one kind's burst does not hide another's line.
  RateLimitedLog jump_log, late_log, imu_late_log, imu_dup_log, outlier_log;
  GapCounter cloud_gaps, imu_gaps;  // each used by its reader's listener only

  mutable std::mutex stats_mutex;
  NodeSummary summary;
  LatencyStats latency_ms, core_time_ms, overhead_ms, imu_wait_stats, decode_stats, queue_stats,
      behind_core_stats, publish_stats;
  std::atomic<int64_t> core_busy_ns{0};  // total executor time inside the core
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

  // Writers (ROS 2 QoS conventions, ROS2-INTEROP.md).
  m.odometry_writer = CreateWriter<nav_msgs::msg::Odometry>(
      m.participant, m.publisher, &m.odom_type, c.odometry_topic, DefaultWriterQos(10), error);
  if (!m.odometry_writer) return false;
  if (c.publish_skeleton_planes) {
    m.planes_writer = CreateWriter<ppf_msgs::msg::SkeletonPlaneArray>(
        m.participant, m.publisher, &m.planes_type, c.skeleton_planes_topic, DefaultWriterQos(10),
        error);
    if (!m.planes_writer) return false;
  }
  if (c.publish_tf) {
    m.tf_writer = CreateWriter<tf2_msgs::msg::TFMessage>(m.participant, m.publisher, &m.tf_type,
                                                         c.tf_topic, TfWriterQos(), error);
    if (!m.tf_writer) return false;
  }
  if (c.publish_path) {
    // Each message is the whole bounded path: only the latest matters.
    m.path_writer = CreateWriter<nav_msgs::msg::Path>(m.participant, m.publisher, &m.path_type,
                                                      c.path_topic, DefaultWriterQos(1), error);
    if (!m.path_writer) return false;
  }
  if (c.publish_registered_points) {
    // Reliable matches both reliable and best-effort readers (RViz either way); depth 2 bounds
    // the memory held for slow readers.
    m.registered_writer = CreateWriter<sensor_msgs::msg::PointCloud2>(
        m.participant, m.publisher, &m.cloud_in_type, c.registered_points_topic,
        DefaultWriterQos(2), error);
    if (!m.registered_writer) return false;
  }

  // Readers last: data may flow as soon as they exist.
  if (m.cloud_in_type.register_type(m.participant) != ReturnCode_t::RETCODE_OK ||
      m.imu_in_type.register_type(m.participant) != ReturnCode_t::RETCODE_OK) {
    *error = "input types already registered differently";
    return false;
  }
  fdds::Topic* points_topic = m.participant->create_topic(
      RosTopicToDds(c.points_topic), m.cloud_in_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  fdds::Topic* imu_topic = m.participant->create_topic(
      RosTopicToDds(c.imu_topic), m.imu_in_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  if (!points_topic || !imu_topic) {
    *error = "cannot create input topics";
    return false;
  }
  m.cloud_listener = std::make_unique<Impl::CloudListener>(&m);
  m.imu_listener = std::make_unique<Impl::ImuListener>(&m);
  m.points_reader = m.subscriber->create_datareader(
      points_topic, SensorReaderQos(c.sensor_reliability, c.sensor_depth), m.cloud_listener.get());
  // IMU: deeper reader history than clouds, a burst of 400 Hz samples must not be overwritten
  // before the listener takes them.
  m.imu_reader = m.subscriber->create_datareader(
      imu_topic, SensorReaderQos(c.sensor_reliability, std::max(c.sensor_depth, 100)),
      m.imu_listener.get());
  if (!m.points_reader || !m.imu_reader) {
    *error = "cannot create input readers";
    return false;
  }
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
  m.accepting = false;
  m.drain_requested = true;
  m.scan_queue.Notify();
  executor.join();
  m.FlushInputLogs();  // the counts of bursts no later line reported
  if (!m.config.tum_file.empty()) {
    std::string error;
    if (m.WriteTum(&error)) {
      Log(Level::kInfo,
          "trajectory: " + std::to_string(m.trajectory.size()) + " poses -> " + m.config.tum_file);
    } else {
      Log(Level::kError, error);
    }
  }
  // Give reliable readers a moment to receive the last outputs before the writers go away.
  if (m.odometry_writer) m.odometry_writer->wait_for_acknowledgments({1, 0});
  m.TearDown();
}

void PpfNode::stop() {
  {
    std::lock_guard<std::mutex> lock(impl_->stop_mutex);
    impl_->stop_requested = true;
  }
  impl_->stop_cv.notify_all();
}

NodeSummary PpfNode::summary() const { return impl_->Snapshot(); }

std::string PpfNode::FormatSummary(const NodeSummary& s) {
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
    << " last_status=" << (s.last_status.empty() ? "none" : s.last_status);
  return o.str();
}

}  // namespace ppf::dds
