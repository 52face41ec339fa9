// Decoding of a CloudView into points with an absolute time each, and detection of how the
// driver encodes per-point time.
//
// Conventions seen in the wild (all handled, each covered by test_time_field.cpp):
//   field name : "t" (Ouster), "time" (Velodyne), "timestamp" (Hesai), "time_stamp",
//                "offset_time" (Livox)
//   type       : uint32 -> nanoseconds (Ouster, Livox); float32 -> seconds (Velodyne);
//                float64 -> seconds, often absolute epoch time (Hesai); other integer types -> ns
//   reference  : relative to the header stamp, or absolute. Detected by magnitude: values within
//                1 s of a header stamp that is itself > 10 s are absolute; otherwise relative.
//   header     : stamp at scan start (default) or at scan end. Relative times <= 0 (ending at 0)
//                mean "relative to the end"; non-negative relative times cannot tell, so
//                TimeFieldOptions::stamp decides (kAuto treats them as start).
// Detection runs on the first scan that has points, is logged once, and is then fixed (a driver
// does not change conventions mid-run); every field can be forced in the options instead.
//
// Without a time field the scan is either treated as instantaneous (no de-skew) or its times are
// estimated from the azimuth of each point assuming a spinning LiDAR (NoTimePolicy).
//
// Plausible sweep window: a field time more than kEarlyPointTimeS before the header stamp of a
// scan-start stamp, or later than two scan periods (TimeFieldOptions::scan_period_s) after it, is
// not a time of this sweep (mirrored for a stamp at the scan end; both sides of the stamp for
// absolute times, whose stamp may be either end). Such a point is dropped and counted
// (DecodedScan::dropped_bad_time) and never moves t_begin / t_end: one corrupt value must not make
// the scan wait for IMU coverage far ahead, or look as if time went backwards.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/cloud_view.hpp"
#include "ppf_core/config.hpp"  // this stage's options
#include "ppf_core/log.hpp"
#include "ppf_core/result_types.hpp"

namespace ppf {

// One decoded point in the LiDAR frame with its absolute time.
struct TimedPoint {
  Eigen::Vector3f p;
  float intensity = 0.f;
  double t = 0.0;  // absolute seconds
};

struct DecodedScan {
  std::vector<TimedPoint> points;  // finite points only, in input order
  double t_begin = 0.0;            // min point time (header stamp if no points)
  double t_end = 0.0;              // max point time
  size_t input_points = 0;         // width * height
  size_t dropped_nan = 0;          // non-finite (or |coordinate| > 1e30) coordinates or time
  size_t dropped_bad_time = 0;     // finite time outside the plausible sweep window (above)
  bool has_time_field = false;
  bool times_estimated = false;    // azimuth estimate used
  std::string note;                // e.g. "no time field: times estimated from azimuth"
};

class TimeFieldDecoder {
 public:
  explicit TimeFieldDecoder(const TimeFieldOptions& options = TimeFieldOptions(),
                            LogCallback log = nullptr);

  // Decodes `cloud`. On a malformed cloud returns false, fills *error, and leaves *out empty.
  // Never throws, never reads outside [data, data + size).
  bool Decode(const CloudView& cloud, DecodedScan* out, std::string* error);

  const TimeFieldInfo& info() const { return info_; }
  // Threads for decoding large clouds (0 = OpenMP default, 1 = serial); the result does not
  // depend on it.
  void set_num_threads(int num_threads) { num_threads_ = num_threads; }
  // Takes the points of a scan the caller is done with: the next Decode() of an all-float32 cloud
  // writes into them instead of a fresh vector the size of the scan, which it would zero-fill
  // first (serially, before the threads start).
  void Recycle(std::vector<TimedPoint>* points) {
    if (points->capacity() > spare_.capacity()) spare_.swap(*points);
  }
  void Reset() { info_ = TimeFieldInfo(); }

 private:
  void Detect(const CloudView& cloud, const FieldDesc* time_field, const std::vector<double>& raw);

  TimeFieldOptions options_;
  LogCallback log_;
  TimeFieldInfo info_;
  // Raw time values of the scan being decoded, kept between calls: a fresh buffer per scan is an
  // allocation (and page faults) the size of the scan.
  std::vector<double> raw_t_;
  int num_threads_ = 1;
  std::vector<TimedPoint> spare_;  // Recycle()'s; any size, contents overwritten
};

// Checks the layout of `cloud` (x/y/z present, offsets inside point_step, buffer size). Returns
// "" if usable, otherwise a human-readable reason.
std::string ValidateCloudLayout(const CloudView& cloud);

// How far before a scan-start header stamp a point time may lie (drivers that stamp the first
// packet's arrival may be a few milliseconds late).
constexpr double kEarlyPointTimeS = 0.01;

// Field names tried, in order, when TimeFieldOptions::field is empty.
const std::vector<std::string>& KnownTimeFieldNames();

}  // namespace ppf
