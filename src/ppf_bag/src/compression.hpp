// Chunk compression for MCAP ("", "lz4", "zstd"), using the lz4 and zstd frame formats as the
// MCAP spec requires.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ppf::bag::detail {

// Throws BagError for an unknown algorithm. "" and "none" mean uncompressed.
std::vector<uint8_t> Compress(const std::string& algorithm, const uint8_t* data, size_t size);
// Output must be exactly `uncompressed_size` bytes, otherwise BagError (corrupt chunk).
std::vector<uint8_t> Decompress(const std::string& algorithm, const uint8_t* data, size_t size,
                                uint64_t uncompressed_size);
bool IsSupportedCompression(const std::string& algorithm);

}  // namespace ppf::bag::detail
