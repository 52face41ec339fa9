// PeekCloudPointCount: the point count a PointCloud2 payload declares, read without decoding it,
// against the generated encoder's bytes (little- and big-endian) and against damaged payloads.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "ppf_msgs_cdr/cdr.hpp"
#include "sensor_msgs/msg/PointCloud2.h"

namespace ppf::msgs {
namespace {

sensor_msgs::msg::PointCloud2 Cloud(const std::string& frame, uint32_t height, uint32_t width) {
  sensor_msgs::msg::PointCloud2 c;
  c.header().frame_id(frame);
  c.height(height);
  c.width(width);
  c.point_step(16);
  c.row_step(16 * width);
  c.data().resize(64);  // fewer bytes than declared: the peek must not care
  return c;
}

TEST(PeekCloudPointCount, ReadsHeightTimesWidthWhateverTheFrameIdPadding) {
  // frame_id lengths 0..5 with the NUL put height at every 4-byte alignment case.
  for (const std::string frame : {"", "a", "ab", "abc", "abcd", "velodyne_points"}) {
    const std::vector<uint8_t> bytes = EncodeCdr(Cloud(frame, 64, 2048));
    uint64_t n = 0;
    ASSERT_TRUE(PeekCloudPointCount(bytes.data(), bytes.size(), &n)) << "'" << frame << "'";
    EXPECT_EQ(n, 64u * 2048u) << "'" << frame << "'";
  }
}

TEST(PeekCloudPointCount, DoesNotOverflowOnHugeDeclarations) {
  const std::vector<uint8_t> bytes = EncodeCdr(Cloud("lidar", 0xFFFFFFFFu, 0xFFFFFFFFu));
  uint64_t n = 0;
  ASSERT_TRUE(PeekCloudPointCount(bytes.data(), bytes.size(), &n));
  EXPECT_EQ(n, uint64_t{0xFFFFFFFFu} * 0xFFFFFFFFu);
}

TEST(PeekCloudPointCount, ReadsBigEndianPayloads) {
  // The same message hand-encoded big-endian (encapsulation 00 00): stamp, frame_id "ab",
  // padding to 4, height 3, width 5.
  const std::vector<uint8_t> be = {0x00, 0x00, 0x00, 0x00,                          // CDR_BE
                                   0, 0, 0, 1, 0, 0, 0, 2,                          // stamp
                                   0, 0, 0, 3, 'a', 'b', 0, 0,                      // "ab" + pad
                                   0, 0, 0, 3, 0, 0, 0, 5};                         // h, w
  uint64_t n = 0;
  ASSERT_TRUE(PeekCloudPointCount(be.data(), be.size(), &n));
  EXPECT_EQ(n, 15u);
}

TEST(PeekCloudPointCount, RefusesWhatItCannotRead) {
  const std::vector<uint8_t> bytes = EncodeCdr(Cloud("lidar", 16, 100));
  uint64_t n = 7;
  // Every truncation short of the width field.
  for (size_t len = 0; len < 4 + 8 + 4 + 8 + 8; ++len) {
    EXPECT_FALSE(PeekCloudPointCount(bytes.data(), len, &n)) << len;
  }
  // Unknown encapsulation (XCDR2, parameter lists, garbage).
  for (uint8_t kind : {0x02, 0x03, 0x07, 0xFF}) {
    std::vector<uint8_t> b = bytes;
    b[1] = kind;
    EXPECT_FALSE(PeekCloudPointCount(b.data(), b.size(), &n)) << int(kind);
  }
  // A frame_id length pointing past the end.
  std::vector<uint8_t> b = bytes;
  b[12] = b[13] = b[14] = b[15] = 0x7F;
  EXPECT_FALSE(PeekCloudPointCount(b.data(), b.size(), &n));
  EXPECT_FALSE(PeekCloudPointCount(nullptr, 100, &n));
  EXPECT_EQ(n, 7u) << "written although refused";
}

}  // namespace
}  // namespace ppf::msgs
