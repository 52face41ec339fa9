// Fuzz target: ppf_node's YAML config loader (--config). A malformed file must be refused with a
// message, never take the node down.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "ppf_dds_node/node_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ppf::dds::NodeConfig config;
  const ppf::dds::NodeConfigReport report =
      ppf::dds::LoadNodeConfigString(std::string(reinterpret_cast<const char*>(data), size), &config);
  if (!report.ok && report.error.empty()) {
    std::fprintf(stderr, "config refused without a reason\n");
    std::abort();
  }
  return 0;
}
