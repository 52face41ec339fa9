#include "imu_rate_output.hpp"

#include <optional>

#include "ppf_bridge/odometry.hpp"
#include "ppf_dds_node/dds_common.hpp"

namespace ppf::dds {

namespace fdds = eprosima::fastdds::dds;

namespace {

ImuRateOdometry::Options OptionsFromCore(const Config& core) {
  ImuRateOdometry::Options o;
  o.noise = core.imu.noise;
  o.acc_scale = core.imu.init.acc_scale;
  return o;
}

}  // namespace

ImuRateOutput::ImuRateOutput(const NodeConfig& config, const Config& core, NodeStats* stats)
    : config_(config), stats_(stats), odometry_(OptionsFromCore(core)) {}

bool ImuRateOutput::Create(fdds::DomainParticipant* participant, fdds::Publisher* publisher,
                           std::string* error) {
  // The /odometry writer registered this type already (same name, same serializer).
  if (participant->find_type(odom_type_.get_type_name()).empty() &&
      odom_type_.register_type(participant) != ReturnCode_t::RETCODE_OK) {
    *error = "cannot register type " + odom_type_.get_type_name();
    return false;
  }
  const std::string topic_name = RosTopicToDds(config_.odometry_imu_rate_topic);
  fdds::Topic* topic =
      participant->create_topic(topic_name, odom_type_.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  if (!topic) {
    *error = "cannot create topic " + topic_name;
    return false;
  }
  writer_ = publisher->create_datawriter(topic, DefaultWriterQos(10));
  if (!writer_) {
    *error = "cannot create writer on " + topic_name;
    return false;
  }
  return true;
}

void ImuRateOutput::OnImu(const ImuSample& sample, const builtin_interfaces::msg::Time& stamp,
                          std::chrono::steady_clock::time_point received) {
  std::optional<ImuRateOdometry::State> state;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    state = odometry_.AddImu(sample);
  }
  if (!state || !writer_) return;
  // The result type carries what /odometry is made of: one conversion, the same conventions.
  ScanResult r;
  r.stamp_s = state->stamp_s;
  r.T_world_imu = state->T_world_imu;
  r.velocity_world = state->velocity_world;
  r.angular_velocity = state->angular_velocity;
  r.covariance = state->covariance;
  r.pose_covariance = state->covariance.topLeftCorner<6, 6>();
  nav_msgs::msg::Odometry odom =
      bridge::ToOdometryMsg(r, bridge::OdometryFrames{config_.odom_frame, config_.base_frame});
  // The IMU message's own stamp: its seconds as a double are a few hundred nanoseconds off.
  odom.header().stamp(stamp);
  writer_->write(&odom);
  stats_->AddImuRatePublished(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - received)
          .count());
}

void ImuRateOutput::OnResult(const ScanResult& result) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (result.status == Status::kReset) {
    odometry_.Invalidate(true);
  } else if (result.pose_valid) {
    odometry_.Reset(result);
  }
}

void ImuRateOutput::WaitForAcknowledgments() {
  if (writer_) writer_->wait_for_acknowledgments({1, 0});
}

void ImuRateOutput::OnCoreRestart() {
  std::lock_guard<std::mutex> lock(mutex_);
  odometry_.Invalidate(true);
}

}  // namespace ppf::dds
