#include "ppf_core/time_field.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

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

// Reads one element; the caller guarantees offset + size <= point_step within the buffer.
double ReadAs(const uint8_t* p, FieldType type) {
  switch (type) {
    case FieldType::kInt8: {
      int8_t v;
      std::memcpy(&v, p, 1);
      return v;
    }
    case FieldType::kUint8:
      return *p;
    case FieldType::kInt16: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    case FieldType::kUint16: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    case FieldType::kInt32: {
      int32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case FieldType::kUint32: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case FieldType::kFloat32: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case FieldType::kFloat64: {
      double v;
      std::memcpy(&v, p, 8);
      return v;
    }
  }
  return std::numeric_limits<double>::quiet_NaN();
}

bool FieldFits(const FieldDesc& f, uint32_t point_step) {
  const size_t sz = FieldTypeSize(f.type);
  return sz > 0 && static_cast<uint64_t>(f.offset) + sz <= point_step;
}

const char* TypeName(FieldType t) {
  switch (t) {
    case FieldType::kInt8:
      return "int8";
    case FieldType::kUint8:
      return "uint8";
    case FieldType::kInt16:
      return "int16";
    case FieldType::kUint16:
      return "uint16";
    case FieldType::kInt32:
      return "int32";
    case FieldType::kUint32:
      return "uint32";
    case FieldType::kFloat32:
      return "float32";
    case FieldType::kFloat64:
      return "float64";
  }
  return "unknown";
}

bool IsIntegerType(FieldType t) { return t != FieldType::kFloat32 && t != FieldType::kFloat64; }

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
  if (!absolute) os << (stamp_at_end ? ", header stamp at scan end" : ", header stamp at scan start");
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
    : options_(options), log_(std::move(log)) {}

void TimeFieldDecoder::Detect(const CloudView& cloud, const FieldDesc* time_field,
                              const std::vector<double>& raw) {
  info_ = TimeFieldInfo();
  info_.detected = true;
  if (time_field == nullptr) {
    info_.present = false;
    if (log_) {
      log_(LogLevel::kWarn,
           std::string("no per-point time field (looked for ") +
               (options_.field_name.empty() ? "t/time/timestamp/time_stamp/offset_time"
                                            : options_.field_name) +
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
  info_.unit_scale_s = options_.unit_scale_s > 0.0
                           ? options_.unit_scale_s
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
  switch (options_.stamp_position) {
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

  const FieldDesc* fx = FindField(cloud, "x");
  const FieldDesc* fy = FindField(cloud, "y");
  const FieldDesc* fz = FindField(cloud, "z");
  const FieldDesc* fi = FindField(cloud, "intensity");
  if (fi && !FieldFits(*fi, cloud.point_step)) fi = nullptr;
  const FieldDesc* ft = nullptr;
  if (!options_.field_name.empty()) {
    ft = FindField(cloud, options_.field_name);
  } else {
    for (const std::string& name : KnownTimeFieldNames()) {
      if ((ft = FindField(cloud, name)) != nullptr) break;
    }
  }
  if (ft && !FieldFits(*ft, cloud.point_step)) {
    if (error) *error = "time field '" + ft->name + "' lies outside point_step";
    return false;
  }

  const uint64_t row_step =
      cloud.row_step == 0 ? static_cast<uint64_t>(cloud.width) * cloud.point_step : cloud.row_step;
  // Visits the points in index order, row by row (no division per point).
  auto for_each_point = [&](auto&& visit) {
    size_t i = 0;
    for (uint32_t row = 0; row < cloud.height; ++row) {
      const uint8_t* p = cloud.data + row * row_step;
      for (uint32_t col = 0; col < cloud.width; ++col, ++i, p += cloud.point_step) visit(i, p);
    }
  };

  std::vector<double>& raw_t = raw_t_;
  raw_t.clear();
  if (ft) {
    raw_t.resize(n);
    if (ft->type == FieldType::kFloat32) {
      for_each_point([&](size_t i, const uint8_t* p) { raw_t[i] = ReadFloat32(p + ft->offset); });
    } else {
      for_each_point(
          [&](size_t i, const uint8_t* p) { raw_t[i] = ReadAs(p + ft->offset, ft->type); });
    }
  }
  // Detect once; a later change of layout (different field) triggers a new detection.
  if (!info_.detected || info_.present != (ft != nullptr) ||
      (ft && (ft->name != info_.name || ft->type != info_.type))) {
    Detect(cloud, ft, raw_t);
  }

  out->has_time_field = ft != nullptr;
  out->points.reserve(n);
  double base = cloud.stamp_s;
  double scale = info_.unit_scale_s;
  if (ft) {
    if (info_.absolute) {
      base = 0.0;
    } else if (info_.stamp_at_end) {
      // Times ending at 0 are offsets from the end already; non-negative ones are shifted so the
      // last point lands on the stamp.
      double hi = -std::numeric_limits<double>::infinity();
      for (double v : raw_t) {
        if (std::isfinite(v)) hi = std::max(hi, v * scale);
      }
      if (std::isfinite(hi) && hi > 0.0) base = cloud.stamp_s - hi;
    }
  }

  // float32 x/y/z and intensity (nearly every driver) skip the per-element type dispatch; the
  // values and the validity test are the same as through ReadAs.
  const bool xyz_f32 = fx->type == FieldType::kFloat32 && fy->type == FieldType::kFloat32 &&
                       fz->type == FieldType::kFloat32;
  const bool intensity_f32 = fi && fi->type == FieldType::kFloat32;
  auto decode = [&](size_t i, const uint8_t* p, const Eigen::Vector3d& xyz) {
    TimedPoint tp;
    tp.t = ft ? base + raw_t[i] * scale : cloud.stamp_s;
    // float64 coordinates beyond float range would overflow the conversion: treat as invalid.
    if (!xyz.allFinite() || xyz.cwiseAbs().maxCoeff() > 1e30 || !std::isfinite(tp.t)) {
      ++out->dropped_nan;
      return;
    }
    tp.p = xyz.cast<float>();
    if (fi) {
      const double v =
          intensity_f32 ? ReadFloat32(p + fi->offset) : ReadAs(p + fi->offset, fi->type);
      tp.intensity = std::isfinite(v) && std::abs(v) < 1e30 ? static_cast<float>(v) : 0.f;
    }
    out->points.push_back(tp);
  };
  if (xyz_f32 && (!fi || intensity_f32)) {
    // Every field float32 (nearly every driver): one pass writing straight into the output, with
    // the general path's values and validity test (a non-finite or > 1e30 coordinate fails
    // |c| <= 1e30; the time is the same double).
    out->points.resize(n);
    TimedPoint* dst = out->points.data();
    size_t kept = 0;
    const uint32_t ox = fx->offset, oy = fy->offset, oz = fz->offset;
    const uint32_t oi = fi ? fi->offset : 0;
    const double* times = ft ? raw_t.data() : nullptr;
    for_each_point([&](size_t i, const uint8_t* p) {
      const double x = ReadFloat32(p + ox), y = ReadFloat32(p + oy), z = ReadFloat32(p + oz);
      const double t = times ? base + times[i] * scale : cloud.stamp_s;
      if (!(std::abs(x) <= 1e30 && std::abs(y) <= 1e30 && std::abs(z) <= 1e30) ||
          !std::isfinite(t)) {
        ++out->dropped_nan;
        return;
      }
      TimedPoint& tp = dst[kept++];
      tp.p = Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
      tp.t = t;
      if (fi) {
        const double v = ReadFloat32(p + oi);
        tp.intensity = std::isfinite(v) && std::abs(v) < 1e30 ? static_cast<float>(v) : 0.f;
      } else {
        tp.intensity = 0.f;
      }
    });
    out->points.resize(kept);
  } else if (xyz_f32) {
    for_each_point([&](size_t i, const uint8_t* p) {
      decode(i, p,
             Eigen::Vector3d(ReadFloat32(p + fx->offset), ReadFloat32(p + fy->offset),
                             ReadFloat32(p + fz->offset)));
    });
  } else {
    for_each_point([&](size_t i, const uint8_t* p) {
      decode(i, p,
             Eigen::Vector3d(ReadAs(p + fx->offset, fx->type), ReadAs(p + fy->offset, fy->type),
                             ReadAs(p + fz->offset, fz->type)));
    });
  }

  if (!ft) {
    if (options_.no_time_policy == NoTimePolicy::kAzimuth && !out->points.empty()) {
      const double period = options_.scan_period_s > 0.0 ? options_.scan_period_s : 0.1;
      const double start =
          options_.stamp_position == StampPosition::kEnd ? cloud.stamp_s - period : cloud.stamp_s;
      const double a0 = std::atan2(out->points.front().p.y(), out->points.front().p.x());
      for (TimedPoint& tp : out->points) {
        const double a = std::atan2(tp.p.y(), tp.p.x());
        double swept = options_.azimuth_clockwise ? a0 - a : a - a0;
        swept = std::fmod(swept, kTwoPi);
        if (swept < 0.0) swept += kTwoPi;
        tp.t = start + period * swept / kTwoPi;
      }
      out->times_estimated = true;
      out->note = "no time field: point times estimated from azimuth";
    } else {
      out->note = "no time field: scan not de-skewed";
    }
  }

  if (!out->points.empty()) {
    double lo = out->points.front().t, hi = lo;
    for (const TimedPoint& tp : out->points) {
      lo = std::min(lo, tp.t);
      hi = std::max(hi, tp.t);
    }
    out->t_begin = lo;
    out->t_end = hi;
  }
  return true;
}

}  // namespace ppf
