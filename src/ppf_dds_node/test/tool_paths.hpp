// Locating other packages' executables (ppf_sim, ppf_eval) for cross-package tests: PATH first
// (colcon test puts the dependencies' install bin directories there), then the path CMake found
// at configure time.
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <sstream>
#include <string>

namespace ppf::test {

inline std::string FindTool(const std::string& name, const std::string& configured) {
  if (const char* path = std::getenv("PATH")) {
    std::stringstream ss(path);
    std::string dir;
    while (std::getline(ss, dir, ':')) {
      const std::string candidate = dir + "/" + name;
      if (!dir.empty() && access(candidate.c_str(), X_OK) == 0) return candidate;
    }
  }
  if (!configured.empty() && configured.find("NOTFOUND") == std::string::npos &&
      access(configured.c_str(), X_OK) == 0) {
    return configured;
  }
  return "";
}

}  // namespace ppf::test
