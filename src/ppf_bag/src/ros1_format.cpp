#include "ros1_format.hpp"

#include <bzlib.h>

#include <algorithm>
#include <cstring>
#include <memory>

namespace ppf::bag::detail::ros1 {

std::string OpName(uint8_t op) {
  const char* d = "0123456789abcdef";
  return std::string("0x") + d[op >> 4] + d[op & 15];
}

Fields ParseFields(const uint8_t* p, size_t n, const std::string& where) {
  Fields f;
  size_t pos = 0;
  while (pos < n) {
    if (n - pos < 4) throw BagError(where + ": header field length cut off");
    uint32_t len;
    std::memcpy(&len, p + pos, 4);
    pos += 4;
    if (len > n - pos) {
      throw BagError(where + ": header field of " + std::to_string(len) +
                     " bytes runs past the header's end");
    }
    const char* s = reinterpret_cast<const char*>(p + pos);
    const char* eq = static_cast<const char*>(std::memchr(s, '=', len));
    if (eq == nullptr) throw BagError(where + ": header field without '='");
    f[std::string(s, eq)] = std::string(eq + 1, s + len);
    pos += len;
  }
  return f;
}

const std::string& FieldStr(const Fields& f, const char* name, const std::string& where) {
  auto it = f.find(name);
  if (it == f.end()) throw BagError(where + ": header has no '" + name + "' field");
  return it->second;
}

uint64_t TimeField(const Fields& f, const char* name, const std::string& where) {
  const uint64_t raw = FieldAs<uint64_t>(f, name, where);
  const uint64_t sec = raw & 0xffffffffu, nsec = raw >> 32;
  return sec * 1000000000u + nsec;
}

BufRecord ParseBufRecord(const std::vector<uint8_t>& b, size_t pos, const std::string& where) {
  BufRecord r;
  auto u32 = [&](size_t at, const char* what) {
    if (at > b.size() || b.size() - at < 4) throw BagError(where + ": " + what + " cut off");
    uint32_t v;
    std::memcpy(&v, b.data() + at, 4);
    return v;
  };
  const uint32_t hlen = u32(pos, "record header length");
  if (hlen > b.size() - pos - 4) throw BagError(where + ": record header runs past the chunk");
  r.header = ParseFields(b.data() + pos + 4, hlen, where);
  r.data_len = u32(pos + 4 + hlen, "record data length");
  r.data_pos = pos + 8 + hlen;
  if (r.data_len > b.size() - r.data_pos) {
    throw BagError(where + ": record data of " + std::to_string(r.data_len) +
                   " bytes runs past the chunk");
  }
  r.end = r.data_pos + r.data_len;
  return r;
}

std::vector<uint8_t> Bz2Decompress(const std::vector<uint8_t>& in, uint32_t expected,
                                   const std::string& where) {
  bz_stream s;
  std::memset(&s, 0, sizeof(s));
  if (BZ2_bzDecompressInit(&s, 0, 0) != BZ_OK) throw BagError(where + ": bzlib init failed");
  std::unique_ptr<bz_stream, int (*)(bz_stream*)> guard(&s, &BZ2_bzDecompressEnd);
  // One byte beyond `expected` makes output past the declared size detectable.
  const uint64_t limit = uint64_t(expected) + 1;
  std::vector<uint8_t> out(std::min<uint64_t>(limit, 1 << 20));
  s.next_in = const_cast<char*>(reinterpret_cast<const char*>(in.data()));
  s.avail_in = static_cast<unsigned int>(in.size());
  uint64_t produced = 0;
  for (;;) {
    if (produced == out.size()) {
      if (out.size() >= limit) break;
      out.resize(std::min<uint64_t>(limit, out.size() * 2));
    }
    s.next_out = reinterpret_cast<char*>(out.data() + produced);
    s.avail_out = static_cast<unsigned int>(out.size() - produced);
    const unsigned int before = s.avail_out;
    const int rc = BZ2_bzDecompress(&s);
    produced += before - s.avail_out;
    if (rc == BZ_STREAM_END) break;
    if (rc != BZ_OK) {
      throw BagError(where + ": bz2 chunk is corrupt (bzlib error " + std::to_string(rc) + ")");
    }
    if (s.avail_in == 0 && s.avail_out > 0) {
      throw BagError(where + ": bz2 chunk is truncated (stream ends early)");
    }
  }
  if (produced != expected) {
    throw BagError(where + ": bz2 chunk inflated to " +
                   (produced > expected ? "more than" : std::to_string(produced)) +
                   " bytes, expected " + std::to_string(expected));
  }
  out.resize(expected);
  return out;
}

}  // namespace ppf::bag::detail::ros1
