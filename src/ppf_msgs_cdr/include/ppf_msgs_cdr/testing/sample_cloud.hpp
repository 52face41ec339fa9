// A small PointCloud2 for the tests of the packages that take messages apart (ppf_msgs_cdr,
// ppf_bridge): installed with the headers so both build it from one place, header-only so a
// library user who never includes it pays nothing.
#pragma once

#include <cstdint>

#include "ppf_msgs_cdr/time.hpp"
#include "sensor_msgs/msg/PointCloud2.h"

namespace ppf::msgs::test_util {

// `n` points, frame "velodyne", stamp 1700000000.123456789 s, dense; fields x, y, z, intensity
// (float32 at 0, 4, 8, 12) and t (uint32 at 16), point_step 20; data byte i is i * 7 (mod 256),
// so every byte is known and no two neighbours are equal.
inline sensor_msgs::msg::PointCloud2 MakeCloud(uint32_t n) {
  sensor_msgs::msg::PointCloud2 c;
  c.header().stamp(TimeFromNanoseconds(1700000000123456789LL));
  c.header().frame_id("velodyne");
  c.height(1);
  c.width(n);
  const char* names[] = {"x", "y", "z", "intensity"};
  for (uint32_t i = 0; i < 4; ++i) {
    sensor_msgs::msg::PointField f;
    f.name(names[i]);
    f.offset(4 * i);
    f.datatype(7);
    f.count(1);
    c.fields().push_back(f);
  }
  sensor_msgs::msg::PointField t;
  t.name("t");
  t.offset(16);
  t.datatype(6);
  t.count(1);
  c.fields().push_back(t);
  c.point_step(20);
  c.row_step(20 * n);
  c.data().resize(20 * n);
  for (uint32_t i = 0; i < 20 * n; ++i) c.data()[i] = static_cast<uint8_t>(i * 7);
  c.is_dense(true);
  return c;
}

}  // namespace ppf::msgs::test_util
