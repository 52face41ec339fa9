// The thin serialization layer: scans and IMU samples to ROS 2 CDR (through ppf_msgs_cdr) and
// into a rosbag2 directory (through ppf_bag). No generated message type appears here, so users
// of the generator do not compile against Fast DDS headers.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ppf_sim/cloud_buffer.hpp"

namespace ppf::bag {
class Writer;
}

namespace ppf::sim {

struct ImuMessage {
  int64_t stamp_ns = 0;
  std::string frame_id = "imu";
  double gyro[3] = {0, 0, 0};   // rad/s
  double accel[3] = {0, 0, 0};  // m/s^2
  double gyro_var = 0.0;        // per-axis variance written on the covariance diagonal
  double accel_var = 0.0;
};

std::vector<uint8_t> EncodePointCloud2(const CloudBuffer& cloud);
std::vector<uint8_t> EncodeImu(const ImuMessage& imu);
// Round trip for tests and tools; false (with a reason) for a malformed payload.
bool DecodePointCloud2(const uint8_t* data, size_t size, CloudBuffer* out, std::string* error);
bool DecodeImu(const uint8_t* data, size_t size, ImuMessage* out, std::string* error);

struct BagOutputOptions {
  std::string storage = "mcap";       // mcap | sqlite3
  std::string compression = "none";   // mcap chunks: none | lz4 | zstd
  std::string points_topic = "/points";
  std::string imu_topic = "/imu";
};

// Bag time (the "receive" timestamp rosbag2 stores) is chosen by the caller: the simulator uses
// the scan end for clouds (when a driver would publish it) and the stamp for IMU samples.
class BagOutput {
 public:
  BagOutput(const std::string& dir, const BagOutputOptions& opt);
  ~BagOutput();
  void WriteCloud(const CloudBuffer& cloud, int64_t bag_time_ns);
  void WriteImu(const ImuMessage& imu, int64_t bag_time_ns);
  void Close();
  uint64_t clouds() const { return clouds_; }
  uint64_t imus() const { return imus_; }
  uint64_t bytes() const { return bytes_; }

 private:
  std::unique_ptr<ppf::bag::Writer> writer_;
  BagOutputOptions opt_;
  uint64_t clouds_ = 0, imus_ = 0, bytes_ = 0;
};

// Importers: writes the time-sorted samples from *next on with stamp t <= until_ns as Imu messages
// (bag time = stamp) and advances *next, so IMU and clouds interleave in time. Sample needs
// `int64_t t` (ns) and `double w[3], a[3]`. Returns the number written.
template <typename Sample>
size_t WriteImuUntil(BagOutput& bag, const std::vector<Sample>& samples, size_t* next,
                     int64_t until_ns, const std::string& frame_id) {
  ImuMessage msg;
  msg.frame_id = frame_id;
  size_t written = 0;
  for (; *next < samples.size() && samples[*next].t <= until_ns; ++*next, ++written) {
    const Sample& s = samples[*next];
    msg.stamp_ns = s.t;
    std::copy(s.w, s.w + 3, msg.gyro);
    std::copy(s.a, s.a + 3, msg.accel);
    bag.WriteImu(msg, msg.stamp_ns);
  }
  return written;
}

// Offered QoS as rosbag2 (Humble) records it: reliable, volatile, keep last. Reliable so that
// `ros2 bag play` output matches both reliable and best-effort subscribers.
const char* RecordedQosYaml();

}  // namespace ppf::sim
