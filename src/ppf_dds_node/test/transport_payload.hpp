// Deterministic message contents for the cross-process transport test: publisher and subscriber
// regenerate the same bytes from a sequence number, so the subscriber checks every byte.
#pragma once

#include <cstdint>
#include <string>

#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/PointCloud2.h"

namespace ppf::test {

constexpr int kTransportClouds = 20;
constexpr int kTransportImus = 200;
// 65536 points x 32 B = 2 MiB of point data per cloud.
constexpr uint32_t kTransportCloudPoints = 65536;
constexpr uint32_t kTransportPointStep = 32;

inline uint64_t SplitMix64(uint64_t* state) {
  uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

inline sensor_msgs::msg::PointCloud2 MakeTransportCloud(int seq) {
  sensor_msgs::msg::PointCloud2 msg;
  msg.header().stamp().sec(seq);
  msg.header().stamp().nanosec(static_cast<uint32_t>(seq) * 1000u);
  msg.header().frame_id("lidar_" + std::to_string(seq));
  msg.height(1);
  msg.width(kTransportCloudPoints);
  const char* names[] = {"x", "y", "z", "intensity"};
  for (uint32_t i = 0; i < 4; ++i) {
    sensor_msgs::msg::PointField f;
    f.name(names[i]);
    f.offset(4 * i);
    f.datatype(7);  // FLOAT32
    f.count(1);
    msg.fields().push_back(f);
  }
  msg.is_bigendian(false);
  msg.point_step(kTransportPointStep);
  msg.row_step(kTransportPointStep * kTransportCloudPoints);
  std::vector<uint8_t>& data = msg.data();
  data.resize(static_cast<size_t>(kTransportPointStep) * kTransportCloudPoints);
  uint64_t state = 0x1234567800000000ull + static_cast<uint64_t>(seq);
  for (size_t i = 0; i < data.size(); i += 8) {
    const uint64_t v = SplitMix64(&state);
    for (size_t k = 0; k < 8; ++k) data[i + k] = static_cast<uint8_t>(v >> (8 * k));
  }
  msg.is_dense(true);
  return msg;
}

inline sensor_msgs::msg::Imu MakeTransportImu(int seq) {
  sensor_msgs::msg::Imu msg;
  msg.header().stamp().sec(seq / 200);
  msg.header().stamp().nanosec(static_cast<uint32_t>(seq % 200) * 5000000u);
  msg.header().frame_id("imu");
  msg.angular_velocity().x(0.001 * seq);
  msg.angular_velocity().y(-0.002 * seq);
  msg.angular_velocity().z(0.5);
  msg.linear_acceleration().x(0.01 * seq);
  msg.linear_acceleration().y(0.0);
  msg.linear_acceleration().z(9.81);
  msg.orientation().w(1.0);
  for (int i = 0; i < 9; ++i) msg.linear_acceleration_covariance()[i] = seq + i;
  return msg;
}

}  // namespace ppf::test
