#include "test_util.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace ppf::bag::test {

TempDir::TempDir() {
  std::string tmpl = "/tmp/ppf_bag_test_XXXXXX";
  if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::string ShellQuote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

CommandResult Run(const std::string& command) {
  CommandResult r;
  FILE* p = popen(command.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::vector<uint8_t> ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

void WriteFileBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path);
}

std::vector<Message> ReadAll(Reader& reader) {
  std::vector<Message> out;
  Message m;
  while (reader.Next(m)) out.push_back(m);
  return out;
}

std::vector<int64_t> Stamps(const std::vector<Message>& messages) {
  std::vector<int64_t> out;
  for (const Message& m : messages) out.push_back(m.timestamp_ns);
  return out;
}

template <typename T>
T CdrReader::Get() {
  while ((pos_ - 4) % sizeof(T)) ++pos_;
  if (pos_ + sizeof(T) > b_.size()) throw std::runtime_error("CDR underrun");
  T v;
  std::memcpy(&v, b_.data() + pos_, sizeof(T));
  pos_ += sizeof(T);
  return v;
}

std::string CdrReader::Str() {
  const uint32_t n = U32();
  if (n == 0 || pos_ + n > b_.size()) throw std::runtime_error("bad CDR string");
  std::string s(reinterpret_cast<const char*>(b_.data() + pos_), n - 1);
  pos_ += n;
  return s;
}

// ROS pads serialized messages to a multiple of 4 after the header.
bool CdrReader::AtEnd() const { return b_.size() - pos_ < 4; }

std::vector<uint8_t> EncodeImu(const Imu& m) {
  CdrWriter w;
  w.I32(m.sec);
  w.U32(m.nanosec);
  w.Str(m.frame_id);
  for (double v : m.orientation) w.F64(v);
  for (double v : m.orientation_cov) w.F64(v);
  for (double v : m.angular_velocity) w.F64(v);
  for (double v : m.angular_velocity_cov) w.F64(v);
  for (double v : m.linear_acceleration) w.F64(v);
  for (double v : m.linear_acceleration_cov) w.F64(v);
  return w.data();
}

Imu DecodeImu(const std::vector<uint8_t>& cdr) {
  Imu m;
  EXPECT_GE(cdr.size(), 4u);
  if (cdr.size() < 4) return m;
  EXPECT_EQ(cdr[0], 0x00);
  EXPECT_EQ(cdr[1], 0x01);
  CdrReader r(cdr);
  m.sec = r.I32();
  m.nanosec = r.U32();
  m.frame_id = r.Str();
  for (double& v : m.orientation) v = r.F64();
  for (double& v : m.orientation_cov) v = r.F64();
  for (double& v : m.angular_velocity) v = r.F64();
  for (double& v : m.angular_velocity_cov) v = r.F64();
  for (double& v : m.linear_acceleration) v = r.F64();
  for (double& v : m.linear_acceleration_cov) v = r.F64();
  EXPECT_TRUE(r.AtEnd()) << "trailing bytes after Imu";
  return m;
}

uint32_t Fnv1a(const std::vector<uint8_t>& bytes) {
  uint32_t h = 0x811c9dc5u;
  for (uint8_t b : bytes) h = (h ^ b) * 0x01000193u;
  return h;
}

}  // namespace ppf::bag::test
