// NodeOutputs: what the node publishes per scan (odometry, TF, path, skeleton planes, registered
// points) and the TUM trajectory it writes at shutdown. Used by the executor thread only (and by
// run() once that thread has been joined), so it needs no lock.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "ppf_core/lio_ppf.hpp"
#include "ppf_dds_node/node_config.hpp"
#include "ppf_msgs_cdr/msg_traits.hpp"
#include "ppf_trajectory/trajectory_io.hpp"

namespace ppf::dds {

class NodeOutputs {
 public:
  explicit NodeOutputs(const NodeConfig& config) : config_(config) {}

  // Registers the output types and creates the configured writers (ROS 2 QoS conventions,
  // ROS2-INTEROP.md). `cloud_type` is the input's validating PointCloud2 type: a type name can
  // only be registered once per participant, and the reader must keep the validating one.
  bool Create(eprosima::fastdds::dds::DomainParticipant* participant,
              eprosima::fastdds::dds::Publisher* publisher,
              eprosima::fastdds::dds::TypeSupport* cloud_type, std::string* error);

  // Writes every configured output of a result with a valid pose (registered_points from its
  // deskewed_points_lidar: the core fills them when that output is on, CreateCore).
  void Publish(const ScanResult& r);

  // The poses published so far, as a TUM file (config tum_file).
  bool WriteTum(std::string* error) const;
  size_t trajectory_size() const { return trajectory_.size(); }

  // Gives reliable readers a moment to receive the last outputs before the writers go away.
  void WaitForAcknowledgments();

 private:
  void PublishRegistered(const ScanResult& r);

  const NodeConfig config_;
  eprosima::fastdds::dds::DataWriter* odometry_writer_ = nullptr;
  eprosima::fastdds::dds::DataWriter* tf_writer_ = nullptr;
  eprosima::fastdds::dds::DataWriter* path_writer_ = nullptr;
  eprosima::fastdds::dds::DataWriter* planes_writer_ = nullptr;
  eprosima::fastdds::dds::DataWriter* registered_writer_ = nullptr;
  eprosima::fastdds::dds::TypeSupport odom_type_{new nav_msgs::msg::OdometryPubSubType()};
  eprosima::fastdds::dds::TypeSupport tf_type_{new tf2_msgs::msg::TFMessagePubSubType()};
  eprosima::fastdds::dds::TypeSupport path_type_{new nav_msgs::msg::PathPubSubType()};
  eprosima::fastdds::dds::TypeSupport planes_type_{
      new ppf_msgs::msg::SkeletonPlaneArrayPubSubType()};
  nav_msgs::msg::Path path_;
  Trajectory trajectory_;  // T_world_imu per published scan
};

}  // namespace ppf::dds
