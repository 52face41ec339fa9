// What the tests that run the core on ppf_sim sequences share: generating a sequence once per
// build tree and loading a LiDAR preset with the sequence's calibration on top. Includers define
// PPF_TEST_WORKDIR (where sequences go) and, from CMake, PPF_SIM_EXE and PPF_CONFIG_DIR.
#pragma once

#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>

#include "ppf_core/config.hpp"
#include "ppf_tools/study.hpp"

#ifndef PPF_SIM_EXE
#define PPF_SIM_EXE "ppf_sim"
#endif
#ifndef PPF_CONFIG_DIR
#define PPF_CONFIG_DIR "config"
#endif

namespace ppf::tools::test {

// <PPF_TEST_WORKDIR>/<sim_args>_<duration> (spaces and dashes as '_') holding the sequence
// `ppf_sim <sim_args> <extra_args> --duration <duration> --seed 1 --storage mcap` (the seed
// the arguments give, if any). Test cases
// that share a sequence (knn and ppf) may run at once (ctest -j): it is generated once,
// atomically (GenerateSequenceOnce). A failure is a test failure naming ppf_sim's log.
inline std::string GenerateSimSequence(const std::string& sim_args, double duration,
                                       const std::string& extra_args = "") {
  std::ostringstream name;
  name << sim_args << "_" << duration;
  std::string n = name.str();
  for (char& ch : n) {
    if (ch == ' ' || ch == '-') ch = '_';
  }
  const std::string dir = (std::filesystem::path(PPF_TEST_WORKDIR) / n).string();
  const bool ok = GenerateSequenceOnce(dir, [&](const std::string& out) {
    std::ostringstream cmd;
    // Seed 1 unless the arguments choose another drive.
    const bool seeded = (sim_args + extra_args).find("--seed") != std::string::npos;
    cmd << PPF_SIM_EXE << " " << sim_args << extra_args << " --duration " << duration
        << (seeded ? "" : " --seed 1") << " --storage mcap --out '" << out << "' > '" << dir
        << "." << ::getpid() << ".log' 2>&1";
    return std::system(cmd.str().c_str()) == 0;
  });
  EXPECT_TRUE(ok) << "ppf_sim failed, see " << dir << ".<pid>.log";
  return dir;
}

// PPF_CONFIG_DIR/<lidar>.yaml, then <bag>/calibration.yaml (the simulated robot's own, non-identity
// T_imu_lidar) on top, as a user layers their robot's calibration over a LiDAR preset.
inline ::testing::AssertionResult LoadPresetAndCalibration(const std::string& lidar,
                                                           const std::string& bag,
                                                           ppf::Config* config) {
  std::string error;
  if (!LoadSequenceConfig(PPF_CONFIG_DIR, lidar, bag, -1, config, &error)) {
    return ::testing::AssertionFailure() << error;
  }
  return ::testing::AssertionSuccess();
}

}  // namespace ppf::tools::test
