// MCAP wire-level helpers: opcodes, little-endian builders and a bounds-checked parser.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "ppf_bag/bag.hpp"

namespace ppf::bag::detail::mcap {

inline constexpr uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum Op : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// Opcode byte + uint64 length.
inline constexpr size_t kRecordPrefix = 9;
// Footer content: summary_start, summary_offset_start, summary_crc.
inline constexpr size_t kFooterContent = 20;
inline constexpr size_t kFooterRecord = kRecordPrefix + kFooterContent;

class Builder {
 public:
  std::vector<uint8_t> buf;

  void U8(uint8_t v) { buf.push_back(v); }
  void U16(uint16_t v) { Le(v, 2); }
  void U32(uint32_t v) { Le(v, 4); }
  void U64(uint64_t v) { Le(v, 8); }
  void Bytes(const void* p, size_t n) {
    const auto* b = static_cast<const uint8_t*>(p);
    buf.insert(buf.end(), b, b + n);
  }
  void Str(const std::string& s) {
    U32(static_cast<uint32_t>(s.size()));
    Bytes(s.data(), s.size());
  }
  // Starts a record; returns the position of its length field for EndRecord().
  size_t BeginRecord(uint8_t op) {
    U8(op);
    const size_t at = buf.size();
    U64(0);
    return at;
  }
  void EndRecord(size_t at) { Patch64(at, buf.size() - at - 8); }
  // Starts a uint32 length-prefixed Map/Array.
  size_t Begin32() {
    const size_t at = buf.size();
    U32(0);
    return at;
  }
  void End32(size_t at) {
    const uint64_t n = buf.size() - at - 4;
    for (int i = 0; i < 4; ++i) buf[at + i] = static_cast<uint8_t>(n >> (8 * i));
  }
  void Patch64(size_t at, uint64_t v) {
    for (int i = 0; i < 8; ++i) buf[at + i] = static_cast<uint8_t>(v >> (8 * i));
  }

 private:
  void Le(uint64_t v, int n) {
    for (int i = 0; i < n; ++i) buf.push_back(static_cast<uint8_t>(v >> (8 * i)));
  }
};

// Parses a byte range; every read is bounds-checked and throws BagError naming `what_`.
class Parser {
 public:
  Parser(const uint8_t* p, size_t n, std::string what) : p_(p), n_(n), what_(std::move(what)) {}

  size_t pos() const { return pos_; }
  size_t remaining() const { return n_ - pos_; }
  bool done() const { return pos_ == n_; }
  const uint8_t* cur() const { return p_ + pos_; }

  uint8_t U8() { return static_cast<uint8_t>(Le(1)); }
  uint16_t U16() { return static_cast<uint16_t>(Le(2)); }
  uint32_t U32() { return static_cast<uint32_t>(Le(4)); }
  uint64_t U64() { return Le(8); }
  std::string Str() {
    const uint32_t n = U32();
    Need(n);
    std::string s(reinterpret_cast<const char*>(p_ + pos_), n);
    pos_ += n;
    return s;
  }
  // Returns a sub-parser over the next n bytes and skips them.
  Parser Sub(uint64_t n, const std::string& what) {
    Need(n);
    Parser sub(p_ + pos_, static_cast<size_t>(n), what_ + ": " + what);
    pos_ += static_cast<size_t>(n);
    return sub;
  }
  Parser Sub32(const std::string& what) { return Sub(U32(), what); }
  void Skip(uint64_t n) {
    Need(n);
    pos_ += static_cast<size_t>(n);
  }
  [[noreturn]] void Fail(const std::string& msg) const {
    throw BagError(what_ + ": " + msg + " (at byte " + std::to_string(pos_) + ")");
  }

 private:
  void Need(uint64_t n) const {
    if (n > n_ - pos_) {
      Fail("truncated record: need " + std::to_string(n) + " bytes, only " +
           std::to_string(n_ - pos_) + " left");
    }
  }
  uint64_t Le(int n) {
    Need(n);
    uint64_t v = 0;
    for (int i = 0; i < n; ++i) v |= uint64_t(p_[pos_ + i]) << (8 * i);
    pos_ += n;
    return v;
  }

  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
  std::string what_;
};

}  // namespace ppf::bag::detail::mcap
