// Sequence-number gaps per writer: samples a reader never got (best-effort transport loss) or that
// its history overwrote before the listener could take them. DDS reports neither; the node counts
// every gap so no input vanishes silently.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>

#include <fastdds/rtps/common/Guid.h>

namespace ppf::dds {

class GapCounter {
 public:
  // Samples missing between the previous sample of `writer` and this one (`seq`). The first
  // sample of a writer sets the baseline: a reader that joins late does not count what came
  // before it.
  uint64_t Count(const eprosima::fastrtps::rtps::GUID_t& writer, uint64_t seq) {
    auto it = last_.find(writer);
    if (it == last_.end()) {
      last_[writer] = seq;
      return 0;
    }
    const uint64_t missing = seq > it->second + 1 ? seq - it->second - 1 : 0;
    it->second = std::max(it->second, seq);
    return missing;
  }

 private:
  std::map<eprosima::fastrtps::rtps::GUID_t, uint64_t> last_;
};

}  // namespace ppf::dds
