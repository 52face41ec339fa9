// Per-point time detection and conversion for every convention, fallbacks without a time field,
// and rejection of malformed clouds.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "ppf_core/lio/time_field.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

using test::SimPoint;
using test::TimeEncoding;

// A static sensor in the room: 1 revolution starting at t0.
std::vector<SimPoint> StaticScan(double t0) {
  test::LidarModel m;
  m.rings = 4;
  m.azimuth_steps = 90;
  const auto pose = [](double) { return Eigen::Isometry3d::Identity(); };
  return test::SimulateScan(test::MakeRoomScene(), pose, Eigen::Isometry3d::Identity(), t0, m);
}

struct Convention {
  const char* label;
  TimeEncoding enc;
  double t0;  // absolute start of the scan
  bool expect_absolute;
  bool expect_stamp_at_end;
};

class TimeFieldConventions : public ::testing::TestWithParam<Convention> {};

TEST_P(TimeFieldConventions, DetectsAndConvertsToAbsoluteTimes) {
  const Convention& c = GetParam();
  const std::vector<SimPoint> pts = StaticScan(c.t0);
  const double t_end = pts.back().t;
  const test::CloudBuffer cloud = test::MakeCloud(pts, c.t0, t_end, c.enc);

  int info_logs = 0;
  TimeFieldDecoder decoder(TimeFieldOptions(), [&](LogLevel level, const std::string&) {
    if (level == LogLevel::kInfo) ++info_logs;
  });
  DecodedScan scan;
  std::string error;
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error)) << error;
  ASSERT_EQ(scan.points.size(), pts.size());
  EXPECT_TRUE(scan.has_time_field);
  EXPECT_EQ(decoder.info().name, c.enc.name);
  EXPECT_EQ(decoder.info().absolute, c.expect_absolute) << decoder.info().Describe();
  EXPECT_EQ(decoder.info().stamp_at_end, c.expect_stamp_at_end) << decoder.info().Describe();
  // float32 seconds relative: ~1e-8; float64 absolute epoch: ~1e-7; uint32 ns: 1e-9.
  for (size_t i = 0; i < pts.size(); ++i) {
    ASSERT_NEAR(scan.points[i].t, pts[i].t, 1e-6) << c.label << " point " << i;
  }
  EXPECT_NEAR(scan.t_begin, c.t0, 1e-6);
  EXPECT_NEAR(scan.t_end, t_end, 1e-6);

  // Detection happens once: decoding more scans logs nothing new.
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error));
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error));
  EXPECT_EQ(info_logs, 1);
}

TimeEncoding Enc(const char* name, FieldType type, double unit, bool absolute, bool at_end,
                 bool rel_end) {
  TimeEncoding e;
  e.name = name;
  e.type = type;
  e.unit_s = unit;
  e.absolute = absolute;
  e.stamp_at_end = at_end;
  e.relative_to_end = rel_end;
  return e;
}

INSTANTIATE_TEST_SUITE_P(
    AllConventions, TimeFieldConventions,
    ::testing::Values(
        // Ouster: t, uint32 ns relative to the header stamp at scan start.
        Convention{"ouster_t_u32ns", Enc("t", FieldType::kUint32, 1e-9, false, false, false),
                   1700000000.25, false, false},
        // Velodyne: time, float32 s relative to the scan start stamp.
        Convention{"velodyne_time_f32", Enc("time", FieldType::kFloat32, 1.0, false, false, false),
                   1700000000.5, false, false},
        // Velodyne (stamp at end): float32 offsets <= 0 relative to the end stamp.
        Convention{"velodyne_time_f32_end",
                   Enc("time", FieldType::kFloat32, 1.0, false, true, true), 1700000000.5, false,
                   true},
        // Hesai: timestamp, float64 absolute epoch seconds.
        Convention{"hesai_timestamp_f64_abs",
                   Enc("timestamp", FieldType::kFloat64, 1.0, true, false, false), 1700000000.75,
                   true, false},
        // time_stamp float64 relative (sim clock near zero: stays relative).
        Convention{"time_stamp_f64_rel",
                   Enc("time_stamp", FieldType::kFloat64, 1.0, false, false, false), 3.0, false,
                   false},
        // Livox: offset_time uint32 ns relative to the scan start.
        Convention{"livox_offset_time_u32ns",
                   Enc("offset_time", FieldType::kUint32, 1e-9, false, false, false), 120.0, false,
                   false}),
    [](const ::testing::TestParamInfo<Convention>& info) { return std::string(info.param.label); });

TEST(TimeField, StampAtEndWithNonNegativeOffsetsNeedsConfig) {
  const std::vector<SimPoint> pts = StaticScan(50.0);
  const double t_end = pts.back().t;
  // Offsets from the first point (>= 0), header stamp at the END: only config can tell.
  TimeEncoding enc = Enc("time", FieldType::kFloat32, 1.0, false, true, false);
  const test::CloudBuffer cloud = test::MakeCloud(pts, 50.0, t_end, enc);
  TimeFieldOptions opt;
  opt.stamp = StampPosition::kEnd;
  TimeFieldDecoder decoder(opt);
  DecodedScan scan;
  std::string error;
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error)) << error;
  EXPECT_TRUE(decoder.info().stamp_at_end);
  for (size_t i = 0; i < pts.size(); ++i) ASSERT_NEAR(scan.points[i].t, pts[i].t, 1e-6);
}

TEST(TimeField, ConfigOverridesNameAndUnit) {
  const std::vector<SimPoint> pts = StaticScan(10.0);
  // A microsecond uint32 field with a non-standard name, plus a decoy "t" field full of zeros.
  TimeEncoding enc = Enc("t_us", FieldType::kUint32, 1e-6, false, false, false);
  test::CloudBuffer cloud = test::MakeCloud(pts, 10.0, pts.back().t, enc);
  TimeFieldOptions opt;
  opt.field = "t_us";
  opt.unit_scale_s = 1e-6;
  TimeFieldDecoder decoder(opt);
  DecodedScan scan;
  std::string error;
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error)) << error;
  EXPECT_EQ(decoder.info().name, "t_us");
  for (size_t i = 0; i < pts.size(); ++i) ASSERT_NEAR(scan.points[i].t, pts[i].t, 1e-6);
  // Forcing "absolute" makes the same values absolute seconds (tiny): the override wins, and
  // times 10 s before the header stamp are no times of this sweep: every point is dropped.
  TimeFieldOptions abs_opt = opt;
  abs_opt.reference = TimeReference::kAbsolute;
  TimeFieldDecoder abs_decoder(abs_opt);
  ASSERT_TRUE(abs_decoder.Decode(cloud.view, &scan, &error));
  EXPECT_TRUE(abs_decoder.info().absolute);
  EXPECT_TRUE(scan.points.empty());
  EXPECT_EQ(scan.dropped_bad_time, pts.size());
}

TEST(TimeField, NoTimeFieldNoDeskewUsesStamp) {
  const std::vector<SimPoint> pts = StaticScan(5.0);
  TimeEncoding enc;
  enc.name = "";
  const test::CloudBuffer cloud = test::MakeCloud(pts, 5.0, pts.back().t, enc);
  TimeFieldOptions opt;
  opt.no_time_policy = NoTimePolicy::kNoDeskew;
  int warnings = 0;
  TimeFieldDecoder decoder(opt, [&](LogLevel l, const std::string&) {
    if (l == LogLevel::kWarn) ++warnings;
  });
  DecodedScan scan;
  std::string error;
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error));
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error));
  EXPECT_FALSE(scan.has_time_field);
  EXPECT_FALSE(scan.times_estimated);
  EXPECT_NE(scan.note.find("not de-skewed"), std::string::npos);
  for (const TimedPoint& p : scan.points) ASSERT_EQ(p.t, 5.0);
  EXPECT_EQ(warnings, 1);  // said loudly, once
}

// A still room scan from 7.0 s, 4 rings x 360 steps, without a time field: the azimuth
// estimate's input (the true point times in `pts`).
test::CloudBuffer RoomScanWithoutTimeField(std::vector<SimPoint>* pts) {
  test::LidarModel m;
  m.rings = 4;
  m.azimuth_steps = 360;
  const auto pose = [](double) { return Eigen::Isometry3d::Identity(); };
  *pts = test::SimulateScan(test::MakeRoomScene(), pose, Eigen::Isometry3d::Identity(), 7.0, m);
  TimeEncoding enc;
  enc.name = "";
  return test::MakeCloud(*pts, 7.0, pts->back().t, enc);
}

TEST(TimeField, NoTimeFieldAzimuthEstimate) {
  std::vector<SimPoint> pts;
  const test::CloudBuffer cloud = RoomScanWithoutTimeField(&pts);
  TimeFieldDecoder decoder;  // default policy: azimuth, clockwise, 0.1 s
  DecodedScan scan;
  std::string error;
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error));
  EXPECT_TRUE(scan.times_estimated);
  EXPECT_NE(scan.note.find("azimuth"), std::string::npos);
  // float32 coordinates put the azimuth within ~1e-6 rad: well within one step (0.1 s / 360).
  for (size_t i = 0; i < pts.size(); ++i) {
    ASSERT_NEAR(scan.points[i].t, pts[i].t, 1e-4) << i;
  }
}

// A period that is no LiDAR's (infinite, astronomical, NaN, not positive) is replaced by 0.1 s
// with a warning: with it the azimuth estimate made every point time infinite (a fuzzer's find).
TEST(TimeField, AnUnusableScanPeriodFallsBackToTheDefaultWithAWarning) {
  std::vector<SimPoint> pts;
  const test::CloudBuffer cloud = RoomScanWithoutTimeField(&pts);
  for (const double period : {std::numeric_limits<double>::infinity(), 1e300, 10.5,
                              std::numeric_limits<double>::quiet_NaN(), 0.0, -0.1}) {
    TimeFieldOptions opt;
    opt.scan_period_s = period;
    std::vector<std::string> warnings;
    TimeFieldDecoder decoder(opt, [&](LogLevel l, const std::string& text) {
      if (l == LogLevel::kWarn && text.find("scan period") != std::string::npos) {
        warnings.push_back(text);
      }
    });
    DecodedScan scan;
    std::string error;
    ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error)) << period;
    ASSERT_EQ(warnings.size(), 1u) << period;
    EXPECT_NE(warnings[0].find("using 0.1 s"), std::string::npos) << warnings[0];
    ASSERT_EQ(scan.points.size(), pts.size()) << period;
    for (size_t i = 0; i < pts.size(); ++i) {
      ASSERT_NEAR(scan.points[i].t, pts[i].t, 1e-4) << period << " point " << i;
    }
    EXPECT_GE(scan.t_begin, 7.0 - 1e-9);
    EXPECT_LE(scan.t_end, 7.1 + 1e-9);
  }
  // The longest period taken as one is kept.
  TimeFieldOptions slow;
  slow.scan_period_s = kMaxScanPeriodS;
  int warnings = 0;
  TimeFieldDecoder decoder(slow, [&](LogLevel l, const std::string& text) {
    warnings += l == LogLevel::kWarn && text.find("scan period") != std::string::npos;
  });
  DecodedScan scan;
  std::string error;
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error));
  EXPECT_EQ(warnings, 0);
  EXPECT_GT(scan.t_end, 7.0 + 1.0);  // the estimate spreads the sweep over 10 s
}

CloudView GoodView(const test::CloudBuffer& c) { return c.view; }

TEST(TimeField, RejectsMalformedClouds) {
  const std::vector<SimPoint> pts = StaticScan(1.0);
  const test::CloudBuffer cloud = test::MakeCloud(pts, 1.0, pts.back().t, TimeEncoding());
  TimeFieldDecoder decoder;
  DecodedScan scan;
  std::string error;

  CloudView v = GoodView(cloud);
  v.point_step = 8;  // z at offset 8 does not fit
  v.row_step = v.point_step * v.width;
  EXPECT_FALSE(decoder.Decode(v, &scan, &error));
  EXPECT_NE(error.find("point_step"), std::string::npos) << error;
  EXPECT_TRUE(scan.points.empty());

  v = GoodView(cloud);
  v.size = cloud.bytes.size() - 1;  // one byte short
  EXPECT_FALSE(decoder.Decode(v, &scan, &error));
  EXPECT_NE(error.find("size mismatch"), std::string::npos) << error;

  v = GoodView(cloud);
  v.width += 10;  // claims more points than bytes
  EXPECT_FALSE(decoder.Decode(v, &scan, &error));

  v = GoodView(cloud);
  v.fields.erase(v.fields.begin() + 2);  // no z
  EXPECT_FALSE(decoder.Decode(v, &scan, &error));
  EXPECT_NE(error.find("x, y or z"), std::string::npos) << error;

  v = GoodView(cloud);
  v.data = nullptr;
  EXPECT_FALSE(decoder.Decode(v, &scan, &error));

  v = GoodView(cloud);
  v.is_bigendian = true;
  EXPECT_FALSE(decoder.Decode(v, &scan, &error));

  v = GoodView(cloud);
  v.fields[4].type = static_cast<FieldType>(42);
  EXPECT_FALSE(decoder.Decode(v, &scan, &error));

  v = GoodView(cloud);
  v.fields[4].offset = v.point_step - 2;  // time field straddles the point end
  EXPECT_FALSE(decoder.Decode(v, &scan, &error));
}

TEST(TimeField, NanPointsDroppedAndCounted) {
  std::vector<SimPoint> pts = StaticScan(1.0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  pts[3].p.x() = nan;
  pts[10].p.z() = std::numeric_limits<float>::infinity();
  const test::CloudBuffer cloud = test::MakeCloud(pts, 1.0, pts.back().t, TimeEncoding());
  TimeFieldDecoder decoder;
  DecodedScan scan;
  std::string error;
  ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error));
  EXPECT_EQ(scan.dropped_nan, 2u);
  EXPECT_EQ(scan.points.size(), pts.size() - 2);
  EXPECT_EQ(scan.input_points, pts.size());
}

// A point time far outside the sweep (a corrupt value, a driver bug) is dropped and counted in
// every convention, and the scan's time span stays that of the other points: the facade would
// otherwise wait for IMU coverage 1e6 s ahead, or take the scan for time going backwards.
TEST(TimeField, ImplausiblePointTimesDroppedAndCounted) {
  struct Case {
    const char* label;
    TimeEncoding enc;
    double t0;
    StampPosition stamp;
  };
  const Case cases[] = {
      {"relative_start_f32", Enc("time", FieldType::kFloat32, 1.0, false, false, false), 5.0,
       StampPosition::kAuto},
      {"relative_to_end_f32", Enc("time", FieldType::kFloat32, 1.0, false, true, true), 5.0,
       StampPosition::kAuto},
      // Non-negative offsets, stamp at the end: the last offset places every point (TimeBase).
      {"offsets_stamp_end_f32", Enc("time", FieldType::kFloat32, 1.0, false, true, false), 5.0,
       StampPosition::kEnd},
      {"absolute_f64", Enc("timestamp", FieldType::kFloat64, 1.0, true, false, false),
       1700000000.75, StampPosition::kAuto},
      {"relative_start_u32ns", Enc("t", FieldType::kUint32, 1e-9, false, false, false), 5.0,
       StampPosition::kAuto},
  };
  for (const Case& c : cases) {
    std::vector<SimPoint> pts = StaticScan(c.t0);
    const double t_begin = pts.front().t, t_end = pts.back().t;
    // uint32 ns cannot hold -100 s or 1e6 s: 4.2 s (the largest value) is as implausible.
    const bool u32 = c.enc.type == FieldType::kUint32;
    pts[5].t += u32 ? 4.0 : 1e6;
    pts[9].t -= u32 ? 0.0 : 100.0;
    pts[12].t += u32 ? 0.5 : -100.0;
    // A first clean scan fixes the convention, as a driver's first scan would.
    TimeFieldOptions opt;
    opt.stamp = c.stamp;
    TimeFieldDecoder decoder(opt);
    DecodedScan scan;
    std::string error;
    const test::CloudBuffer clean = test::MakeCloud(StaticScan(c.t0), t_begin, t_end, c.enc);
    ASSERT_TRUE(decoder.Decode(clean.view, &scan, &error)) << error;
    EXPECT_EQ(scan.dropped_bad_time, 0u) << c.label;
    const test::CloudBuffer cloud = test::MakeCloud(pts, t_begin, t_end, c.enc);
    ASSERT_TRUE(decoder.Decode(cloud.view, &scan, &error)) << error;
    EXPECT_EQ(scan.dropped_bad_time, u32 ? 2u : 3u) << c.label;
    EXPECT_EQ(scan.points.size() + scan.dropped_bad_time, pts.size()) << c.label;
    EXPECT_NEAR(scan.t_begin, t_begin, 1e-6) << c.label;
    EXPECT_NEAR(scan.t_end, t_end, 1e-6) << c.label;
    for (const TimedPoint& p : scan.points) {
      ASSERT_GE(p.t, t_begin - 1e-6) << c.label;
      ASSERT_LE(p.t, t_end + 1e-6) << c.label;
    }
  }
}

// The window follows time.scan_period: a sweep of 0.25 s keeps its points with a period of
// 0.25 s and loses the part beyond 2 x 0.1 s with the default.
TEST(TimeField, SweepWindowFollowsTheScanPeriod) {
  test::LidarModel m;
  m.rings = 4;
  m.azimuth_steps = 91;  // no point within 2 ms of 0.2 s: float32 rounding decides nothing
  m.period = 0.25;
  const auto pose = [](double) { return Eigen::Isometry3d::Identity(); };
  const std::vector<SimPoint> pts =
      test::SimulateScan(test::MakeRoomScene(), pose, Eigen::Isometry3d::Identity(), 2.0, m);
  const test::CloudBuffer cloud = test::MakeCloud(pts, 2.0, pts.back().t, TimeEncoding());
  size_t late = 0;
  for (const SimPoint& p : pts) late += p.t - 2.0 > 0.2 + 1e-6 ? 1 : 0;
  ASSERT_GT(late, 0u);
  DecodedScan scan;
  std::string error;
  TimeFieldDecoder defaults;
  ASSERT_TRUE(defaults.Decode(cloud.view, &scan, &error)) << error;
  EXPECT_EQ(scan.dropped_bad_time, late);
  EXPECT_LE(scan.t_end, 2.2 + 1e-6);
  TimeFieldOptions slow;
  slow.scan_period_s = 0.25;
  TimeFieldDecoder configured(slow);
  ASSERT_TRUE(configured.Decode(cloud.view, &scan, &error)) << error;
  EXPECT_EQ(scan.dropped_bad_time, 0u);
  EXPECT_EQ(scan.points.size(), pts.size());
}

// Random layouts and bytes: Decode either rejects or returns finite points, never reads outside
// the buffer (run under -fsanitize=address to check the latter).
TEST(TimeField, FuzzedLayoutsNeverCrash) {
  std::mt19937 rng(1234);
  std::uniform_int_distribution<int> byte(0, 255), small(0, 40), type(0, 9), count(0, 64);
  const char* names[] = {"x", "y", "z", "t", "time", "timestamp", "intensity", "offset_time"};
  size_t accepted = 0;
  for (int iter = 0; iter < 3000; ++iter) {
    CloudView v;
    v.stamp_s = (iter % 3 == 0) ? 1.7e9 : 0.5 * iter;
    v.width = static_cast<uint32_t>(count(rng));
    v.height = static_cast<uint32_t>(1 + iter % 3);
    v.point_step = static_cast<uint32_t>(small(rng));
    v.row_step =
        (iter % 4 == 0) ? 0 : v.width * v.point_step + static_cast<uint32_t>(small(rng) % 5);
    v.is_bigendian = (iter % 50 == 0);
    const int nfields = 1 + small(rng) % 6;
    for (int f = 0; f < nfields; ++f) {
      v.fields.push_back({names[(f + iter) % 8], static_cast<uint32_t>(small(rng)),
                          static_cast<FieldType>(type(rng)), 1});
    }
    if (iter % 2 == 0) {  // a plausible layout with random details, so some clouds are valid
      v.fields = {{"x", 0, FieldType::kFloat32, 1},
                  {"y", 4, FieldType::kFloat32, 1},
                  {"z", 8, FieldType::kFloat32, 1},
                  {names[3 + iter % 5], 12, static_cast<FieldType>(1 + type(rng) % 8), 1}};
      v.point_step = 12 + static_cast<uint32_t>(small(rng) % 12);
      v.row_step = v.width * v.point_step;
    }
    size_t nbytes = static_cast<size_t>(small(rng)) * static_cast<size_t>(count(rng));
    if (iter % 4 == 0) nbytes = static_cast<size_t>(v.height) * v.width * v.point_step;
    std::vector<uint8_t> bytes(nbytes);
    for (auto& b : bytes) b = static_cast<uint8_t>(byte(rng));
    v.data = bytes.empty() ? nullptr : bytes.data();
    v.size = bytes.size();
    TimeFieldDecoder decoder;
    DecodedScan scan;
    std::string error;
    if (decoder.Decode(v, &scan, &error)) {
      ++accepted;
      for (const TimedPoint& p : scan.points) {
        ASSERT_TRUE(p.p.allFinite());
        ASSERT_TRUE(std::isfinite(p.t));
      }
      EXPECT_EQ(scan.points.size() + scan.dropped_nan + scan.dropped_bad_time, scan.input_points);
    } else {
      EXPECT_FALSE(error.empty());
    }
  }
  EXPECT_GT(accepted, 0u);  // the generator also produces valid clouds
}

TEST(TimeField, EmptyCloudIsValid) {
  CloudView v;
  v.fields = {{"x", 0, FieldType::kFloat32, 1},
              {"y", 4, FieldType::kFloat32, 1},
              {"z", 8, FieldType::kFloat32, 1}};
  v.point_step = 12;
  TimeFieldDecoder decoder;
  DecodedScan scan;
  std::string error;
  EXPECT_TRUE(decoder.Decode(v, &scan, &error)) << error;
  EXPECT_TRUE(scan.points.empty());
}

// Decoding a large cloud on several threads (index ranges moved together afterwards) into
// recycled points must give the serial result into fresh ones bit for bit, with invalid points in
// every range and rows of the cloud split between threads.
// The same cloud with float64 coordinates: the general decode path, which reads each element
// through its type, while the float32 cloud takes the fast path with its tests on floats.
test::CloudBuffer WithFloat64Xyz(const test::CloudBuffer& f32) {
  test::CloudBuffer c;
  c.view = f32.view;
  const uint32_t step = 32;  // x y z float64, intensity float32, a 4-byte time field
  c.view.point_step = step;
  c.view.row_step = step * c.view.width;
  c.view.fields = {{"x", 0, FieldType::kFloat64, 1},
                   {"y", 8, FieldType::kFloat64, 1},
                   {"z", 16, FieldType::kFloat64, 1},
                   {"intensity", 24, FieldType::kFloat32, 1}};
  bool timed = false;
  for (const FieldDesc& f : f32.view.fields) {
    if (f.offset == 16) c.view.fields.push_back({f.name, 28, f.type, 1});
    timed = timed || f.offset == 16;
  }
  c.bytes.assign(static_cast<size_t>(c.view.row_step), 0);
  for (uint32_t i = 0; i < c.view.width; ++i) {
    const uint8_t* src = f32.bytes.data() + static_cast<size_t>(i) * f32.view.point_step;
    uint8_t* dst = c.bytes.data() + static_cast<size_t>(i) * step;
    for (int k = 0; k < 3; ++k) {
      float v;
      std::memcpy(&v, src + 4 * k, 4);
      const double d = v;
      std::memcpy(dst + 8 * k, &d, 8);
    }
    std::memcpy(dst + 24, src + 12, 4);
    if (timed) std::memcpy(dst + 28, src + 16, 4);
  }
  c.view.data = c.bytes.data();
  c.view.size = c.bytes.size();
  return c;
}

// The float32 fast path keeps exactly the points, values and counts of the general path, at the
// edges of its tests too: coordinates at the largest float below 1e30 and the next one up, NaN
// and infinities, intensities the same; for a float32, a uint32 (Ouster's nanoseconds, a path of
// its own), another integer and no time field.
TEST(TimeField, Float32PathEqualsTheGeneralPath) {
  std::vector<SimPoint> pts = StaticScan(2.0);
  ASSERT_GT(pts.size(), 100u);
  float edge = static_cast<float>(1e30);
  while (static_cast<double>(edge) >= 1e30) edge = std::nextafter(edge, 0.0f);
  const float above = std::nextafter(edge, std::numeric_limits<float>::infinity());
  const float inf = std::numeric_limits<float>::infinity();
  const float coords[] = {edge, -edge, above, -above, inf, -inf, std::nanf("")};
  size_t k = 0;
  for (const float c : coords) {
    for (int axis = 0; axis < 3; ++axis) pts[5 + 3 * k++].p[axis] = c;
  }
  const float intensities[] = {edge, -edge, above, -above, inf, -inf, std::nanf(""), 7.5f};
  const TimeEncoding f32;
  TimeEncoding u32;
  u32.type = FieldType::kUint32;
  u32.unit_s = 1e-9;
  TimeEncoding i32 = u32;
  i32.type = FieldType::kInt32;
  TimeEncoding none;
  none.name = "";
  for (const TimeEncoding& enc : {f32, u32, i32, none}) {
    test::CloudBuffer fast = test::MakeCloud(pts, 2.0, pts.back().t, enc);
    for (size_t j = 0; j < 8; ++j) {
      std::memcpy(fast.bytes.data() + (60 + 7 * j) * fast.view.point_step + 12, &intensities[j], 4);
    }
    const test::CloudBuffer general = WithFloat64Xyz(fast);
    TimeFieldDecoder a, b;
    std::string error;
    // Twice: the first decode reads all raw times (detection), the second each time in the loop.
    for (int call = 0; call < 2; ++call) {
      DecodedScan x, y;
      ASSERT_TRUE(a.Decode(fast.view, &x, &error)) << error;
      ASSERT_TRUE(b.Decode(general.view, &y, &error)) << error;
      EXPECT_EQ(x.dropped_nan, 3u * 5u) << enc.name;  // above, -above, inf, -inf, NaN
      EXPECT_EQ(x.dropped_nan, y.dropped_nan);
      EXPECT_EQ(x.dropped_bad_time, y.dropped_bad_time);
      EXPECT_EQ(x.t_begin, y.t_begin);
      EXPECT_EQ(x.t_end, y.t_end);
      ASSERT_EQ(x.points.size(), y.points.size());
      for (size_t i = 0; i < x.points.size(); ++i) {
        ASSERT_EQ(std::memcmp(x.points[i].p.data(), y.points[i].p.data(), 12), 0) << i;
        ASSERT_EQ(std::memcmp(&x.points[i].intensity, &y.points[i].intensity, 4), 0) << i;
        ASSERT_EQ(std::memcmp(&x.points[i].t, &y.points[i].t, 8), 0) << i;
      }
      size_t kept_edges = 0;
      for (const TimedPoint& tp : x.points) kept_edges += std::abs(tp.p.x()) == edge;
      EXPECT_EQ(kept_edges, 2u);
    }
  }
}

TEST(TimeField, ParallelDecodeEqualsSerialBitForBit) {
  test::LidarModel m;
  m.rings = 32;
  m.azimuth_steps = 2000;
  const auto pose = [](double) { return Eigen::Isometry3d::Identity(); };
  std::vector<SimPoint> pts =
      test::SimulateScan(test::MakeRoomScene(), pose, Eigen::Isometry3d::Identity(), 30.0, m);
  ASSERT_GT(pts.size(), 40000u);
  pts.resize(pts.size() / 4 * 4);
  for (size_t i = 7; i < pts.size(); i += 997) pts[i].p.x() = std::nanf("");
  for (const FieldType type : {FieldType::kFloat32, FieldType::kUint32}) {
    TimeEncoding enc;
    enc.type = type;
    enc.unit_s = type == FieldType::kUint32 ? 1e-9 : 1.0;
    test::CloudBuffer cloud = test::MakeCloud(pts, 30.0, pts.back().t, enc);
    cloud.view.height = 4;  // same bytes as 4 rows
    cloud.view.width /= 4;
    cloud.view.row_step /= 4;
    TimeFieldDecoder serial;
    serial.set_num_threads(1);
    std::vector<DecodedScan> reference(2);
    std::string error;
    // The first call reads all raw times (detection), later ones read each time in the loop.
    for (DecodedScan& r : reference) ASSERT_TRUE(serial.Decode(cloud.view, &r, &error)) << error;
    ASSERT_GT(reference[0].dropped_nan, 30u);
    for (const int threads : {2, 3}) {
      TimeFieldDecoder parallel;
      parallel.set_num_threads(threads);
      // Decoding into recycled points (larger than the scan, stale contents) changes nothing.
      std::vector<TimedPoint> stale(pts.size() + 100, {Eigen::Vector3f(9.f, 9.f, 9.f), 9.f, 9.0});
      parallel.Recycle(&stale);
      for (const DecodedScan& r : reference) {
        DecodedScan scan;
        ASSERT_TRUE(parallel.Decode(cloud.view, &scan, &error)) << error;
        ASSERT_EQ(scan.points.size(), r.points.size());
        EXPECT_EQ(scan.dropped_nan, r.dropped_nan);
        EXPECT_EQ(std::memcmp(&scan.t_begin, &r.t_begin, sizeof(double)), 0);
        EXPECT_EQ(std::memcmp(&scan.t_end, &r.t_end, sizeof(double)), 0);
        for (size_t i = 0; i < r.points.size(); ++i) {
          const TimedPoint& a = scan.points[i];
          const TimedPoint& b = r.points[i];
          ASSERT_EQ(std::memcmp(a.p.data(), b.p.data(), sizeof(float) * 3), 0) << i;
          ASSERT_EQ(std::memcmp(&a.intensity, &b.intensity, sizeof(float)), 0) << i;
          ASSERT_EQ(std::memcmp(&a.t, &b.t, sizeof(double)), 0) << i;
        }
        parallel.Recycle(&scan.points);
      }
    }
  }
}

}  // namespace
}  // namespace ppf
