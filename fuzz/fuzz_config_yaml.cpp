// Fuzz target: the core's YAML config loader (config/<lidar>.yaml, core.config_file of a node
// config). Its contract: never throws, a hard error is reported in the result.
#include <cstdint>
#include <string>

#include "ppf_core/config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ppf::Config config;
  ppf::LoadConfigYamlString(std::string(reinterpret_cast<const char*>(data), size), &config);
  return 0;
}
