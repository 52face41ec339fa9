// Fuzz target: the ROS 1 bag reader (ppf_bag), fed a whole .bag file, including the ROS 1 ->
// CDR conversion of every PointCloud2, Imu and Livox CustomMsg it returns.
#include "bag_fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ppf::fuzz::ReadWholeBag(data, size, ".bag");
  return 0;
}
