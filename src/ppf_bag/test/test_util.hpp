// Helpers shared by the ppf_bag tests: temp dirs, shell commands, hand-built CDR.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ppf_bag/bag.hpp"

namespace ppf::bag::test {

// A fresh directory under /tmp, removed (recursively) on destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::string& path() const { return path_; }
  std::string operator/(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout (stderr goes to the test log unless redirected by the command)
};
CommandResult Run(const std::string& command);
std::string ShellQuote(const std::string& s);

std::vector<uint8_t> ReadFileBytes(const std::string& path);
void WriteFileBytes(const std::string& path, const std::vector<uint8_t>& bytes);
std::vector<Message> ReadAll(Reader& reader);
// The messages' timestamp_ns, in order.
std::vector<int64_t> Stamps(const std::vector<Message>& messages);

// Little-endian XCDR1 writer with ROS 2 encapsulation header 00 01 00 00; alignment is relative
// to the end of the header, as in rosidl/Fast CDR.
class CdrWriter {
 public:
  CdrWriter() : buf_{0x00, 0x01, 0x00, 0x00} {}
  void U8(uint8_t v) { buf_.push_back(v); }
  void Bool(bool v) { U8(v ? 1 : 0); }
  void U32(uint32_t v) { Raw(&v, 4); }
  void I32(int32_t v) { Raw(&v, 4); }
  void F64(double v) { Raw(&v, 8); }
  void Str(const std::string& s) {
    U32(static_cast<uint32_t>(s.size() + 1));
    buf_.insert(buf_.end(), s.begin(), s.end());
    buf_.push_back(0);
  }
  void Bytes(const std::vector<uint8_t>& b) {
    U32(static_cast<uint32_t>(b.size()));
    buf_.insert(buf_.end(), b.begin(), b.end());
  }
  const std::vector<uint8_t>& data() const { return buf_; }

 private:
  void Raw(const void* p, size_t n) {
    while ((buf_.size() - 4) % n) buf_.push_back(0);
    const auto* b = static_cast<const uint8_t*>(p);
    buf_.insert(buf_.end(), b, b + n);
  }
  std::vector<uint8_t> buf_;
};

class CdrReader {
 public:
  explicit CdrReader(const std::vector<uint8_t>& b) : b_(b), pos_(4) {}
  uint32_t U32() { return Get<uint32_t>(); }
  int32_t I32() { return Get<int32_t>(); }
  double F64() { return Get<double>(); }
  std::string Str();
  bool AtEnd() const;

 private:
  template <typename T>
  T Get();
  const std::vector<uint8_t>& b_;
  size_t pos_;
};

struct Imu {
  int32_t sec = 0;
  uint32_t nanosec = 0;
  std::string frame_id;
  double orientation[4] = {0, 0, 0, 1};
  double orientation_cov[9] = {};
  double angular_velocity[3] = {};
  double angular_velocity_cov[9] = {};
  double linear_acceleration[3] = {};
  double linear_acceleration_cov[9] = {};
};
std::vector<uint8_t> EncodeImu(const Imu& imu);
Imu DecodeImu(const std::vector<uint8_t>& cdr);  // gtest-asserts full consumption

uint32_t Fnv1a(const std::vector<uint8_t>& bytes);

}  // namespace ppf::bag::test
