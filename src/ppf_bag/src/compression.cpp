#include "compression.hpp"

#include <lz4frame.h>
#include <zstd.h>

#include <cstring>
#include <memory>

#include "ppf_bag/bag.hpp"

namespace ppf::bag::detail {
namespace {

// Largest chunk we agree to inflate; protects against a corrupt size field asking for terabytes.
constexpr uint64_t kMaxUncompressed = uint64_t(1) << 34;

std::vector<uint8_t> Lz4Compress(const uint8_t* data, size_t size) {
  LZ4F_preferences_t prefs;
  std::memset(&prefs, 0, sizeof(prefs));
  prefs.frameInfo.contentSize = size;
  std::vector<uint8_t> out(LZ4F_compressFrameBound(size, &prefs));
  const size_t n = LZ4F_compressFrame(out.data(), out.size(), data, size, &prefs);
  if (LZ4F_isError(n)) throw BagError(std::string("lz4 compression failed: ") + LZ4F_getErrorName(n));
  out.resize(n);
  return out;
}

std::vector<uint8_t> Lz4Decompress(const uint8_t* data, size_t size, uint64_t expected) {
  LZ4F_dctx* raw = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&raw, LZ4F_VERSION))) {
    throw BagError("lz4: cannot create decompression context");
  }
  std::unique_ptr<LZ4F_dctx, decltype(&LZ4F_freeDecompressionContext)> ctx(
      raw, &LZ4F_freeDecompressionContext);
  std::vector<uint8_t> out(expected);
  size_t in_pos = 0, out_pos = 0;
  size_t hint = 1;
  // Concatenated frames are legal; keep going until all input is consumed.
  while (in_pos < size) {
    size_t dst_size = out.size() - out_pos;
    size_t src_size = size - in_pos;
    hint = LZ4F_decompress(ctx.get(), out.data() + out_pos, &dst_size, data + in_pos, &src_size,
                           nullptr);
    if (LZ4F_isError(hint)) {
      throw BagError(std::string("lz4 chunk is corrupt: ") + LZ4F_getErrorName(hint));
    }
    in_pos += src_size;
    out_pos += dst_size;
    if (src_size == 0 && dst_size == 0) {
      throw BagError("lz4 chunk decompresses to more than its declared uncompressed size " +
                     std::to_string(expected));
    }
  }
  if (hint != 0) throw BagError("lz4 chunk is truncated (incomplete frame)");
  if (out_pos != expected) {
    throw BagError("lz4 chunk decompressed to " + std::to_string(out_pos) + " bytes, expected " +
                   std::to_string(expected));
  }
  return out;
}

std::vector<uint8_t> ZstdCompress(const uint8_t* data, size_t size) {
  std::vector<uint8_t> out(ZSTD_compressBound(size));
  const size_t n = ZSTD_compress(out.data(), out.size(), data, size, 3);
  if (ZSTD_isError(n)) throw BagError(std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
  out.resize(n);
  return out;
}

std::vector<uint8_t> ZstdDecompress(const uint8_t* data, size_t size, uint64_t expected) {
  std::vector<uint8_t> out(expected);
  const size_t n = ZSTD_decompress(out.data(), out.size(), data, size);
  if (ZSTD_isError(n)) {
    throw BagError(std::string("zstd chunk is corrupt: ") + ZSTD_getErrorName(n));
  }
  if (n != expected) {
    throw BagError("zstd chunk decompressed to " + std::to_string(n) + " bytes, expected " +
                   std::to_string(expected));
  }
  return out;
}

}  // namespace

bool IsSupportedCompression(const std::string& a) {
  return a.empty() || a == "none" || a == "lz4" || a == "zstd";
}

std::vector<uint8_t> Compress(const std::string& algorithm, const uint8_t* data, size_t size) {
  if (algorithm.empty() || algorithm == "none") return std::vector<uint8_t>(data, data + size);
  if (algorithm == "lz4") return Lz4Compress(data, size);
  if (algorithm == "zstd") return ZstdCompress(data, size);
  throw BagError("unsupported compression '" + algorithm + "' (expected none, lz4 or zstd)");
}

std::vector<uint8_t> Decompress(const std::string& algorithm, const uint8_t* data, size_t size,
                                uint64_t uncompressed_size) {
  if (uncompressed_size > kMaxUncompressed) {
    throw BagError("chunk declares an implausible uncompressed size " +
                   std::to_string(uncompressed_size));
  }
  if (algorithm.empty()) {
    if (size != uncompressed_size) {
      throw BagError("uncompressed chunk has " + std::to_string(size) +
                     " bytes but declares " + std::to_string(uncompressed_size));
    }
    return std::vector<uint8_t>(data, data + size);
  }
  // The output buffer is allocated from the declared size before a byte is inflated, so the
  // size is first held against the most either format can encode in `size` bytes: an LZ4 sequence
  // grows by at most 255 bytes per input byte; a zstd block has a 3-byte header and inflates to at
  // most 128 KiB. A corrupt field (found by fuzz_bag_mcap) is then an error, not an allocation of
  // gigabytes.
  const auto refuse_ratio = [&](uint64_t most) {
    if (uncompressed_size > most) {
      throw BagError(algorithm + " chunk declares " + std::to_string(uncompressed_size) +
                     " uncompressed bytes, more than " + std::to_string(size) +
                     " compressed bytes can hold");
    }
  };
  if (algorithm == "lz4") {
    refuse_ratio(256 * uint64_t(size) + 4096);
    return Lz4Decompress(data, size, uncompressed_size);
  }
  if (algorithm == "zstd") {
    refuse_ratio((uint64_t(128) << 10) * (uint64_t(size) / 3 + 1));
    return ZstdDecompress(data, size, uncompressed_size);
  }
  throw BagError("unsupported chunk compression '" + algorithm + "'");
}

}  // namespace ppf::bag::detail
