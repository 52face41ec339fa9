#include "ppf_bridge/convert.hpp"

#include <cmath>

namespace ppf::bridge {

double ToSeconds(const builtin_interfaces::msg::Time& t) {
  return static_cast<double>(t.sec()) + 1e-9 * static_cast<double>(t.nanosec());
}

int64_t ToNanoseconds(const builtin_interfaces::msg::Time& t) {
  return static_cast<int64_t>(t.sec()) * 1000000000LL + static_cast<int64_t>(t.nanosec());
}

builtin_interfaces::msg::Time TimeFromNanoseconds(int64_t ns) {
  // Floor division so that negative times keep 0 <= nanosec < 1e9, as rclcpp does.
  int64_t sec = ns / 1000000000LL;
  int64_t rem = ns % 1000000000LL;
  if (rem < 0) {
    rem += 1000000000LL;
    sec -= 1;
  }
  builtin_interfaces::msg::Time t;
  t.sec(static_cast<int32_t>(sec));
  t.nanosec(static_cast<uint32_t>(rem));
  return t;
}

builtin_interfaces::msg::Time TimeFromSeconds(double s) {
  return TimeFromNanoseconds(static_cast<int64_t>(std::llround(s * 1e9)));
}

std::optional<CloudView> ToCloudView(const sensor_msgs::msg::PointCloud2& msg, std::string* error) {
  CloudView view;
  view.stamp_s = ToSeconds(msg.header().stamp());
  view.frame_id = msg.header().frame_id();
  view.height = msg.height();
  view.width = msg.width();
  view.point_step = msg.point_step();
  view.row_step = msg.row_step();
  view.is_bigendian = msg.is_bigendian();
  view.fields.reserve(msg.fields().size());
  for (const auto& f : msg.fields()) {
    if (f.datatype() < 1 || f.datatype() > 8) {
      if (error) *error = "field '" + f.name() + "' has unknown datatype " + std::to_string(f.datatype());
      return std::nullopt;
    }
    view.fields.push_back(FieldDesc{f.name(), f.offset(), static_cast<FieldType>(f.datatype()), f.count()});
  }
  view.data = msg.data().data();
  view.size = msg.data().size();
  return view;
}

std::optional<ImuSample> ToImuSample(const sensor_msgs::msg::Imu& msg, std::string* error) {
  ImuSample s;
  s.stamp_s = ToSeconds(msg.header().stamp());
  const auto& w = msg.angular_velocity();
  const auto& a = msg.linear_acceleration();
  s.angular_velocity = Eigen::Vector3d(w.x(), w.y(), w.z());
  s.linear_acceleration = Eigen::Vector3d(a.x(), a.y(), a.z());
  if (!s.angular_velocity.allFinite() || !s.linear_acceleration.allFinite()) {
    if (error) *error = "IMU sample has non-finite angular velocity or acceleration";
    return std::nullopt;
  }
  return s;
}

sensor_msgs::msg::Imu ToImuMsg(const ImuSample& sample, const std::string& frame_id) {
  sensor_msgs::msg::Imu msg;
  msg.header().stamp(TimeFromSeconds(sample.stamp_s));
  msg.header().frame_id(frame_id);
  // No orientation estimate: REP 145 says so with -1 in the first covariance element.
  msg.orientation().w(1.0);
  msg.orientation_covariance()[0] = -1.0;
  msg.angular_velocity().x(sample.angular_velocity.x());
  msg.angular_velocity().y(sample.angular_velocity.y());
  msg.angular_velocity().z(sample.angular_velocity.z());
  msg.linear_acceleration().x(sample.linear_acceleration.x());
  msg.linear_acceleration().y(sample.linear_acceleration.y());
  msg.linear_acceleration().z(sample.linear_acceleration.z());
  return msg;
}

}  // namespace ppf::bridge
