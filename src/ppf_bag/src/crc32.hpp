// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320) as MCAP uses for chunk, data-section and
// summary checksums. Incremental: Crc32Update(Crc32Update(0, a), b) == Crc32 of a+b.
#pragma once

#include <cstddef>
#include <cstdint>

namespace ppf::bag::detail {

uint32_t Crc32Update(uint32_t crc, const uint8_t* data, size_t size);
inline uint32_t Crc32(const uint8_t* data, size_t size) { return Crc32Update(0, data, size); }

}  // namespace ppf::bag::detail
