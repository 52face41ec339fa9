#include "ppf_core/lio/time_field.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ppf {
namespace {

constexpr double kTwoPi = 6.283185307179586;

const FieldDesc* FindField(const CloudView& cloud, const std::string& name) {
  for (const FieldDesc& f : cloud.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

inline double ReadFloat32(const uint8_t* p) {
  float v;
  std::memcpy(&v, p, 4);
  return v;
}

template <typename T>
double Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return static_cast<double>(v);
}

// Reads one element; the caller guarantees offset + size <= point_step within the buffer.
double ReadAs(const uint8_t* p, FieldType type) {
  switch (type) {
    case FieldType::kInt8:
      return Load<int8_t>(p);
    case FieldType::kUint8:
      return Load<uint8_t>(p);
    case FieldType::kInt16:
      return Load<int16_t>(p);
    case FieldType::kUint16:
      return Load<uint16_t>(p);
    case FieldType::kInt32:
      return Load<int32_t>(p);
    case FieldType::kUint32:
      return Load<uint32_t>(p);
    case FieldType::kFloat32:
      return Load<float>(p);
    case FieldType::kFloat64:
      return Load<double>(p);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

bool FieldFits(const FieldDesc& f, uint32_t point_step) {
  const size_t sz = FieldTypeSize(f.type);
  return sz > 0 && static_cast<uint64_t>(f.offset) + sz <= point_step;
}

const char* TypeName(FieldType t) {
  // Indexed by the PointField datatype value (cloud_view.hpp), 1..8.
  static const char* const kNames[] = {"unknown", "int8",   "uint8",   "int16",  "uint16",
                                       "int32",   "uint32", "float32", "float64"};
  const size_t i = static_cast<size_t>(t);
  return i < sizeof(kNames) / sizeof(kNames[0]) ? kNames[i] : "unknown";
}

bool IsIntegerType(FieldType t) { return t != FieldType::kFloat32 && t != FieldType::kFloat64; }

// The configured time field, or the first of the known names the cloud has.
const FieldDesc* FindTimeField(const CloudView& cloud, const std::string& configured_name) {
  if (!configured_name.empty()) return FindField(cloud, configured_name);
  for (const std::string& name : KnownTimeFieldNames()) {
    if (const FieldDesc* f = FindField(cloud, name)) return f;
  }
  return nullptr;
}

// Visits the points of the indices [begin, end) in order, row by row (no division per point):
// visit(i, point bytes).
template <typename Visit>
void ForEachPointIn(const CloudView& cloud, size_t begin, size_t end, Visit&& visit) {
  if (begin >= end) return;
  const uint64_t row_step =
      cloud.row_step == 0 ? static_cast<uint64_t>(cloud.width) * cloud.point_step : cloud.row_step;
  size_t i = begin;
  uint32_t col = static_cast<uint32_t>(begin % cloud.width);
  for (uint64_t row = begin / cloud.width; i < end; ++row, col = 0) {
    const uint8_t* p = cloud.data + row * row_step + static_cast<uint64_t>(col) * cloud.point_step;
    // One bound per row, not two tests per point.
    const size_t row_end = std::min(end, i + (cloud.width - col));
    for (; i < row_end; ++i, p += cloud.point_step) visit(i, p);
  }
}

template <typename Visit>
void ForEachPoint(const CloudView& cloud, Visit&& visit) {
  ForEachPointIn(cloud, 0, static_cast<size_t>(cloud.width) * cloud.height, visit);
}

// The raw (unscaled) value of the time field of every point, in index order.
void ReadRawTimes(const CloudView& cloud, const FieldDesc& ft, std::vector<double>* raw_t) {
  raw_t->resize(static_cast<size_t>(cloud.width) * cloud.height);
  double* raw = raw_t->data();
  if (ft.type == FieldType::kFloat32) {
    ForEachPoint(cloud, [&](size_t i, const uint8_t* p) { raw[i] = ReadFloat32(p + ft.offset); });
  } else {
    ForEachPoint(cloud,
                 [&](size_t i, const uint8_t* p) { raw[i] = ReadAs(p + ft.offset, ft.type); });
  }
}

// Point time = base + raw * scale, the raw value from the buffer of raw times or, without one,
// straight from the point's time field (same value: one pass over the cloud less); the header
// stamp for every point without a time field.
struct TimeMap {
  const double* raw = nullptr;
  const FieldDesc* field = nullptr;
  double base = 0.0;
  double scale = 1.0;
  double stamp_s = 0.0;
  // The plausible sweep window (time_field.hpp); infinite without a time field.
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool Plausible(double t) const { return t >= lo && t <= hi; }
  double At(size_t i, const uint8_t* p) const {
    if (raw) return base + raw[i] * scale;
    if (!field) return stamp_s;
    const double v = field->type == FieldType::kFloat32 ? ReadFloat32(p + field->offset)
                                                        : ReadAs(p + field->offset, field->type);
    return base + v * scale;
  }
};

// Where raw time zero lies: nowhere for absolute times (base 0), the header stamp for times
// relative to the scan start, and stamp - last time for stamp-at-end clouds whose times are
// non-negative (times ending at 0 are offsets from the end already). The last time is the last
// plausible one (an offset of at most `span`): a corrupt offset must not shift every point.
double TimeBase(const TimeFieldInfo& info, double stamp_s, const std::vector<double>& raw_t,
                double span) {
  if (info.absolute) return 0.0;
  if (!info.stamp_at_end) return stamp_s;
  double hi = -std::numeric_limits<double>::infinity();
  for (double v : raw_t) {
    const double offset = v * info.unit_scale_s;
    if (std::isfinite(offset) && offset <= span) hi = std::max(hi, offset);
  }
  return std::isfinite(hi) && hi > 0.0 ? stamp_s - hi : stamp_s;
}

// The plausible sweep window of field times around the header stamp (time_field.hpp): after a
// scan-start stamp, before a scan-end stamp, either side of it for absolute times.
void SetPlausibleWindow(const TimeFieldInfo& info, double stamp_s, double span, TimeMap* times) {
  if (info.absolute) {
    times->lo = stamp_s - span;
    times->hi = stamp_s + span;
  } else if (info.stamp_at_end) {
    times->lo = stamp_s - span;
    times->hi = stamp_s + kEarlyPointTimeS;
  } else {
    times->lo = stamp_s - kEarlyPointTimeS;
    times->hi = stamp_s + span;
  }
}

// The coordinate and intensity fields of a validated cloud (intensity null when absent or not
// fitting in point_step).
struct PointFields {
  const FieldDesc* x;
  const FieldDesc* y;
  const FieldDesc* z;
  const FieldDesc* intensity;
  bool XyzFloat32() const {
    return x->type == FieldType::kFloat32 && y->type == FieldType::kFloat32 &&
           z->type == FieldType::kFloat32;
  }
  bool IntensityFloat32() const { return intensity && intensity->type == FieldType::kFloat32; }
};

// What one thread's range of DecodeAllFloat32 kept: its points start at `begin` of the output.
struct DecodedRange {
  size_t begin = 0, kept = 0, dropped = 0, bad_time = 0;
  double t_lo = 0.0, t_hi = 0.0;  // first-found min / max of the kept times (SetTimeSpan's)
};

// The largest float that passes the decode's |c| <= 1e30 test made in double: no float equals
// 1e30, so a float's magnitude is at most this exactly when it is below 1e30 as well.
float LargestFloatNotAbove(double limit) {
  float f = static_cast<float>(limit);
  while (static_cast<double>(f) > limit) f = std::nextafter(f, 0.0f);
  return f;
}
const float kMaxCoordF = LargestFloatNotAbove(1e30);

inline float LoadFloat32(const uint8_t* p) {
  float v;
  std::memcpy(&v, p, 4);
  return v;
}

// Where DecodeFloat32Range takes each point's time from (TimeMap's three cases, the field's type
// split): chosen once per cloud, not per point. uint32 is Ouster's nanosecond `t`.
enum class TimeSource { kRaw, kFieldFloat32, kFieldUint32, kFieldOther, kNone };

// Every field float32 (nearly every driver): one pass writing straight into the output, with
// the general path's values and validity test (a non-finite or > 1e30 coordinate fails
// |c| <= 1e30, tested on the float against kMaxCoordF; the time is the same double). Decodes the
// indices [begin, end) compacted to dst + begin.
template <TimeSource kTime, bool kIntensity>
void DecodeFloat32Range(const CloudView& cloud, const PointFields& f, const TimeMap& times,
                        size_t begin, size_t end, TimedPoint* dst, DecodedRange* range) {
  range->begin = begin;
  size_t kept = begin, dropped = 0, bad_time = 0;
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  const uint32_t ox = f.x->offset, oy = f.y->offset, oz = f.z->offset;
  const uint32_t oi = kIntensity ? f.intensity->offset : 0;
  const uint32_t ot = times.field != nullptr ? times.field->offset : 0;
  const FieldType time_type = times.field != nullptr ? times.field->type : FieldType::kFloat32;
  const double base = times.base, scale = times.scale, stamp_s = times.stamp_s;
  const double window_lo = times.lo, window_hi = times.hi;
  const double* raw = times.raw;
  ForEachPointIn(cloud, begin, end, [&](size_t i, const uint8_t* p) {
    const float x = LoadFloat32(p + ox), y = LoadFloat32(p + oy), z = LoadFloat32(p + oz);
    double t;
    if constexpr (kTime == TimeSource::kRaw) {
      t = base + raw[i] * scale;
    } else if constexpr (kTime == TimeSource::kFieldFloat32) {
      t = base + ReadFloat32(p + ot) * scale;
    } else if constexpr (kTime == TimeSource::kFieldUint32) {
      t = base + Load<uint32_t>(p + ot) * scale;
    } else if constexpr (kTime == TimeSource::kFieldOther) {
      t = base + ReadAs(p + ot, time_type) * scale;
    } else {
      t = stamp_s;
    }
    const bool finite_xyz =
        (std::fabs(x) <= kMaxCoordF) & (std::fabs(y) <= kMaxCoordF) & (std::fabs(z) <= kMaxCoordF);
    if (!finite_xyz || !std::isfinite(t)) {
      ++dropped;
      return;
    }
    if (!(t >= window_lo && t <= window_hi)) {  // TimeMap::Plausible
      ++bad_time;
      return;
    }
    lo = std::min(lo, t);
    hi = std::max(hi, t);
    TimedPoint& tp = dst[kept++];
    tp.p = Eigen::Vector3f(x, y, z);
    tp.t = t;
    if constexpr (kIntensity) {
      const float v = LoadFloat32(p + oi);
      tp.intensity = std::fabs(v) <= kMaxCoordF ? v : 0.f;
    } else {
      tp.intensity = 0.f;
    }
  });
  range->kept = kept - begin;
  range->dropped = dropped;
  range->bad_time = bad_time;
  range->t_lo = range->kept > 0 ? lo : 0.0;
  range->t_hi = range->kept > 0 ? hi : 0.0;
}

using DecodeRangeFn = void (*)(const CloudView&, const PointFields&, const TimeMap&, size_t, size_t,
                               TimedPoint*, DecodedRange*);

template <TimeSource kTime>
DecodeRangeFn PickDecodeRange(bool intensity) {
  return intensity ? &DecodeFloat32Range<kTime, true> : &DecodeFloat32Range<kTime, false>;
}

DecodeRangeFn PickDecodeRange(const PointFields& f, const TimeMap& times) {
  const bool intensity = f.intensity != nullptr;
  if (times.raw != nullptr) return PickDecodeRange<TimeSource::kRaw>(intensity);
  if (times.field == nullptr) return PickDecodeRange<TimeSource::kNone>(intensity);
  if (times.field->type == FieldType::kFloat32) {
    return PickDecodeRange<TimeSource::kFieldFloat32>(intensity);
  }
  if (times.field->type == FieldType::kUint32) {
    return PickDecodeRange<TimeSource::kFieldUint32>(intensity);
  }
  return PickDecodeRange<TimeSource::kFieldOther>(intensity);
}

// Fewer points than this decode on one thread: a 16-beam scan decodes faster than a fork/join.
constexpr size_t kParallelDecodePoints = 32768;

// DecodeFloat32Range over the whole cloud, split in index ranges over `threads`; the ranges'
// points are then moved together in order and their time spans combined in order, which gives
// the serial result (the first of equal minima / maxima, as SetTimeSpan finds them).
void DecodeAllFloat32(const CloudView& cloud, const PointFields& f, const TimeMap& times,
                      int threads, DecodedScan* out) {
  const size_t n = static_cast<size_t>(cloud.width) * cloud.height;
  out->points.resize(n);
  TimedPoint* dst = out->points.data();
  const int parts = threads > 1 && n >= kParallelDecodePoints ? threads : 1;
  DecodedRange ranges[8];
  const int used = std::min(parts, 8);
  const DecodeRangeFn decode = PickDecodeRange(f, times);
  if (used == 1) {
    decode(cloud, f, times, 0, n, dst, &ranges[0]);
  } else {
#pragma omp parallel for schedule(static, 1) num_threads(used)
    for (int c = 0; c < used; ++c) {
      decode(cloud, f, times, n * c / used, n * (c + 1) / used, dst, &ranges[c]);
    }
  }
  size_t kept = 0;
  bool any = false;
  for (int c = 0; c < used; ++c) {
    const DecodedRange& r = ranges[c];
    if (r.begin != kept) std::copy(dst + r.begin, dst + r.begin + r.kept, dst + kept);
    kept += r.kept;
    out->dropped_nan += r.dropped;
    out->dropped_bad_time += r.bad_time;
    if (r.kept == 0) continue;
    out->t_begin = any ? std::min(out->t_begin, r.t_lo) : r.t_lo;
    out->t_end = any ? std::max(out->t_end, r.t_hi) : r.t_hi;
    any = true;
  }
  out->points.resize(kept);
}

// Any field types: each element read through its type (float32 x/y/z and intensity skip the
// per-element type dispatch; the values and the validity test are the same as through ReadAs).
void DecodeGeneral(const CloudView& cloud, const PointFields& f, const TimeMap& times,
                   DecodedScan* out) {
  const bool xyz_f32 = f.XyzFloat32();
  const bool intensity_f32 = f.IntensityFloat32();
  out->points.reserve(static_cast<size_t>(cloud.width) * cloud.height);
  ForEachPoint(cloud, [&](size_t i, const uint8_t* p) {
    const Eigen::Vector3d xyz =
        xyz_f32 ? Eigen::Vector3d(ReadFloat32(p + f.x->offset), ReadFloat32(p + f.y->offset),
                                  ReadFloat32(p + f.z->offset))
                : Eigen::Vector3d(ReadAs(p + f.x->offset, f.x->type),
                                  ReadAs(p + f.y->offset, f.y->type),
                                  ReadAs(p + f.z->offset, f.z->type));
    TimedPoint tp;
    tp.t = times.At(i, p);
    // float64 coordinates beyond float range would overflow the conversion: treat as invalid.
    if (!xyz.allFinite() || xyz.cwiseAbs().maxCoeff() > 1e30 || !std::isfinite(tp.t)) {
      ++out->dropped_nan;
      return;
    }
    if (!times.Plausible(tp.t)) {
      ++out->dropped_bad_time;
      return;
    }
    tp.p = xyz.cast<float>();
    if (f.intensity) {
      const FieldDesc& fi = *f.intensity;
      const double v = intensity_f32 ? ReadFloat32(p + fi.offset) : ReadAs(p + fi.offset, fi.type);
      tp.intensity = std::isfinite(v) && std::abs(v) < 1e30 ? static_cast<float>(v) : 0.f;
    }
    out->points.push_back(tp);
  });
}

// No time field: spread the points over one spin period by their azimuth from the first point
// (a spinning LiDAR assumed), or leave every point at the header stamp.
void ApplyNoTimePolicy(const TimeFieldOptions& options, double stamp_s, DecodedScan* out) {
  if (options.no_time_policy != NoTimePolicy::kAzimuth || out->points.empty()) {
    out->note = "no time field: scan not de-skewed";
    return;
  }
  const double period = options.scan_period_s;  // usable: the constructor checked it
  const double start = options.stamp == StampPosition::kEnd ? stamp_s - period : stamp_s;
  const double a0 = std::atan2(out->points.front().p.y(), out->points.front().p.x());
  for (TimedPoint& tp : out->points) {
    const double a = std::atan2(tp.p.y(), tp.p.x());
    double swept = options.azimuth_clockwise ? a0 - a : a - a0;
    swept = std::fmod(swept, kTwoPi);
    if (swept < 0.0) swept += kTwoPi;
    tp.t = start + period * swept / kTwoPi;
  }
  out->times_estimated = true;
  out->note = "no time field: point times estimated from azimuth";
}

// t_begin / t_end: the earliest and latest point time (left at the stamp without points).
void SetTimeSpan(DecodedScan* out) {
  if (out->points.empty()) return;
  double lo = out->points.front().t, hi = lo;
  for (const TimedPoint& tp : out->points) {
    lo = std::min(lo, tp.t);
    hi = std::max(hi, tp.t);
  }
  out->t_begin = lo;
  out->t_end = hi;
}

}  // namespace

const std::vector<std::string>& KnownTimeFieldNames() {
  static const std::vector<std::string> names = {"t", "time", "timestamp", "time_stamp",
                                                 "offset_time"};
  return names;
}

std::string TimeFieldInfo::Describe() const {
  if (!present) return "no per-point time field";
  std::ostringstream os;
  os << "time field '" << name << "' " << TypeName(type) << " (x" << unit_scale_s << " s), "
     << (absolute ? "absolute" : "relative to the header stamp");
  if (!absolute)
    os << (stamp_at_end ? ", header stamp at scan end" : ", header stamp at scan start");
  return os.str();
}

std::string ValidateCloudLayout(const CloudView& cloud) {
  const uint64_t n = static_cast<uint64_t>(cloud.width) * cloud.height;
  if (cloud.is_bigendian) return "big-endian point clouds are not supported";
  const FieldDesc* fx = FindField(cloud, "x");
  const FieldDesc* fy = FindField(cloud, "y");
  const FieldDesc* fz = FindField(cloud, "z");
  if (!fx || !fy || !fz) return "cloud lacks an x, y or z field";
  for (const FieldDesc* f : {fx, fy, fz}) {
    if (f->type != FieldType::kFloat32 && f->type != FieldType::kFloat64)
      return "field '" + f->name + "' must be float32 or float64";
    if (!FieldFits(*f, cloud.point_step)) {
      std::ostringstream os;
      os << "point_step " << cloud.point_step << " too small for field '" << f->name
         << "' at offset " << f->offset;
      return os.str();
    }
  }
  for (const FieldDesc& f : cloud.fields) {
    if (FieldTypeSize(f.type) == 0) return "field '" + f.name + "' has an unknown datatype";
  }
  if (n == 0) return "";
  if (cloud.data == nullptr) return "cloud has points but no data";
  const uint64_t row_bytes = static_cast<uint64_t>(cloud.width) * cloud.point_step;
  const uint64_t row_step = cloud.row_step == 0 ? row_bytes : cloud.row_step;
  if (row_step < row_bytes) {
    std::ostringstream os;
    os << "row_step " << cloud.row_step << " < width * point_step " << row_bytes;
    return os.str();
  }
  const uint64_t needed = (cloud.height - 1) * row_step + row_bytes;
  if (cloud.size < needed) {
    std::ostringstream os;
    os << "size mismatch: " << cloud.size << " bytes for " << cloud.width << "x" << cloud.height
       << " points of " << cloud.point_step << " bytes (need " << needed << ")";
    return os.str();
  }
  return "";
}

TimeFieldDecoder::TimeFieldDecoder(const TimeFieldOptions& options, LogCallback log)
    : options_(options), log_(std::move(log)) {
  // The core's config is validated already; a caller of the decoder alone may pass anything.
  if (!(options_.scan_period_s > 0.0 && options_.scan_period_s <= kMaxScanPeriodS)) {
    if (log_) {
      std::ostringstream os;
      os << "scan period " << options_.scan_period_s << " s is not in (0, " << kMaxScanPeriodS
         << "]: using 0.1 s";
      log_(LogLevel::kWarn, os.str());
    }
    options_.scan_period_s = 0.1;
  }
}

void TimeFieldDecoder::Detect(const CloudView& cloud, const FieldDesc* time_field,
                              const std::vector<double>& raw) {
  info_ = TimeFieldInfo();
  info_.detected = true;
  if (time_field == nullptr) {
    info_.present = false;
    if (log_) {
      log_(LogLevel::kWarn,
           std::string("no per-point time field (looked for ") +
               (options_.field.empty() ? "t/time/timestamp/time_stamp/offset_time"
                                       : options_.field) +
               "): " +
               (options_.no_time_policy == NoTimePolicy::kAzimuth
                    ? "estimating point times from azimuth (spinning LiDAR assumed)"
                    : "no de-skew"));
    }
    return;
  }
  info_.present = true;
  info_.name = time_field->name;
  info_.type = time_field->type;
  info_.offset = time_field->offset;
  info_.unit_scale_s = options_.unit_scale_s > 0.0 ? options_.unit_scale_s
                                                   : (IsIntegerType(time_field->type) ? 1e-9 : 1.0);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::vector<double> finite;
  finite.reserve(raw.size());
  for (double v : raw) {
    if (std::isfinite(v)) {
      finite.push_back(v * info_.unit_scale_s);
      lo = std::min(lo, finite.back());
      hi = std::max(hi, finite.back());
    }
  }
  double median = 0.0;
  if (!finite.empty()) {
    std::nth_element(finite.begin(), finite.begin() + finite.size() / 2, finite.end());
    median = finite[finite.size() / 2];
  }
  switch (options_.reference) {
    case TimeReference::kAbsolute:
      info_.absolute = true;
      break;
    case TimeReference::kRelative:
      info_.absolute = false;
      break;
    case TimeReference::kAuto:
      // Relative offsets are a fraction of a second; absolute times sit next to the header stamp.
      // With a stamp near zero (simulation clocks) the two are indistinguishable: assume relative.
      info_.absolute = !finite.empty() && std::abs(cloud.stamp_s) > 10.0 &&
                       std::abs(median - cloud.stamp_s) < 1.0;
      break;
  }
  switch (options_.stamp) {
    case StampPosition::kStart:
      info_.stamp_at_end = false;
      break;
    case StampPosition::kEnd:
      info_.stamp_at_end = true;
      break;
    case StampPosition::kAuto:
      info_.stamp_at_end = !info_.absolute && !finite.empty() && hi <= 1e-6 && lo < 0.0;
      break;
  }
  if (log_) log_(LogLevel::kInfo, "per-point time: " + info_.Describe());
}

bool TimeFieldDecoder::Decode(const CloudView& cloud, DecodedScan* out, std::string* error) {
  *out = DecodedScan();
  out->t_begin = out->t_end = cloud.stamp_s;
  const std::string layout_error = ValidateCloudLayout(cloud);
  if (!layout_error.empty()) {
    if (error) *error = layout_error;
    return false;
  }
  const size_t n = static_cast<size_t>(cloud.width) * cloud.height;
  out->input_points = n;
  if (n == 0) return true;

  PointFields fields{FindField(cloud, "x"), FindField(cloud, "y"), FindField(cloud, "z"),
                     FindField(cloud, "intensity")};
  if (fields.intensity && !FieldFits(*fields.intensity, cloud.point_step)) {
    fields.intensity = nullptr;
  }
  const FieldDesc* ft = FindTimeField(cloud, options_.field);
  if (ft && !FieldFits(*ft, cloud.point_step)) {
    if (error) *error = "time field '" + ft->name + "' lies outside point_step";
    return false;
  }

  // Detect once; a later change of layout (different field) triggers a new detection.
  const bool detect = !info_.detected || info_.present != (ft != nullptr) ||
                      (ft && (ft->name != info_.name || ft->type != info_.type));
  raw_t_.clear();
  // The raw times are needed as a whole only to detect the convention and for stamp-at-end
  // relative times (TimeBase); otherwise the decode loop reads each point's time itself.
  if (ft && (detect || (info_.stamp_at_end && !info_.absolute))) ReadRawTimes(cloud, *ft, &raw_t_);
  if (detect) Detect(cloud, ft, raw_t_);

  out->has_time_field = ft != nullptr;
  TimeMap times;
  times.stamp_s = cloud.stamp_s;
  if (ft) {
    if (raw_t_.empty()) {
      times.field = ft;
    } else {
      times.raw = raw_t_.data();
    }
    // Two scan periods: a sweep that takes longer than the configured period (a slower LiDAR
    // than configured, packet delays) keeps its points.
    const double span = 2.0 * options_.scan_period_s;
    times.base = TimeBase(info_, cloud.stamp_s, raw_t_, span);
    times.scale = info_.unit_scale_s;
    SetPlausibleWindow(info_, cloud.stamp_s, span, &times);
  }
  const bool all_float32 = fields.XyzFloat32() && (!fields.intensity || fields.IntensityFloat32());
  if (all_float32) {
    out->points.swap(spare_);  // resized, not cleared: every kept element is overwritten
    int threads = 1;
#ifdef _OPENMP
    threads = num_threads_ > 0 ? num_threads_ : omp_get_max_threads();
#endif
    DecodeAllFloat32(cloud, fields, times, threads, out);
  } else {
    DecodeGeneral(cloud, fields, times, out);
  }
  if (!ft) ApplyNoTimePolicy(options_, cloud.stamp_s, out);
  if (!ft || !all_float32) SetTimeSpan(out);  // DecodeAllFloat32 found the span of field times
  return true;
}

}  // namespace ppf
