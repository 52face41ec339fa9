#include "node_inputs.hpp"

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <optional>
#include <vector>

#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>

#include "ppf_bridge/convert.hpp"
#include "ppf_dds_node/dds_common.hpp"
#include "ppf_dds_node/validating_type.hpp"
#include "ppf_msgs_cdr/cdr.hpp"
#include "ppf_msgs_cdr/time.hpp"

namespace ppf::dds {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;

// Cloud buffers are recycled: a fresh multi-MB vector per scan costs page faults and a memset
// in the listener, the bulk of its latency tail (docs/decisions.md, "Cloud buffer pool").
class NodeInputs::CloudPool : public std::enable_shared_from_this<CloudPool> {
 public:
  std::unique_ptr<sensor_msgs::msg::PointCloud2> Take() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (free_.empty()) return std::make_unique<sensor_msgs::msg::PointCloud2>();
    auto m = std::move(free_.back());
    free_.pop_back();
    return m;
  }
  void Return(std::unique_ptr<sensor_msgs::msg::PointCloud2> m) {
    // A buffer keeps the capacity of the largest cloud it held: one that grew for an unusually
    // large cloud is freed rather than kept resident for the ordinary scans that follow.
    if (m->data().capacity() > kMaxPooledBytes) return;
    std::lock_guard<std::mutex> lock(mutex_);
    if (free_.size() < kMax) free_.push_back(std::move(m));
  }
  // Shared ownership whose last holder hands the buffer back.
  std::shared_ptr<sensor_msgs::msg::PointCloud2> Share(
      std::unique_ptr<sensor_msgs::msg::PointCloud2> m) {
    return {m.release(), [pool = shared_from_this()](sensor_msgs::msg::PointCloud2* p) {
              pool->Return(std::unique_ptr<sensor_msgs::msg::PointCloud2>(p));
            }};
  }

 private:
  static constexpr size_t kMax = 8;
  // Well above a 128-beam LiDAR's scan.
  static constexpr size_t kMaxPooledBytes = 32u << 20;
  std::mutex mutex_;
  std::vector<std::unique_ptr<sensor_msgs::msg::PointCloud2>> free_;
};

class NodeInputs::CloudListener : public fdds::DataReaderListener {
 public:
  explicit CloudListener(NodeInputs* inputs) : inputs_(inputs) {}
  void on_data_available(fdds::DataReader* reader) override { inputs_->OnClouds(reader); }
  void on_subscription_matched(fdds::DataReader*,
                               const fdds::SubscriptionMatchedStatus& s) override {
    inputs_->points_stall_.OnMatched(s.current_count, Clock::now());
    Log(Level::kInfo, "points: " + std::to_string(s.current_count) + " publisher(s) matched");
  }
  void on_requested_incompatible_qos(fdds::DataReader*,
                                     const fdds::RequestedIncompatibleQosStatus&) override {
    Log(Level::kWarn, "points: a publisher with incompatible QoS was ignored (reliability?)");
  }

 private:
  NodeInputs* inputs_;
};

class NodeInputs::ImuListener : public fdds::DataReaderListener {
 public:
  explicit ImuListener(NodeInputs* inputs) : inputs_(inputs) {}
  void on_data_available(fdds::DataReader* reader) override {
    inputs_->OnImu(reader);
    // Wake the executor: a queued scan may be waiting for IMU that covers its end.
    inputs_->scan_queue_.Notify();
  }
  void on_subscription_matched(fdds::DataReader*,
                               const fdds::SubscriptionMatchedStatus& s) override {
    inputs_->imu_stall_.OnMatched(s.current_count, Clock::now());
    Log(Level::kInfo, "imu: " + std::to_string(s.current_count) + " publisher(s) matched");
  }
  void on_requested_incompatible_qos(fdds::DataReader*,
                                     const fdds::RequestedIncompatibleQosStatus&) override {
    Log(Level::kWarn, "imu: a publisher with incompatible QoS was ignored (reliability?)");
  }

 private:
  NodeInputs* inputs_;
};

NodeInputs::NodeInputs(const NodeConfig& c, NodeStats* stats)
    : config_(c),
      stats_(stats),
      pool_(std::make_shared<CloudPool>()),
      scan_queue_(static_cast<size_t>(c.scan_queue_capacity)),
      imu_queue_(static_cast<size_t>(c.imu_queue_capacity)),
      // Size first, from the payload's header: a cloud declaring more points than the bound is
      // refused before its data is decoded or copied.
      cloud_type_(new ValidatingPubSubType<sensor_msgs::msg::PointCloud2>(
          [max_points = static_cast<uint64_t>(c.max_cloud_points)](const uint8_t* data,
                                                                    size_t size) {
            uint64_t n = 0;
            if (!msgs::PeekCloudPointCount(data, size, &n) || n <= max_points) return std::string();
            return std::to_string(n);
          })),
      imu_type_(new ValidatingPubSubType<sensor_msgs::msg::Imu>()),
      malformed_log_(c.malformed_log_interval_s),
      imu_malformed_log_(c.malformed_log_interval_s),
      drop_log_(c.malformed_log_interval_s),
      empty_log_(c.malformed_log_interval_s),
      large_log_(c.malformed_log_interval_s),
      stamp_log_(c.malformed_log_interval_s),
      jump_log_(c.malformed_log_interval_s),
      points_stall_(c.stall_warn_s),
      imu_stall_(c.stall_warn_s) {}

NodeInputs::~NodeInputs() = default;

bool NodeInputs::Create(fdds::DomainParticipant* participant, fdds::Subscriber* subscriber,
                        std::string* error) {
  if (cloud_type_.register_type(participant) != ReturnCode_t::RETCODE_OK ||
      imu_type_.register_type(participant) != ReturnCode_t::RETCODE_OK) {
    *error = "input types already registered differently";
    return false;
  }
  fdds::Topic* points_topic = participant->create_topic(
      RosTopicToDds(config_.points_topic), cloud_type_.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  fdds::Topic* imu_topic = participant->create_topic(
      RosTopicToDds(config_.imu_topic), imu_type_.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  if (!points_topic || !imu_topic) {
    *error = "cannot create input topics";
    return false;
  }
  cloud_listener_ = std::make_unique<CloudListener>(this);
  imu_listener_ = std::make_unique<ImuListener>(this);
  fdds::DataReaderQos points_qos =
      SensorReaderQos(config_.sensor_reliability, config_.sensor_depth);
  // Payloads allocated per sample and freed once taken: a reusing history keeps each slot at the
  // largest cloud it ever held, so one huge cloud (refused or not) stayed resident for good.
  points_qos.endpoint().history_memory_policy =
      eprosima::fastrtps::rtps::DYNAMIC_RESERVE_MEMORY_MODE;
  fdds::DataReader* points_reader =
      subscriber->create_datareader(points_topic, points_qos, cloud_listener_.get());
  // IMU: deeper reader history than clouds, a burst of 400 Hz samples must not be overwritten
  // before the listener takes them.
  fdds::DataReader* imu_reader = subscriber->create_datareader(
      imu_topic, SensorReaderQos(config_.sensor_reliability, std::max(config_.sensor_depth, 100)),
      imu_listener_.get());
  if (!points_reader || !imu_reader) {
    *error = "cannot create input readers";
    return false;
  }
  return true;
}

QueueFill NodeInputs::Fill() const {
  QueueFill q;
  q.scans = scan_queue_.Size();
  q.scan_capacity = scan_queue_.capacity();
  q.imus = imu_queue_.Size();
  return q;
}

void NodeInputs::FlushLogs() {
  for (RateLimitedLog* l : {&malformed_log_, &imu_malformed_log_, &drop_log_, &empty_log_,
                            &large_log_, &stamp_log_, &lost_log_, &jump_log_}) {
    l->Flush();
  }
}

namespace {

std::string Seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", s);
  return buf;
}

// One stream's stall events as log lines; counts the counted episodes into `counter`.
void ReportStall(const std::string& stream, StallWatch* w, NodeStats* stats,
                 uint64_t NodeSummary::*counter) {
  const StallWatch::Poll p = w->Check(Clock::now());
  const std::string matched = std::to_string(w->matched()) + " publisher(s) matched";
  switch (p.event) {
    case StallWatch::Event::kNone:
      break;
    case StallWatch::Event::kStalled:
      if (p.counted) {
        const uint64_t n = stats->Add(counter);
        Log(Level::kWarn, stream + ": stalled: nothing received for " + Seconds(p.silent_s) +
                              " s although " + matched +
                              " (the publisher stopped sending, or the transport stopped "
                              "delivering; stall " +
                              std::to_string(n) + ")");
      } else {
        Log(Level::kWarn, stream + ": " + matched + " " + Seconds(p.silent_s) +
                              " s ago, nothing received yet (a replay not started? a driver "
                              "not sending?)");
      }
      break;
    case StallWatch::Event::kStillStalled:
      Log(Level::kWarn, stream + ": still stalled: nothing received for " + Seconds(p.silent_s) +
                            " s, " + matched);
      break;
    case StallWatch::Event::kResumed:
      Log(Level::kInfo, stream + ": " + (p.counted ? "data resumed" : "first data") +
                            " after a silence of at least " + Seconds(p.silent_s) + " s");
      break;
    case StallWatch::Event::kEnded:
      Log(Level::kInfo, stream + ": no publisher left; the stall ended after at least " +
                            Seconds(p.silent_s) + " s without data");
      break;
  }
}

}  // namespace

std::string NodeInputs::CheckStalls() {
  ReportStall("points", &points_stall_, stats_, &NodeSummary::points_stalls);
  ReportStall("imu", &imu_stall_, stats_, &NodeSummary::imu_stalls);
  std::string stalled;
  if (points_stall_.stalled()) stalled = "points";
  if (imu_stall_.stalled()) stalled += stalled.empty() ? "imu" : "+imu";
  return stalled;
}

void NodeInputs::OnClouds(fdds::DataReader* reader) {
  while (true) {
    const Clock::time_point received = Clock::now();
    Validated<sensor_msgs::msg::PointCloud2> sample;
    std::unique_ptr<sensor_msgs::msg::PointCloud2> buffer = pool_->Take();
    sample.msg = std::move(*buffer);  // moves keep the data vector's capacity
    fdds::SampleInfo info;
    const bool taken = reader->take_next_sample(&sample, &info) == ReturnCode_t::RETCODE_OK;
    *buffer = std::move(sample.msg);
    if (!taken) {
      pool_->Return(std::move(buffer));
      break;
    }
    if (!info.valid_data) {
      pool_->Return(std::move(buffer));
      continue;
    }
    // Any sample, malformed ones too: the stream is alive.
    points_stall_.OnSample(received);
    if (!accepting_.load()) {
      pool_->Return(std::move(buffer));
      continue;
    }
    if (const uint64_t missing =
            cloud_gaps_.Count(info.sample_identity.writer_guid(),
                              info.sample_identity.sequence_number().to64long())) {
      stats_->Add(&NodeSummary::scans_lost, missing);
      lost_log_.Log(Level::kWarn, "points: " + std::to_string(missing) +
                                      " scan(s) never reached the node (transport loss or "
                                      "reader history overwritten)");
    }
    stats_->AddScanReceived(received);
    if (sample.refused) {  // by the type's size gate, undecoded: the buffer kept its capacity
      ReportTooLarge(sample.error);
      pool_->Return(std::move(buffer));
      continue;
    }
    std::string error;
    if (sample.valid) {
      if (!bridge::ToCloudView(*buffer, &error)) sample.valid = false;
    } else {
      error = sample.error;
    }
    if (!sample.valid) {
      stats_->Add(&NodeSummary::scans_malformed);
      malformed_log_.Log(
          Level::kWarn, "rejected malformed PointCloud2 on " + RosTopicToDds(config_.points_topic) +
                            " (" + std::to_string(sample.payload_size) + " bytes): " + error);
      pool_->Return(std::move(buffer));
      continue;
    }
    NoteUnusualCloud(*buffer);
    const double stamp = msgs::ToSeconds(buffer->header().stamp());
    if (!CheckCloudUsable(*buffer, stamp)) {
      pool_->Return(std::move(buffer));
      continue;
    }
    auto pushed = scan_queue_.Push(stamp, ScanItem{pool_->Share(std::move(buffer)), received,
                                                   Clock::now(), stats_->core_busy_ns()});
    if (pushed.time_jump) {
      stats_->Add(&NodeSummary::time_jumps);
      jump_log_.Log(Level::kWarn,
                    "scan time jumped back to " + std::to_string(stamp) +
                        " (bag loop? clock reset? a stale scan?): the core restarts only if "
                        "the IMU stream jumps back too, otherwise the scan is dropped as late");
    }
    if (pushed.evicted) {
      stats_->Add(&NodeSummary::scans_dropped);
      drop_log_.Log(Level::kWarn,
                    "core behind: dropped the oldest queued scan (stamp " +
                        std::to_string(msgs::ToSeconds(pushed.evicted->msg->header().stamp())) +
                        ")");
    }
  }
}

void NodeInputs::ReportTooLarge(const std::string& points) {
  stats_->Add(&NodeSummary::scans_too_large);
  large_log_.Log(Level::kWarn, points + "-point PointCloud2 on " +
                                   RosTopicToDds(config_.points_topic) +
                                   " exceeds queues.max_cloud_points " +
                                   std::to_string(config_.max_cloud_points) + ": skipped");
}

// Well-formed clouds the core cannot use. Refused here, before the scan queue: queued, they would
// evict good scans, and their stamps would move the queue's timeline.
bool NodeInputs::CheckCloudUsable(const sensor_msgs::msg::PointCloud2& m, double stamp) {
  const uint64_t n = static_cast<uint64_t>(m.width()) * m.height();
  const std::string on = " PointCloud2 on " + RosTopicToDds(config_.points_topic);
  if (n == 0) {
    stats_->Add(&NodeSummary::scans_empty);
    empty_log_.Log(Level::kWarn, "empty" + on + " (stamp " + std::to_string(stamp) +
                                     "): nothing to register, skipped");
    return false;
  }
  if (!(stamp > 0.0)) {
    stats_->Add(&NodeSummary::scans_bad_stamp);
    stamp_log_.Log(Level::kWarn, on.substr(1) + " has stamp " + std::to_string(stamp) +
                                     " (unset clock?): skipped");
    return false;
  }
  return true;
}

namespace {

// Real drivers declare a few to a few tens of fields, and frame names are short; far beyond
// either, a user debugging a driver wants to hear of it.
constexpr size_t kManyFields = 64;
constexpr size_t kLongFrameId = 256;

}  // namespace

// Clouds taken as they are, but unusual enough to name. Each kind is logged the first time only:
// a driver that always does it would otherwise repeat the line all run; every one is counted.
void NodeInputs::NoteUnusualCloud(const sensor_msgs::msg::PointCloud2& m) {
  const std::string cloud = "PointCloud2 on " + RosTopicToDds(config_.points_topic);
  const std::string later = " (said once; every such cloud is counted in scans_unusual)";
  bool unusual = false;
  if (m.row_step() == 0 && static_cast<uint64_t>(m.width()) * m.height() > 0) {
    unusual = true;
    if (!said_row_step_zero_.exchange(true)) {
      Log(Level::kInfo, cloud + " has row_step 0: read as width * point_step (" +
                            std::to_string(static_cast<uint64_t>(m.width()) * m.point_step()) +
                            " bytes per row), the data matching that" + later);
    }
  }
  if (m.fields().size() > kManyFields) {
    unusual = true;
    if (!said_many_fields_.exchange(true)) {
      Log(Level::kWarn, cloud + " declares " + std::to_string(m.fields().size()) +
                            " fields: only x, y, z and the time field are read" + later);
    }
  }
  if (m.header().frame_id().size() > kLongFrameId) {
    unusual = true;
    if (!said_long_frame_id_.exchange(true)) {
      Log(Level::kWarn, cloud + " has a frame_id of " +
                            std::to_string(m.header().frame_id().size()) + " bytes (\"" +
                            m.header().frame_id().substr(0, 32) +
                            "...\"): not used, the node's frames come from frames.*" + later);
    }
  }
  if (unusual) stats_->Add(&NodeSummary::scans_unusual);
}

void NodeInputs::OnImu(fdds::DataReader* reader) {
  while (true) {
    Validated<sensor_msgs::msg::Imu> sample;
    fdds::SampleInfo info;
    const Clock::time_point received = Clock::now();
    if (reader->take_next_sample(&sample, &info) != ReturnCode_t::RETCODE_OK) break;
    if (!info.valid_data) continue;
    imu_stall_.OnSample(Clock::now());
    if (!accepting_.load()) continue;
    if (const uint64_t missing =
            imu_gaps_.Count(info.sample_identity.writer_guid(),
                            info.sample_identity.sequence_number().to64long())) {
      const uint64_t total = stats_->Add(&NodeSummary::imu_lost, missing);
      // Loud: the filter integrates every IMU sample (the core also sees the time gap).
      Log(Level::kError, "imu: " + std::to_string(missing) +
                             " sample(s) never reached the node (transport loss or reader "
                             "history overwritten; total " +
                             std::to_string(total) + ")");
    }
    std::string error = sample.error;
    std::optional<ImuSample> imu;
    if (sample.valid) imu = bridge::ToImuSample(sample.msg, &error);
    stats_->Add(&NodeSummary::imu_received);
    if (!imu) {
      stats_->Add(&NodeSummary::imu_malformed);
      imu_malformed_log_.Log(Level::kWarn, "rejected malformed Imu on " +
                                               RosTopicToDds(config_.imu_topic) + ": " + error);
      continue;
    }
    auto pushed = imu_queue_.Push(imu->stamp_s, ImuItem{*imu, Clock::now()});
    if (pushed.out_of_order) stats_->Add(&NodeSummary::imu_out_of_order);
    if (pushed.time_jump) {
      stats_->Add(&NodeSummary::time_jumps);
      jump_log_.Log(Level::kWarn, "IMU time jumped back to " + std::to_string(imu->stamp_s) +
                                      " (bag loop? clock reset? an outlier?): the core restarts "
                                      "once the following samples continue from there");
    }
    if (pushed.evicted) {
      const uint64_t total = stats_->Add(&NodeSummary::imu_overflow);
      // Loud on purpose: losing IMU silently would corrupt the state estimate.
      Log(Level::kError,
          "IMU queue full (" + std::to_string(imu_queue_.capacity()) + "): dropped IMU sample at " +
              std::to_string(pushed.evicted->sample.stamp_s) +
              "; the core is stalled (total IMU dropped: " + std::to_string(total) + ")");
    }
    if (imu_observer_) imu_observer_(*imu, sample.msg.header().stamp(), received);
  }
}

}  // namespace ppf::dds
