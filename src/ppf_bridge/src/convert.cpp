#include "ppf_bridge/convert.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string_view>
#include <vector>

#include "ppf_core/lio/time_field.hpp"
#include "ppf_msgs_cdr/time.hpp"

namespace ppf::bridge {

std::string CheckStamp(const builtin_interfaces::msg::Time& stamp) {
  // A nanosecond part of a second or more is no time any clock writes: converted as it stands it
  // would move the message seconds ahead (up to 4.3 s), and every later message would look late.
  if (stamp.nanosec() < kNanosecPerSecond) return "";
  return "header.stamp.nanosec " + std::to_string(stamp.nanosec()) +
         " is out of range (must be < 1000000000; stamp sec " + std::to_string(stamp.sec()) + ")";
}

std::optional<CloudView> ToCloudView(const sensor_msgs::msg::PointCloud2& msg, std::string* error) {
  CloudView view;
  view.stamp_s = msgs::ToSeconds(msg.header().stamp());
  view.frame_id = msg.header().frame_id();
  view.height = msg.height();
  view.width = msg.width();
  view.point_step = msg.point_step();
  view.row_step = msg.row_step();
  view.is_bigendian = msg.is_bigendian();
  view.fields.reserve(msg.fields().size());
  auto fail = [error](const std::string& why) {
    if (error) *error = why;
    return std::nullopt;
  };
  if (std::string stamp = CheckStamp(msg.header().stamp()); !stamp.empty()) return fail(stamp);
  // Said apart from "lacks an x, y or z field": a writer that filled in no field table at all is
  // a different bug than one that named its fields differently.
  if (msg.fields().empty() && msg.width() * static_cast<uint64_t>(msg.height()) > 0) {
    return fail("cloud declares no fields (x, y and z are needed)");
  }
  for (const auto& f : msg.fields()) {
    if (f.datatype() < 1 || f.datatype() > 8) {
      return fail("field '" + f.name() + "' has unknown datatype " + std::to_string(f.datatype()));
    }
    const FieldDesc desc{f.name(), f.offset(), static_cast<FieldType>(f.datatype()), f.count()};
    // Every field must lie inside the point, not only the ones the core reads: a field beyond
    // point_step means point_step or the offsets are wrong, so no field can be trusted.
    const uint64_t end = static_cast<uint64_t>(desc.offset) +
                         FieldTypeSize(desc.type) * std::max<uint64_t>(desc.count, 1);
    if (end > msg.point_step()) {
      return fail("field '" + f.name() + "' (offset " + std::to_string(desc.offset) + ", " +
                  std::to_string(end - desc.offset) + " bytes) lies beyond point_step " +
                  std::to_string(msg.point_step()));
    }
    view.fields.push_back(desc);
  }
  // Readers take the first field of a name; a second one means the writer's layout is not what
  // either of them describes. Sorted, not compared pairwise: a table of thousands of fields must
  // not cost the listener quadratic time.
  {
    std::vector<std::string_view> names;
    names.reserve(view.fields.size());
    for (const FieldDesc& d : view.fields) names.emplace_back(d.name);
    std::sort(names.begin(), names.end());
    const auto dup = std::adjacent_find(names.begin(), names.end());
    if (dup != names.end()) return fail("duplicate field '" + std::string(*dup) + "'");
  }
  view.data = msg.data().data();
  view.size = msg.data().size();
  // The core's rules (x/y/z present and float, little endian, rows and data large enough).
  const std::string layout = ValidateCloudLayout(view);
  if (!layout.empty()) return fail(layout);
  // More data than the header declares is as inconsistent as less: one of them is wrong, and
  // reading the declared part could be reading the wrong points.
  const uint64_t row_step =
      msg.row_step() == 0 ? static_cast<uint64_t>(msg.width()) * msg.point_step() : msg.row_step();
  const uint64_t declared = row_step * msg.height();
  if (view.size != declared) {
    return fail("size mismatch: " + std::to_string(view.size) + " bytes of data, header declares " +
                std::to_string(declared) + " (height " + std::to_string(msg.height()) +
                " x row_step " + std::to_string(row_step) + ")");
  }
  return view;
}

std::optional<ImuSample> ToImuSample(const sensor_msgs::msg::Imu& msg, std::string* error) {
  if (std::string stamp = CheckStamp(msg.header().stamp()); !stamp.empty()) {
    if (error) *error = "IMU sample's " + stamp;
    return std::nullopt;
  }
  ImuSample s;
  s.stamp_s = msgs::ToSeconds(msg.header().stamp());
  const auto& w = msg.angular_velocity();
  const auto& a = msg.linear_acceleration();
  s.angular_velocity = Eigen::Vector3d(w.x(), w.y(), w.z());
  s.linear_acceleration = Eigen::Vector3d(a.x(), a.y(), a.z());
  if (!s.angular_velocity.allFinite() || !s.linear_acceleration.allFinite()) {
    if (error) *error = "IMU sample has non-finite angular velocity or acceleration";
    return std::nullopt;
  }
  // An uninitialized message (driver start-up, a zeroed struct): no real accelerometer reads
  // exactly zero on all axes while its gyro also does, and stamp 0 would end the static start.
  if (s.angular_velocity.isZero(0.0) && s.linear_acceleration.isZero(0.0)) {
    if (error) *error = "IMU sample is all zeros (uninitialized message?)";
    return std::nullopt;
  }
  if (!(s.stamp_s > 0.0)) {
    if (error) *error = "IMU sample has stamp " + std::to_string(s.stamp_s) + " (unset clock?)";
    return std::nullopt;
  }
  // One integrated sample beyond any robot IMU's full scale (+-2000 deg/s, +-16 g; a few high-g
  // parts reach 20 g) corrupts velocity and attitude for good: refuse it.
  if (s.angular_velocity.cwiseAbs().maxCoeff() > kImuMaxAngularVelocity ||
      s.linear_acceleration.cwiseAbs().maxCoeff() > kImuMaxAcceleration) {
    std::ostringstream os;
    os << "IMU sample beyond any IMU's range (|w|max " << s.angular_velocity.cwiseAbs().maxCoeff()
       << " rad/s, limit " << kImuMaxAngularVelocity << "; |a|max "
       << s.linear_acceleration.cwiseAbs().maxCoeff() << " m/s^2, limit " << kImuMaxAcceleration
       << ")";
    if (error) *error = os.str();
    return std::nullopt;
  }
  return s;
}

sensor_msgs::msg::Imu ToImuMsg(const ImuSample& sample, const std::string& frame_id) {
  sensor_msgs::msg::Imu msg;
  msg.header().stamp(msgs::TimeFromSeconds(sample.stamp_s));
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
