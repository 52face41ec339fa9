#include "ppf_bridge/odometry.hpp"

#include <Eigen/Geometry>

#include "ppf_bridge/convert.hpp"
#include "ppf_msgs_cdr/time.hpp"

namespace ppf::bridge {

namespace {

geometry_msgs::msg::Quaternion ToQuaternionMsg(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  geometry_msgs::msg::Quaternion out;
  out.x(q.x());
  out.y(q.y());
  out.z(q.z());
  out.w(q.w());
  return out;
}

geometry_msgs::msg::Pose ToPoseMsg(const Eigen::Isometry3d& T) {
  geometry_msgs::msg::Pose pose;
  pose.position().x(T.translation().x());
  pose.position().y(T.translation().y());
  pose.position().z(T.translation().z());
  pose.orientation(ToQuaternionMsg(T.linear()));
  return pose;
}

}  // namespace

nav_msgs::msg::Odometry ToOdometryMsg(const ScanResult& result, const OdometryFrames& frames,
                                      double angular_velocity_variance) {
  const Eigen::Vector3d& angular_velocity_imu = result.angular_velocity;
  nav_msgs::msg::Odometry odom;
  odom.header().stamp(msgs::TimeFromSeconds(result.stamp_s));
  odom.header().frame_id(frames.odom_frame);
  odom.child_frame_id(frames.base_frame);
  odom.pose().pose(ToPoseMsg(result.T_world_imu));

  // Core pose covariance is [rot, pos] (body-frame rotation error); ROS wants [pos, rot].
  const int core_index[6] = {3, 4, 5, 0, 1, 2};
  auto& pc = odom.pose().covariance();
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c)
      pc[r * 6 + c] = result.pose_covariance(core_index[r], core_index[c]);
  }

  // Twist in the child frame: v_imu = R_world_imu^T v_world.
  const Eigen::Matrix3d R_imu_world = result.T_world_imu.linear().transpose();
  const Eigen::Vector3d v_imu = R_imu_world * result.velocity_world;
  odom.twist().twist().linear().x(v_imu.x());
  odom.twist().twist().linear().y(v_imu.y());
  odom.twist().twist().linear().z(v_imu.z());
  odom.twist().twist().angular().x(angular_velocity_imu.x());
  odom.twist().twist().angular().y(angular_velocity_imu.y());
  odom.twist().twist().angular().z(angular_velocity_imu.z());
  const Eigen::Matrix3d P_vv = result.covariance.block<3, 3>(kVel, kVel);  // world frame
  const Eigen::Matrix3d P_vv_imu = R_imu_world * P_vv * R_imu_world.transpose();
  auto& tc = odom.twist().covariance();
  tc.fill(0.0);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) tc[r * 6 + c] = P_vv_imu(r, c);
  }
  for (int i = 3; i < 6; ++i) tc[i * 6 + i] = angular_velocity_variance;
  return odom;
}

tf2_msgs::msg::TFMessage ToTfMessage(const ScanResult& result, const OdometryFrames& frames) {
  geometry_msgs::msg::TransformStamped t;
  t.header().stamp(msgs::TimeFromSeconds(result.stamp_s));
  t.header().frame_id(frames.odom_frame);
  t.child_frame_id(frames.base_frame);
  const Eigen::Vector3d& p = result.T_world_imu.translation();
  t.transform().translation().x(p.x());
  t.transform().translation().y(p.y());
  t.transform().translation().z(p.z());
  t.transform().rotation(ToQuaternionMsg(result.T_world_imu.linear()));
  tf2_msgs::msg::TFMessage msg;
  msg.transforms().push_back(t);
  return msg;
}

geometry_msgs::msg::PoseStamped ToPoseStamped(const ScanResult& result,
                                              const std::string& frame_id) {
  geometry_msgs::msg::PoseStamped ps;
  ps.header().stamp(msgs::TimeFromSeconds(result.stamp_s));
  ps.header().frame_id(frame_id);
  ps.pose(ToPoseMsg(result.T_world_imu));
  return ps;
}

}  // namespace ppf::bridge
