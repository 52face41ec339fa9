// ROS 1 bag format 2.0 at the record level: op codes, header fields, records inside an inflated
// chunk, bz2 chunks. The file's layout and how it is read are ros1_reader.cpp's.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "ppf_bag/bag.hpp"

namespace ppf::bag::detail::ros1 {

inline constexpr char kMagic[] = "#ROSBAG V2.0\n";
inline constexpr size_t kMagicSize = sizeof(kMagic) - 1;

enum Op : uint8_t {
  kMessageData = 0x02,
  kBagHeader = 0x03,
  kIndexData = 0x04,
  kChunk = 0x05,
  kChunkInfo = 0x06,
  kConnection = 0x07,
};

// Largest record header we accept: real ones are a few hundred bytes (a connection's header
// holds only op, conn and topic; the message definition is in its data).
inline constexpr uint32_t kMaxHeaderLen = 1 << 20;

using Fields = std::map<std::string, std::string>;

std::string OpName(uint8_t op);

// Header fields of one record. `where` describes the record's position for error messages.
Fields ParseFields(const uint8_t* p, size_t n, const std::string& where);

template <typename T>
T FieldAs(const Fields& f, const char* name, const std::string& where) {
  auto it = f.find(name);
  if (it == f.end()) throw BagError(where + ": header has no '" + name + "' field");
  if (it->second.size() != sizeof(T)) {
    throw BagError(where + ": header field '" + name + "' has " +
                   std::to_string(it->second.size()) + " bytes, expected " +
                   std::to_string(sizeof(T)));
  }
  T v;
  std::memcpy(&v, it->second.data(), sizeof(T));
  return v;
}

const std::string& FieldStr(const Fields& f, const char* name, const std::string& where);

// ROS 1 time: uint32 sec, uint32 nsec.
uint64_t TimeField(const Fields& f, const char* name, const std::string& where);

// A record inside an in-memory buffer (an inflated chunk).
struct BufRecord {
  Fields header;
  size_t data_pos = 0;
  uint32_t data_len = 0;
  size_t end = 0;
};

BufRecord ParseBufRecord(const std::vector<uint8_t>& b, size_t pos, const std::string& where);

// Streams, so the buffer grows only as output really arrives: a corrupt `size` field of up to
// 4 GiB must not allocate 4 GiB up front (bz2 has no bounded expansion ratio to check it against).
std::vector<uint8_t> Bz2Decompress(const std::vector<uint8_t>& in, uint32_t expected,
                                   const std::string& where);

}  // namespace ppf::bag::detail::ros1
