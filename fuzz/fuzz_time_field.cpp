// Fuzz target: the per-point time decoder on arbitrary cloud layouts, without the CDR layer in
// front (which rarely produces a well-formed header around interesting field tables), including
// point times far outside the sweep (seeds: 1e6 s late, 100 s early). The input
// is read as a small layout description followed by the point bytes; layout values are biased
// towards the ranges real drivers use so the search reaches the decoding paths, not only the
// layout rejections.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "ppf_core/lio/time_field.hpp"

namespace {

// Consumes bytes from the front; past the end every read returns zeros.
class Bytes {
 public:
  Bytes(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  template <typename T>
  T Take() {
    T v{};
    const size_t n = std::min(sizeof(T), size_ - pos_);
    std::memcpy(&v, data_ + pos_, n);
    pos_ += n;
    return v;
  }
  const uint8_t* rest() const { return data_ + pos_; }
  size_t rest_size() const { return size_ - pos_; }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

const char* const kNames[] = {"x", "y", "z", "intensity", "t", "time", "timestamp",
                              "time_stamp", "offset_time", "ring"};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Bytes in(data, size);
  ppf::TimeFieldOptions options;
  const uint8_t opt = in.Take<uint8_t>();
  options.reference = static_cast<ppf::TimeReference>(opt % 3);
  options.stamp = static_cast<ppf::StampPosition>((opt / 3) % 3);
  options.no_time_policy = (opt & 0x10) ? ppf::NoTimePolicy::kNoDeskew : ppf::NoTimePolicy::kAzimuth;
  options.azimuth_clockwise = (opt & 0x20) != 0;
  if (opt & 0x40) options.field = kNames[in.Take<uint8_t>() % 10];
  if (opt & 0x80) options.unit_scale_s = in.Take<double>();
  options.scan_period_s = in.Take<double>();

  ppf::CloudView cloud;
  cloud.stamp_s = in.Take<double>();
  cloud.height = in.Take<uint8_t>() % 4;  // 0..3 rows: organized and unorganized
  cloud.width = in.Take<uint16_t>();
  cloud.point_step = in.Take<uint8_t>();
  cloud.row_step = in.Take<uint16_t>();
  cloud.is_bigendian = (in.Take<uint8_t>() & 0x7) == 0;
  const int nfields = in.Take<uint8_t>() % 9;
  for (int i = 0; i < nfields; ++i) {
    ppf::FieldDesc f;
    f.name = kNames[in.Take<uint8_t>() % 10];
    f.offset = in.Take<uint8_t>();
    f.type = static_cast<ppf::FieldType>(in.Take<uint8_t>() % 10);  // 0 and 9 are invalid
    f.count = 1;
    cloud.fields.push_back(f);
  }
  // The decoder promises never to read outside [data, data + size): an exact-size heap copy
  // lets AddressSanitizer catch the first byte beyond.
  std::vector<uint8_t> points(in.rest(), in.rest() + in.rest_size());
  cloud.data = points.empty() ? nullptr : points.data();
  cloud.size = points.size();

  ppf::TimeFieldDecoder decoder(options);
  ppf::DecodedScan scan;
  std::string error;
  if (!decoder.Decode(cloud, &scan, &error)) {
    if (!scan.points.empty()) {
      std::fprintf(stderr, "a rejected cloud left points behind\n");
      std::abort();
    }
    return 0;
  }
  // Every input point is kept or counted: non-finite, or its time outside the sweep window.
  if (scan.points.size() + scan.dropped_nan + scan.dropped_bad_time != scan.input_points) {
    std::fprintf(stderr, "%zu points + %zu non-finite + %zu bad time != %zu input points\n",
                 scan.points.size(), scan.dropped_nan, scan.dropped_bad_time, scan.input_points);
    std::abort();
  }
  for (const ppf::TimedPoint& p : scan.points) {
    if (!p.p.allFinite() || !std::isfinite(p.t) || p.t < scan.t_begin || p.t > scan.t_end) {
      std::fprintf(stderr, "decoded point outside its promises\n");
      std::abort();
    }
  }
  // A second scan with the same layout takes the already-detected path.
  decoder.Decode(cloud, &scan, &error);
  return 0;
}
