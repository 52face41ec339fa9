// LiDAR-only odometry on a real sequence without IMU: balm_realworld_lidar, 177
// hand-held 2 Hz keyframe sweeps with the producer's own odometry as reference (README of the
// data). Read in place from <workspace>/../shared (PPF_SHARED_DIR at build time, or the
// environment variable PPF_SHARED_DIR); skipped with a message when absent. The sweeps are
// imported into a temporary bag the way ppf_import_pcd does (times from the TUM file's first
// column, no IMU topic) and run through the same offline loop as ppf_offline, which must decide
// LiDAR-only by itself. Bounds: every scan tracked, APE (SE(3)-aligned) <= 0.15 m in
// both modes, and PPF's kNN map smaller than kNN's (skeleton points stay out of it).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "ppf_core/config.hpp"
#include "ppf_sim/bag_output.hpp"
#include "ppf_sim/importers.hpp"
#include "ppf_tools/offline_runner.hpp"
#include "ppf_trajectory/evaluation.hpp"
#include "ppf_trajectory/trajectory_io.hpp"

#ifndef PPF_SHARED_DIR
#define PPF_SHARED_DIR "../shared"
#endif
#ifndef PPF_CONFIG_DIR
#define PPF_CONFIG_DIR "config"
#endif

namespace fs = std::filesystem;

namespace {

fs::path SequenceDir() {
  const char* env = std::getenv("PPF_SHARED_DIR");
  const fs::path shared = env && *env ? fs::path(env) : fs::path(PPF_SHARED_DIR);
  return shared / "data/real/balm_realworld_lidar";
}

struct ModeRun {
  ppf::tools::OfflineRun run;
  ppf::EvalResult ape;
};

ModeRun RunMode(const std::string& bag, const ppf::Trajectory& ref, ppf::Mode mode) {
  ppf::Config config;
  const std::string preset = std::string(PPF_CONFIG_DIR) + "/lidar_only_keyframes.yaml";
  const ppf::ConfigLoadReport report = ppf::LoadConfigYaml(preset, &config);
  EXPECT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.warnings.empty());
  // The preset says none; auto must come to the same without it (the bag has no IMU topic).
  config.imu.mode = ppf::ImuMode::kAuto;
  config.mode = mode;
  ModeRun m;
  ppf::tools::OfflineOptions options;
  options.lidar_frame = true;  // the reference poses are the sensor's
  m.run = ppf::tools::RunOffline(bag, config, options);
  ppf::EvalOptions eo;
  eo.align = ppf::Alignment::kSE3;
  m.ape = ppf::ComputeApe(ref, m.run.trajectory, eo);
  return m;
}

TEST(LidarOnlyReal, BalmRealworldBothModesTrackEveryScan) {
  const fs::path dir = SequenceDir();
  if (!fs::exists(dir / "scans") || !fs::exists(dir / "reference_poses.tum")) {
    GTEST_SKIP() << "balm_realworld_lidar not found at " << dir
                 << " (set PPF_SHARED_DIR to the folder holding data/real/)";
  }
  const fs::path bag =
      fs::path(::testing::TempDir()) / ("ppf_balm_lidar_only_" + std::to_string(getpid()));
  fs::remove_all(bag);
  ppf::sim::PcdOptions import;
  import.stamps_file = (dir / "reference_poses.tum").string();  // its first column: scan times
  ppf::sim::ImportPcdDirectory((dir / "scans").string(), bag.string(), ppf::sim::BagOutputOptions(),
                               import);
  ppf::Trajectory ref;
  std::string error;
  ASSERT_TRUE(ppf::ReadTum((dir / "reference_poses.tum").string(), &ref, &error)) << error;
  ASSERT_EQ(ref.size(), 177u);

  size_t map_size[2] = {0, 0};
  for (const ppf::Mode mode : {ppf::Mode::kKnn, ppf::Mode::kPpf}) {
    const char* name = mode == ppf::Mode::kPpf ? "ppf" : "knn";
    const ModeRun m = RunMode(bag.string(), ref, mode);
    EXPECT_TRUE(m.run.lidar_only) << name;
    ASSERT_EQ(m.run.results.size(), 177u) << name;
    size_t poor = 0, guessed = 0;
    for (const ppf::ScanResult& r : m.run.results) {
      EXPECT_TRUE(r.pose_valid) << name << " scan at " << r.stamp_s << ": " << r.reason;
      // Tracked = registered with a good fit (a lost scan fits the map badly and says so).
      if (r.reason.find("poor fit") != std::string::npos) ++poor;
      if (r.guesses_tried > 1) ++guessed;
    }
    EXPECT_EQ(poor, 0u) << name;
    ASSERT_TRUE(m.ape.ok) << m.ape.error;
    EXPECT_EQ(m.ape.matched, 177u) << name;
    map_size[mode == ppf::Mode::kPpf] = m.run.results.back().map_size;
    std::printf(
        "[balm %s] APE(se3) rmse %.3f m max %.3f m; final map %zu points; "
        "scans that needed extra guesses %zu; wall %.1f s\n",
        name, m.ape.stats.rmse, m.ape.stats.max, m.run.results.back().map_size, guessed,
        m.run.wall_s);
    EXPECT_LE(m.ape.stats.rmse, 0.15) << name;
  }
  EXPECT_LT(map_size[1], map_size[0]);
  fs::remove_all(bag);
}

}  // namespace
