// A non-owning view of one LiDAR scan in the sensor_msgs/PointCloud2 memory layout.
//
// Why a view and not a PCL cloud: drivers disagree on which fields exist and how per-point time
// is encoded (see time_field.hpp). The core decodes the layout itself, so the DDS node and the
// offline runner hand over the received bytes without a copy and without knowing the conventions.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ppf {

// Values equal sensor_msgs/PointField's constants, so a message's datatype casts directly.
enum class FieldType : uint8_t {
  kInt8 = 1,
  kUint8 = 2,
  kInt16 = 3,
  kUint16 = 4,
  kInt32 = 5,
  kUint32 = 6,
  kFloat32 = 7,
  kFloat64 = 8,
};

// Size in bytes of one element of `type`; 0 for an unknown value (a malformed message).
inline size_t FieldTypeSize(FieldType type) {
  switch (type) {
    case FieldType::kInt8:
    case FieldType::kUint8:
      return 1;
    case FieldType::kInt16:
    case FieldType::kUint16:
      return 2;
    case FieldType::kInt32:
    case FieldType::kUint32:
    case FieldType::kFloat32:
      return 4;
    case FieldType::kFloat64:
      return 8;
  }
  return 0;
}

struct FieldDesc {
  std::string name;
  uint32_t offset = 0;
  FieldType type = FieldType::kFloat32;
  uint32_t count = 1;
};

struct CloudView {
  double stamp_s = 0.0;  // header.stamp in seconds (driver-defined: scan start or end, see config)
  std::string frame_id;
  uint32_t height = 1;
  uint32_t width = 0;
  uint32_t point_step = 0;
  uint32_t row_step = 0;
  bool is_bigendian = false;
  std::vector<FieldDesc> fields;
  const uint8_t* data = nullptr;  // not owned; must outlive the call that receives the view
  size_t size = 0;                // bytes available at `data`
};

}  // namespace ppf
