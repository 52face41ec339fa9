// Fuzz target: the rosbag2 sqlite3 bag reader (ppf_bag), fed a whole .db3 file. Most mutations
// are refused by sqlite's own page checks; those that survive reach our schema handling (missing
// columns, unknown topic ids, NULL blobs and texts, odd types).
#include "bag_fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ppf::fuzz::ReadWholeBag(data, size, ".db3");
  return 0;
}
