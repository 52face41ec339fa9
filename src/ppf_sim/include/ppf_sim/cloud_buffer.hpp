// A scan in sensor_msgs/PointCloud2 memory layout, independent of any message library, so the
// generator is testable without serialization and the bag layer is a thin copy on top.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace ppf::sim {

// sensor_msgs/PointField datatype constants.
enum : uint8_t { kInt8 = 1, kUint8 = 2, kInt16 = 3, kUint16 = 4, kInt32 = 5, kUint32 = 6,
                 kFloat32 = 7, kFloat64 = 8 };

struct PointFieldDesc {
  std::string name;
  uint32_t offset = 0;
  uint8_t datatype = kFloat32;
  uint32_t count = 1;
};

struct CloudBuffer {
  int64_t stamp_ns = 0;  // header.stamp: scan start
  std::string frame_id;
  uint32_t height = 1;
  uint32_t width = 0;
  std::vector<PointFieldDesc> fields;
  bool is_bigendian = false;
  uint32_t point_step = 0;
  uint32_t row_step = 0;
  std::vector<uint8_t> data;
  bool is_dense = true;

  size_t num_points() const { return static_cast<size_t>(width) * height; }
  const PointFieldDesc* Field(const std::string& name) const {
    for (const auto& f : fields)
      if (f.name == name) return &f;
    return nullptr;
  }
  template <typename T>
  T Get(size_t index, const PointFieldDesc& f) const {
    T v;
    std::memcpy(&v, data.data() + index * point_step + f.offset, sizeof(T));
    return v;
  }
};

}  // namespace ppf::sim
