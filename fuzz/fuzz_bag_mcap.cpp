// Fuzz target: the MCAP bag reader (ppf_bag), fed a whole .mcap file.
#include "bag_fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ppf::fuzz::ReadWholeBag(data, size, ".mcap");
  return 0;
}
