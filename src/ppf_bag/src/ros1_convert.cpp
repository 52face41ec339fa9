#include "ros1_convert.hpp"

#include <cstring>
#include <limits>
#include <stdexcept>

namespace ppf::bag::detail {
namespace {

// md5sums of the ROS 1 definitions we decode (as genmsg computes them and rosbag stores them in
// every connection header). A connection of the same type name with another md5sum is not
// decoded (see Ros1ConversionFor).
constexpr const char* kPointCloud2Md5 = "1158d486dd51d683ce2f1be655c3c181";
constexpr const char* kImuMd5 = "6a62c6daae103f4ff57a132d6f95cec2";

// Thrown inside this file only, turned into (false, error) by ConvertRos1Message.
struct Malformed : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// ROS 1 serialization: little endian, packed, strings and arrays as uint32 length + elements.
class Ros1In {
 public:
  Ros1In(const uint8_t* p, size_t n) : p_(p), n_(n) {}
  uint8_t U8() { return Get<uint8_t>(); }
  uint32_t U32() { return Get<uint32_t>(); }
  uint64_t U64() { return Get<uint64_t>(); }
  const uint8_t* Bytes(size_t n, const char* what) {
    if (n > n_ - pos_) {
      throw Malformed(std::string(what) + " of " + std::to_string(n) + " bytes at byte " +
                      std::to_string(pos_) + " runs past the end of the " + std::to_string(n_) +
                      "-byte message");
    }
    const uint8_t* r = p_ + pos_;
    pos_ += n;
    return r;
  }
  std::string Str(const char* what) {
    const uint32_t len = U32();
    const uint8_t* b = Bytes(len, what);
    return std::string(reinterpret_cast<const char*>(b), len);
  }
  size_t pos() const { return pos_; }
  size_t remaining() const { return n_ - pos_; }

 private:
  template <typename T>
  T Get() {
    T v;
    std::memcpy(&v, Bytes(sizeof(T), "field"), sizeof(T));
    return v;
  }
  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
};

// XCDR1 little endian with the 00 01 00 00 encapsulation header; alignment counts from the end
// of that header, as rosidl / Fast CDR do. No trailing padding (readers accept both).
class CdrOut {
 public:
  explicit CdrOut(std::vector<uint8_t>* out) : b_(*out) { b_.assign({0x00, 0x01, 0x00, 0x00}); }
  void U8(uint8_t v) { b_.push_back(v); }
  void U32(uint32_t v) { Put(&v, 4); }
  void I32(int32_t v) { Put(&v, 4); }
  void F64(double v) { Put(&v, 8); }
  void Str(const std::string& s) {
    U32(static_cast<uint32_t>(s.size() + 1));
    b_.insert(b_.end(), s.begin(), s.end());
    b_.push_back(0);
  }
  void Bytes(const uint8_t* p, size_t n) { b_.insert(b_.end(), p, p + n); }
  void Reserve(size_t n) { b_.reserve(n); }
  std::vector<uint8_t>& buffer() { return b_; }

 private:
  void Put(const void* p, size_t n) {
    while ((b_.size() - 4) % n) b_.push_back(0);
    const auto* c = static_cast<const uint8_t*>(p);
    b_.insert(b_.end(), c, c + n);
  }
  std::vector<uint8_t>& b_;
};

void WriteStamp(CdrOut& out, uint32_t sec, uint32_t nsec) {
  // ROS 2 stamps are int32 seconds: a ROS 1 stamp after 2038 has no ROS 2 equivalent.
  if (sec > static_cast<uint32_t>(std::numeric_limits<int32_t>::max())) {
    throw Malformed("header stamp " + std::to_string(sec) + " s does not fit ROS 2's int32 sec");
  }
  out.I32(static_cast<int32_t>(sec));
  out.U32(nsec);
}

// std_msgs/Header: ROS 1 has uint32 seq first, ROS 2 dropped it.
void ConvertHeader(Ros1In& in, CdrOut& out) {
  in.U32();  // seq
  const uint32_t sec = in.U32();
  const uint32_t nsec = in.U32();
  WriteStamp(out, sec, nsec);
  out.Str(in.Str("header.frame_id"));
}

void ConvertPointCloud2(Ros1In& in, CdrOut& out) {
  ConvertHeader(in, out);
  out.U32(in.U32());  // height
  out.U32(in.U32());  // width
  const uint32_t nfields = in.U32();
  // Each field takes at least 13 bytes in ROS 1: bounds the count before looping on it.
  if (nfields > in.remaining() / 13) {
    throw Malformed("PointCloud2 declares " + std::to_string(nfields) +
                    " fields, more than the message can hold");
  }
  out.U32(nfields);
  for (uint32_t i = 0; i < nfields; ++i) {
    out.Str(in.Str("fields[].name"));
    out.U32(in.U32());  // offset
    out.U8(in.U8());    // datatype
    out.U32(in.U32());  // count
  }
  out.U8(in.U8());    // is_bigendian
  out.U32(in.U32());  // point_step
  out.U32(in.U32());  // row_step
  const uint32_t ndata = in.U32();
  const uint8_t* data = in.Bytes(ndata, "PointCloud2 data");
  out.U32(ndata);
  out.Reserve(out.buffer().size() + ndata + 1);
  out.Bytes(data, ndata);
  out.U8(in.U8());  // is_dense
}

void ConvertImu(Ros1In& in, CdrOut& out) {
  ConvertHeader(in, out);
  // orientation (4), covariance (9), angular_velocity (3), covariance (9),
  // linear_acceleration (3), covariance (9): all float64, no nesting beyond that.
  for (int i = 0; i < 4 + 9 + 3 + 9 + 3 + 9; ++i) {
    double v;
    std::memcpy(&v, in.Bytes(8, "Imu float64"), 8);
    out.F64(v);
  }
}

// livox_ros_driver(2)/CustomMsg: Header, uint64 timebase (ns, time of the first point),
// uint32 point_num, uint8 lidar_id, uint8[3] rsvd, CustomPoint[] points; CustomPoint is
// uint32 offset_time (ns after timebase), float32 x, y, z, uint8 reflectivity, tag, line.
void ConvertLivox(Ros1In& in, CdrOut& out) {
  in.U32();  // seq
  in.U32();  // stamp sec: replaced by timebase, see below
  in.U32();  // stamp nsec
  const std::string frame = in.Str("header.frame_id");
  const uint64_t timebase = in.U64();
  in.U32();                       // point_num (the array length below is authoritative)
  in.Bytes(4, "lidar_id, rsvd");  // lidar_id, rsvd[3]
  const uint32_t n = in.U32();
  constexpr size_t kIn = 19;  // packed CustomPoint size
  if (n > in.remaining() / kIn) {
    throw Malformed("CustomMsg declares " + std::to_string(n) +
                    " points, more than the message can hold");
  }
  // offset_time is relative to timebase, so timebase becomes the cloud's stamp: the per-point
  // times stay exact integers relative to the header, as the core's time-field decoder expects.
  WriteStamp(out, static_cast<uint32_t>(timebase / 1000000000u),
             static_cast<uint32_t>(timebase % 1000000000u));
  out.Str(frame);
  out.U32(1);  // height
  out.U32(n);  // width
  struct Field {
    const char* name;
    uint32_t offset;
    uint8_t datatype;  // sensor_msgs/PointField constants
  };
  static const Field kFields[] = {{"x", 0, 7},           {"y", 4, 7},    {"z", 8, 7},
                                  {"intensity", 12, 7},  {"tag", 16, 2}, {"line", 17, 2},
                                  {"offset_time", 20, 6}};
  out.U32(static_cast<uint32_t>(sizeof(kFields) / sizeof(kFields[0])));
  for (const Field& f : kFields) {
    out.Str(f.name);
    out.U32(f.offset);
    out.U8(f.datatype);
    out.U32(1);
  }
  out.U8(0);  // is_bigendian
  out.U32(kLivoxPointStep);
  out.U32(kLivoxPointStep * n);
  out.U32(kLivoxPointStep * n);
  std::vector<uint8_t>& b = out.buffer();
  const size_t base = b.size();
  b.resize(base + size_t(kLivoxPointStep) * n + 1, 0);
  for (uint32_t i = 0; i < n; ++i) {
    const uint8_t* p = in.Bytes(kIn, "CustomPoint");
    uint8_t* q = b.data() + base + size_t(kLivoxPointStep) * i;
    std::memcpy(q, p + 4, 12);                          // x, y, z
    const float intensity = static_cast<float>(p[16]);  // reflectivity 0..255
    std::memcpy(q + 12, &intensity, 4);
    q[16] = p[17];              // tag
    q[17] = p[18];              // line
    std::memcpy(q + 20, p, 4);  // offset_time
  }
  // is_dense: Livox clouds carry no NaN placeholders.
  b.back() = 1;
}

}  // namespace

Ros1Conversion Ros1ConversionFor(const std::string& type, const std::string& md5sum) {
  if (type == "sensor_msgs/PointCloud2" && md5sum == kPointCloud2Md5) {
    return Ros1Conversion::kPointCloud2;
  }
  if (type == "sensor_msgs/Imu" && md5sum == kImuMd5) return Ros1Conversion::kImu;
  if (type == "livox_ros_driver/CustomMsg" || type == "livox_ros_driver2/CustomMsg") {
    return Ros1Conversion::kLivoxCustom;
  }
  return Ros1Conversion::kPassThrough;
}

std::string Ros1PresentedType(Ros1Conversion conversion, const std::string& ros1_type) {
  switch (conversion) {
    case Ros1Conversion::kPointCloud2:
    case Ros1Conversion::kLivoxCustom:
      return "sensor_msgs/msg/PointCloud2";
    case Ros1Conversion::kImu:
      return "sensor_msgs/msg/Imu";
    case Ros1Conversion::kPassThrough:
      break;
  }
  return ros1_type;
}

bool ConvertRos1Message(Ros1Conversion conversion, const uint8_t* data, size_t size,
                        std::vector<uint8_t>* out, std::string* error) {
  if (conversion == Ros1Conversion::kPassThrough) {
    out->assign(data, data + size);
    return true;
  }
  Ros1In in(data, size);
  CdrOut cdr(out);
  try {
    switch (conversion) {
      case Ros1Conversion::kPointCloud2:
        ConvertPointCloud2(in, cdr);
        break;
      case Ros1Conversion::kImu:
        ConvertImu(in, cdr);
        break;
      case Ros1Conversion::kLivoxCustom:
        ConvertLivox(in, cdr);
        break;
      case Ros1Conversion::kPassThrough:
        break;
    }
  } catch (const Malformed& e) {
    *error = e.what();
    return false;
  }
  if (in.remaining() != 0) {
    *error = std::to_string(in.remaining()) + " unexpected trailing bytes after byte " +
             std::to_string(in.pos());
    return false;
  }
  return true;
}

}  // namespace ppf::bag::detail
