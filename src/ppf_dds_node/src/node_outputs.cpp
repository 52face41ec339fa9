#include "node_outputs.hpp"

#include <cmath>
#include <cstring>

#include "ppf_bridge/convert.hpp"
#include "ppf_bridge/odometry.hpp"
#include "ppf_bridge/skeleton_planes.hpp"
#include "ppf_dds_node/dds_common.hpp"
#include "ppf_dds_node/validating_type.hpp"
#include "ppf_msgs_cdr/time.hpp"

namespace ppf::dds {

namespace fdds = eprosima::fastdds::dds;

namespace {

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

bool NodeOutputs::Create(fdds::DomainParticipant* participant, fdds::Publisher* publisher,
                         fdds::TypeSupport* cloud_type, std::string* error) {
  const NodeConfig& c = config_;
  odometry_writer_ = CreateWriter(participant, publisher, &odom_type_, c.odometry_topic,
                                  DefaultWriterQos(10), error);
  if (!odometry_writer_) return false;
  if (c.publish_skeleton_planes) {
    planes_writer_ = CreateWriter(participant, publisher, &planes_type_, c.skeleton_planes_topic,
                                  DefaultWriterQos(10), error);
    if (!planes_writer_) return false;
  }
  if (c.publish_tf) {
    tf_writer_ = CreateWriter(participant, publisher, &tf_type_, c.tf_topic, TfWriterQos(), error);
    if (!tf_writer_) return false;
  }
  if (c.publish_path) {
    // Each message is the whole bounded path: only the latest matters.
    path_writer_ =
        CreateWriter(participant, publisher, &path_type_, c.path_topic, DefaultWriterQos(1), error);
    if (!path_writer_) return false;
  }
  if (c.publish_registered_points) {
    // Reliable matches both reliable and best-effort readers (RViz either way); depth 2 bounds
    // the memory held for slow readers.
    registered_writer_ = CreateWriter(participant, publisher, cloud_type, c.registered_points_topic,
                                      DefaultWriterQos(2), error);
    if (!registered_writer_) return false;
  }
  return true;
}

void NodeOutputs::Publish(const ScanResult& r) {
  bridge::OdometryFrames frames{config_.odom_frame, config_.base_frame};
  nav_msgs::msg::Odometry odom = bridge::ToOdometryMsg(r, frames);
  odometry_writer_->write(&odom);
  if (tf_writer_) {
    tf2_msgs::msg::TFMessage tf = bridge::ToTfMessage(r, frames);
    tf_writer_->write(&tf);
  }
  if (path_writer_) {
    path_.poses().push_back(bridge::ToPoseStamped(r, config_.odom_frame));
    if (path_.poses().size() > static_cast<size_t>(config_.path_max_poses)) {
      path_.poses().erase(path_.poses().begin());
    }
    path_.header() = path_.poses().back().header();
    path_writer_->write(&path_);
  }
  if (planes_writer_) {
    // The facade's built-in skeleton tracker (kPpf) reports its world-frame window after each
    // scan; the message carries the planes fitted in this scan (missed_scans == 0), world = odom
    // frame. In kNN mode the message is empty, still one per scan.
    std::vector<SkeletonPlane> fitted;
    for (const SkeletonPlane& sp : r.skeleton_planes) {
      if (sp.missed_scans == 0) fitted.push_back(sp);
    }
    ppf_msgs::msg::SkeletonPlaneArray planes =
        bridge::ToSkeletonPlaneArray(fitted, r.stamp_s, config_.odom_frame);
    planes_writer_->write(&planes);
  }
  if (registered_writer_) PublishRegistered(r);
  trajectory_.push_back({r.stamp_s, r.T_world_imu});
}

// The points the scan was registered with (range-filtered, downsampled, de-skewed to the scan
// end), moved to the odom frame with the scan-end pose: x, y, z float32.
void NodeOutputs::PublishRegistered(const ScanResult& r) {
  // Written through the input's validating type (see Create).
  Validated<sensor_msgs::msg::PointCloud2> wrapped;
  sensor_msgs::msg::PointCloud2& out = wrapped.msg;
  out.header().stamp(msgs::TimeFromSeconds(r.stamp_s));
  out.header().frame_id(config_.odom_frame);
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
  const size_t n = r.deskewed_points_lidar.size();
  std::vector<uint8_t>& data = out.data();
  data.resize(n * 12);
  const Eigen::Isometry3f T_world_lidar = r.T_world_lidar.cast<float>();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f w = T_world_lidar * r.deskewed_points_lidar[i];
    std::memcpy(data.data() + i * 12, w.data(), 12);
  }
  out.width(static_cast<uint32_t>(n));
  out.row_step(static_cast<uint32_t>(n * 12));
  registered_writer_->write(&wrapped);
}

bool NodeOutputs::WriteTum(std::string* error) const {
  // No comment line: the file holds one line per published pose.
  TumWriter writer(config_.tum_file);
  if (!writer.ok()) {
    *error = "cannot write trajectory file '" + config_.tum_file + "'";
    return false;
  }
  for (const StampedPose& pose : trajectory_) writer.Write(pose);
  if (!writer.Close()) {
    *error = "error writing '" + config_.tum_file + "'";
    return false;
  }
  return true;
}

void NodeOutputs::WaitForAcknowledgments() {
  if (odometry_writer_) odometry_writer_->wait_for_acknowledgments({1, 0});
}

}  // namespace ppf::dds
