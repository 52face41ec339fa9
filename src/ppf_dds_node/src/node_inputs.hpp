// NodeInputs: the node's two DDS readers and what happens on their listener threads: take the
// sample (into a recycled cloud buffer), count sequence gaps, validate, and push into the bounded
// time-ordered queues that the executor drains. Listeners never wait for the core.
//
// Locking: Fast DDS calls the listeners with its own locks held, so they only take the short
// internal locks of the buffer pool, the queues and NodeStats; nothing here calls into Fast DDS
// while holding one of ours.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "node_stats.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_dds_node/gap_counter.hpp"
#include "ppf_dds_node/logging.hpp"
#include "ppf_dds_node/node_config.hpp"
#include "ppf_dds_node/stall_watch.hpp"
#include "ppf_dds_node/time_ordered_queue.hpp"
#include "ppf_msgs_cdr/msg_traits.hpp"

namespace ppf::dds {

// A validated cloud on its way to the core, with the times its latency is split by.
struct ScanItem {
  // Returns its buffer to the pool when the last holder lets go (queue, executor, outputs).
  std::shared_ptr<sensor_msgs::msg::PointCloud2> msg;
  std::chrono::steady_clock::time_point received;  // listener entry, before take + decode
  std::chrono::steady_clock::time_point queued;    // pushed into the scan queue
  int64_t core_busy_ns_at_queue = 0;               // NodeStats::core_busy_ns() when queued
};

// An IMU sample with the time it was queued: the executor hands both streams to the core in the
// order they arrived (CoreExecutor::Run), whatever backlog the core has built meanwhile.
struct ImuItem {
  ImuSample sample;
  std::chrono::steady_clock::time_point queued;
};

using ScanQueue = TimeOrderedQueue<ScanItem>;
using ImuQueue = TimeOrderedQueue<ImuItem>;

class NodeInputs {
 public:
  NodeInputs(const NodeConfig& config, NodeStats* stats);
  ~NodeInputs();
  NodeInputs(const NodeInputs&) = delete;
  NodeInputs& operator=(const NodeInputs&) = delete;

  // The validating PointCloud2 type, shared with the registered_points writer (one type name per
  // participant).
  eprosima::fastdds::dds::TypeSupport* cloud_type() { return &cloud_type_; }

  // Registers the input types and creates the topics and readers: data flows as soon as this
  // returns, so call it last. The participant must be torn down before this object goes away.
  bool Create(eprosima::fastdds::dds::DomainParticipant* participant,
              eprosima::fastdds::dds::Subscriber* subscriber, std::string* error);

  // Called on the IMU listener thread with each valid sample after it is queued for the core:
  // the sample, its message's header stamp and when the listener took it. Set before Create().
  using ImuObserver = std::function<void(const ImuSample&, const builtin_interfaces::msg::Time&,
                                         std::chrono::steady_clock::time_point)>;
  void SetImuObserver(ImuObserver observer) { imu_observer_ = std::move(observer); }

  // Samples taken from now on are discarded (shutdown: what is queued is still processed).
  void StopAccepting() { accepting_ = false; }

  ScanQueue& scans() { return scan_queue_; }
  ImuQueue& imus() { return imu_queue_; }
  QueueFill Fill() const;

  // Reports the suppressed tails of the rate-limited input logs.
  void FlushLogs();

  // Diagnostics thread only: logs stall episodes starting, growing and ending, and counts the
  // ones after data had flowed. Returns the streams stalled now ("points", "imu", "points+imu")
  // or "" for the status line.
  std::string CheckStalls();

 private:
  class CloudPool;
  class CloudListener;
  class ImuListener;

  void OnClouds(eprosima::fastdds::dds::DataReader* reader);
  void OnImu(eprosima::fastdds::dds::DataReader* reader);
  void ReportTooLarge(const std::string& points);  // counted and logged, rate-limited
  bool CheckCloudUsable(const sensor_msgs::msg::PointCloud2& m, double stamp);
  void NoteUnusualCloud(const sensor_msgs::msg::PointCloud2& m);  // counted, each kind said once

  const NodeConfig config_;
  NodeStats* const stats_;
  // Shared with every pooled message's deleter, so a message may outlive this object.
  std::shared_ptr<CloudPool> pool_;
  ScanQueue scan_queue_;
  ImuQueue imu_queue_;
  std::atomic<bool> accepting_{true};
  ImuObserver imu_observer_;

  eprosima::fastdds::dds::TypeSupport cloud_type_;
  eprosima::fastdds::dds::TypeSupport imu_type_;
  std::unique_ptr<CloudListener> cloud_listener_;
  std::unique_ptr<ImuListener> imu_listener_;
  GapCounter cloud_gaps_, imu_gaps_;  // each used by its reader's listener only

  // One limiter per kind of defect, so that one kind's burst does not hide another's line.
  RateLimitedLog malformed_log_, imu_malformed_log_, drop_log_, empty_log_, large_log_, stamp_log_,
      jump_log_;
  RateLimitedLog lost_log_{1.0};
  // Unusual but usable clouds (NoteUnusualCloud): whether each kind was named yet.
  std::atomic<bool> said_row_step_zero_{false}, said_many_fields_{false},
      said_long_frame_id_{false};
  // Matched-but-silent watch per stream: listeners mark samples and matches, the diagnostics
  // thread polls (CheckStalls).
  StallWatch points_stall_, imu_stall_;
};

}  // namespace ppf::dds
