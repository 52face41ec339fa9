#include "ppf_sim/bag_output.hpp"

#include "ppf_bag/bag.hpp"
#include "ppf_msgs_cdr/cdr.hpp"
#include "ppf_msgs_cdr/time.hpp"
#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/PointCloud2.h"

namespace ppf::sim {

std::vector<uint8_t> EncodePointCloud2(const CloudBuffer& c) {
  sensor_msgs::msg::PointCloud2 msg;
  msg.header().stamp(msgs::TimeFromNanoseconds(c.stamp_ns));
  msg.header().frame_id(c.frame_id);
  msg.height(c.height);
  msg.width(c.width);
  msg.fields().reserve(c.fields.size());
  for (const PointFieldDesc& f : c.fields) {
    sensor_msgs::msg::PointField pf;
    pf.name(f.name);
    pf.offset(f.offset);
    pf.datatype(f.datatype);
    pf.count(f.count);
    msg.fields().push_back(pf);
  }
  msg.is_bigendian(c.is_bigendian);
  msg.point_step(c.point_step);
  msg.row_step(c.row_step);
  msg.data(c.data);
  msg.is_dense(c.is_dense);
  return msgs::EncodeCdr(msg);
}

std::vector<uint8_t> EncodeImu(const ImuMessage& m) {
  sensor_msgs::msg::Imu msg;
  msg.header().stamp(msgs::TimeFromNanoseconds(m.stamp_ns));
  msg.header().frame_id(m.frame_id);
  // No orientation estimate (REP 145: -1 in the first covariance element).
  msg.orientation().w(1.0);
  msg.orientation_covariance()[0] = -1.0;
  msg.angular_velocity().x(m.gyro[0]);
  msg.angular_velocity().y(m.gyro[1]);
  msg.angular_velocity().z(m.gyro[2]);
  msg.linear_acceleration().x(m.accel[0]);
  msg.linear_acceleration().y(m.accel[1]);
  msg.linear_acceleration().z(m.accel[2]);
  for (int k = 0; k < 3; ++k) {
    msg.angular_velocity_covariance()[4 * k] = m.gyro_var;
    msg.linear_acceleration_covariance()[4 * k] = m.accel_var;
  }
  return msgs::EncodeCdr(msg);
}

bool DecodePointCloud2(const uint8_t* data, size_t size, CloudBuffer* out, std::string* error) {
  sensor_msgs::msg::PointCloud2 msg;
  if (!msgs::DecodeCdr(data, size, &msg, error)) return false;
  out->stamp_ns = msgs::ToNanoseconds(msg.header().stamp());
  out->frame_id = msg.header().frame_id();
  out->height = msg.height();
  out->width = msg.width();
  out->fields.clear();
  for (const auto& f : msg.fields()) {
    out->fields.push_back({f.name(), f.offset(), f.datatype(), f.count()});
  }
  out->is_bigendian = msg.is_bigendian();
  out->point_step = msg.point_step();
  out->row_step = msg.row_step();
  out->data = std::move(msg.data());
  out->is_dense = msg.is_dense();
  return true;
}

bool DecodeImu(const uint8_t* data, size_t size, ImuMessage* out, std::string* error) {
  sensor_msgs::msg::Imu msg;
  if (!msgs::DecodeCdr(data, size, &msg, error)) return false;
  out->stamp_ns = msgs::ToNanoseconds(msg.header().stamp());
  out->frame_id = msg.header().frame_id();
  out->gyro[0] = msg.angular_velocity().x();
  out->gyro[1] = msg.angular_velocity().y();
  out->gyro[2] = msg.angular_velocity().z();
  out->accel[0] = msg.linear_acceleration().x();
  out->accel[1] = msg.linear_acceleration().y();
  out->accel[2] = msg.linear_acceleration().z();
  out->gyro_var = msg.angular_velocity_covariance()[0];
  out->accel_var = msg.linear_acceleration_covariance()[0];
  return true;
}

const char* RecordedQosYaml() {
  return "- history: 3\n"
         "  depth: 0\n"
         "  reliability: 1\n"
         "  durability: 2\n"
         "  deadline:\n"
         "    sec: 2147483647\n"
         "    nsec: 4294967295\n"
         "  lifespan:\n"
         "    sec: 2147483647\n"
         "    nsec: 4294967295\n"
         "  liveliness: 1\n"
         "  liveliness_lease_duration:\n"
         "    sec: 2147483647\n"
         "    nsec: 4294967295\n"
         "  avoid_ros_namespace_conventions: false";
}

BagOutput::BagOutput(const std::string& dir, const BagOutputOptions& opt) : opt_(opt) {
  bag::WriterOptions wo;
  if (opt.storage == "mcap") {
    wo.storage = bag::Storage::kMcap;
  } else if (opt.storage == "sqlite3" || opt.storage == "db3") {
    wo.storage = bag::Storage::kSqlite3;
  } else {
    throw std::invalid_argument("unknown storage '" + opt.storage + "' (mcap, sqlite3)");
  }
  wo.compression = opt.compression;
  writer_ = std::make_unique<bag::Writer>(dir, wo);
  writer_->AddTopic({opt.points_topic, "sensor_msgs/msg/PointCloud2", "cdr", RecordedQosYaml()});
  writer_->AddTopic({opt.imu_topic, "sensor_msgs/msg/Imu", "cdr", RecordedQosYaml()});
}

BagOutput::~BagOutput() = default;

void BagOutput::WriteCloud(const CloudBuffer& cloud, int64_t bag_time_ns) {
  const std::vector<uint8_t> payload = EncodePointCloud2(cloud);
  writer_->Write(opt_.points_topic, bag_time_ns, payload);
  ++clouds_;
  bytes_ += payload.size();
}

void BagOutput::WriteImu(const ImuMessage& imu, int64_t bag_time_ns) {
  const std::vector<uint8_t> payload = EncodeImu(imu);
  writer_->Write(opt_.imu_topic, bag_time_ns, payload);
  ++imus_;
  bytes_ += payload.size();
}

void BagOutput::Close() { writer_->Close(); }

}  // namespace ppf::sim
