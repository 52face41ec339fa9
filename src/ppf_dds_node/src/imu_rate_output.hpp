// ImuRateOutput: the odometry at the IMU's rate (topics.odometry_imu_rate), the last scan's
// posterior propagated with each later IMU sample (ppf_core/imu_rate_odometry.hpp).
//
// Threads: the IMU listener propagates and publishes each sample as soon as it is taken, so the
// message waits neither for the executor (busy registering a scan for tens of milliseconds) nor
// for a scan (docs/decisions.md, "IMU-rate odometry on the IMU listener"); the executor hands
// over each result. The propagation is this object's own small copy of the state, not the core:
// the executor stays the only thread touching LioPpf. One mutex guards that copy, held for the
// propagation only, never while calling into Fast DDS.
#pragma once

#include <chrono>
#include <mutex>
#include <string>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "node_stats.hpp"
#include "ppf_core/imu_rate_odometry.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_dds_node/node_config.hpp"
#include "ppf_msgs_cdr/msg_traits.hpp"

namespace ppf::dds {

class ImuRateOutput {
 public:
  // `core` is the core's config: its process noise and accelerometer scale are the filter's.
  ImuRateOutput(const NodeConfig& config, const Config& core, NodeStats* stats);

  // Creates the writer (the /odometry type and QoS). False with `error`.
  bool Create(eprosima::fastdds::dds::DomainParticipant* participant,
              eprosima::fastdds::dds::Publisher* publisher, std::string* error);

  // IMU listener: a validated sample with its message's header stamp, taken at `received`.
  // Publishes its message, stamped `stamp`, if there is a posterior to propagate.
  void OnImu(const ImuSample& sample, const builtin_interfaces::msg::Time& stamp,
             std::chrono::steady_clock::time_point received);

  // Executor: every result the core returns, notices included. A pose starts the propagation
  // from it, a reset ends it; a rejected scan changed nothing in the filter, nor here.
  void OnResult(const ScanResult& result);
  // Executor: the node restarted the core (a time jump): no output until its next pose.
  void OnCoreRestart();

  // Shutdown, listeners stopped: gives reliable readers a moment to receive the last messages.
  void WaitForAcknowledgments();

 private:
  const NodeConfig config_;
  NodeStats* const stats_;
  eprosima::fastdds::dds::TypeSupport odom_type_{new nav_msgs::msg::OdometryPubSubType()};
  eprosima::fastdds::dds::DataWriter* writer_ = nullptr;
  std::mutex mutex_;
  ImuRateOdometry odometry_;  // guarded by mutex_
};

}  // namespace ppf::dds
