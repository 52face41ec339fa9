// End-to-end accuracy on simulated sequences with exact ground truth: ppf_sim writes a bag, the
// offline loop runs the core in each mode, APE (SE(3)-aligned, like evo) must stay within the
// issue's bounds. CI runs shorter sequences than the 60 s figures recorded in the issue notes;
// the bounds are the same kind (relative to path length, or absolute for hand-held).
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "ppf_core/config.hpp"
#include "ppf_tools/offline_runner.hpp"
#include "ppf_tools/scan_stats.hpp"
#include "ppf_tools/study.hpp"
#include "ppf_trajectory/evaluation.hpp"
#include "sim_sequence.hpp"

namespace fs = std::filesystem;

namespace {

struct Case {
  std::string name;
  std::string sim_args;  // scene, lidar, motion
  std::string lidar;     // config preset
  double duration;
  ppf::Mode mode;
  double max_ape_percent;  // of path length; <= 0: use max_ape_m
  double max_ape_m;
  // > 0: the gravity bounds, from this many seconds after the first pose on (once a turn
  // has made the accelerometer bias observable: at rest it cannot be told from tilt).
  double gravity_after_s = 0.0;
  // imu.mode none: LiDAR-only on the same bag, its IMU ignored.
  bool lidar_only = false;
  int redeskew_iterations = 0;  // lidar_only.redeskew_iterations (2: the hand-held setting)
};

std::ostream& operator<<(std::ostream& os, const Case& c) { return os << c.name; }

class Accuracy : public ::testing::TestWithParam<Case> {};

TEST_P(Accuracy, ApeWithinBound) {
  const Case& c = GetParam();
  // Shared between the knn and ppf cases of one sequence: generated once per build tree.
  const std::string bag = ppf::tools::test::GenerateSimSequence(c.sim_args, c.duration);
  ASSERT_TRUE(fs::exists(fs::path(bag) / "groundtruth.tum"));

  ppf::Config config;
  ASSERT_TRUE(ppf::tools::test::LoadPresetAndCalibration(c.lidar, bag, &config));
  config.mode = c.mode;
  if (c.lidar_only) config.imu.mode = ppf::ImuMode::kNone;
  config.lidar_only.redeskew_iterations = c.redeskew_iterations;

  const auto run = ppf::tools::RunOffline(bag, config);
  EXPECT_EQ(run.lidar_only, c.lidar_only);
  ppf::Trajectory gt;
  std::string error;
  ASSERT_TRUE(ppf::ReadTum(bag + "/groundtruth.tum", &gt, &error)) << error;

  size_t valid = 0, resets = 0, rejected = 0;
  for (const auto& r : run.results) {
    valid += r.pose_valid;
    resets += r.status == ppf::Status::kReset;
    rejected += r.status == ppf::Status::kRejected;
  }
  EXPECT_EQ(resets, 0u);
  EXPECT_EQ(rejected, 0u);
  // Everything after the 2 s static start (about 1 s of initialization) must produce a pose.
  EXPECT_GE(valid + 15, run.results.size()) << "too many scans without a pose";
  if (c.mode == ppf::Mode::kPpf) {
    const auto s = ppf::tools::Summarize(run.results, run.wall_s);
    EXPECT_GT(s.mean_skeleton_points, 0.0) << "PPF mode found no skeleton points";
  }

  ppf::EvalOptions eval;
  eval.align = ppf::Alignment::kSE3;
  const auto ape = ppf::ComputeApe(gt, run.trajectory, eval);
  ASSERT_TRUE(ape.ok) << ape.error;
  EXPECT_GE(ape.matched + 15, run.results.size());
  const double path = ppf::PathLength(gt);
  const double percent = 100.0 * ape.stats.rmse / std::max(path, 1e-9);
  // The gravity bounds' view of the same run: position+yaw alignment (a tilted world shows as
  // error) and the tilt of the estimated gravity.
  eval.align = ppf::Alignment::kPosYaw;
  eval.tilt_after_s = c.gravity_after_s > 0 ? c.gravity_after_s : 2.0;
  const auto ape_posyaw = ppf::ComputeApe(gt, run.trajectory, eval);
  ASSERT_TRUE(ape_posyaw.ok) << ape_posyaw.error;
  // SE(3) alignment may use every DoF the 4-DoF one has, and more: never worse.
  EXPECT_LE(ape.stats.rmse, ape_posyaw.stats.rmse + 1e-9);
  const ppf::GravityMetrics& g = ape_posyaw.gravity;
  ASSERT_TRUE(g.ok);
  std::cout << "[ APE ] " << c.name << ": rmse " << ape.stats.rmse << " m over " << path
            << " m path (" << percent << " %), max " << ape.stats.max << " m, "
            << run.results.size() << " scans; position+yaw rmse " << ape_posyaw.stats.rmse
            << " m, tilt after " << eval.tilt_after_s << " s median " << g.tilt.median << " max "
            << g.tilt.max << " deg, final height error " << g.final_dz_m << " m\n";
  if (c.max_ape_percent > 0) {
    EXPECT_LE(percent, c.max_ape_percent)
        << "APE rmse " << ape.stats.rmse << " m on a " << path << " m path";
  } else {
    EXPECT_LE(ape.stats.rmse, c.max_ape_m);
  }
  if (c.gravity_after_s > 0) {
    // The gravity bounds (ppf_accuracy_study applies the same to its 60 s sequences).
    const ppf::tools::GravityBound bound;
    EXPECT_LE(ape_posyaw.stats.rmse, bound.max_posyaw_ratio * ape.stats.rmse + bound.posyaw_slack_m)
        << "the world is tilted: position+yaw-aligned APE far above the SE(3)-aligned one";
    EXPECT_LE(g.tilt.max, bound.max_tilt_deg) << "estimated gravity off after the first turn";
    EXPECT_LE(std::abs(g.final_dz_m), 0.003 * path) << "height error over 0.3 % of the path";
  }
}

// The gravity bounds as the study applies them, on hand-made runs.
TEST(GravityBound, PosYawAndTiltLimits) {
  ppf::tools::ModeRun run;
  run.ape.ok = run.ape_posyaw.ok = run.gravity.ok = true;
  run.tilt_after = 10.0;
  run.ape.stats.rmse = 0.10;
  run.gravity.tilt = ppf::ComputeStats({0.05, 0.19});
  const ppf::tools::GravityBound bound;
  EXPECT_NEAR(bound.PosYawLimit(run), 1.5 * 0.10 + 0.05, 1e-12);
  run.ape_posyaw.stats.rmse = 0.199;
  EXPECT_TRUE(bound.PosYawMet(run));
  EXPECT_TRUE(bound.TiltMet(run));
  bool all = true;
  std::string lines = ppf::tools::DescribeGravityBounds(bound, "urban/vlp16 knn", run, &all);
  EXPECT_TRUE(all);
  EXPECT_NE(lines.find("  met     urban/vlp16 knn: position+yaw APE 0.199 m <= 1.5 x SE(3) APE "
                       "0.100 m + 0.05 m = 0.200 m\n"),
            std::string::npos)
      << lines;
  EXPECT_NE(lines.find("  met     urban/vlp16 knn: max tilt after 10 s 0.190 deg <= 0.2 deg\n"),
            std::string::npos)
      << lines;

  run.ape_posyaw.stats.rmse = 0.201;
  run.gravity.tilt = ppf::ComputeStats({0.05, 0.21});
  EXPECT_FALSE(bound.PosYawMet(run));
  EXPECT_FALSE(bound.TiltMet(run));
  lines = ppf::tools::DescribeGravityBounds(bound, "park/hdl32 ppf", run, &all);
  EXPECT_FALSE(all);
  EXPECT_NE(lines.find("  MISSED  park/hdl32 ppf: position+yaw APE 0.201 m"), std::string::npos)
      << lines;
  EXPECT_NE(lines.find("  MISSED  park/hdl32 ppf: max tilt after 10 s 0.210 deg"),
            std::string::npos)
      << lines;

  // A run too short to have a pose after the offset shows nothing about the tilt: not met.
  run.gravity.tilt = ppf::ComputeStats({});
  EXPECT_FALSE(bound.TiltMet(run));
  lines = ppf::tools::DescribeGravityBounds(bound, "x", run, nullptr);
  EXPECT_NE(lines.find("MISSED  x: max tilt after 10 s <= 0.2 deg: no pose after 10 s"),
            std::string::npos)
      << lines;
}

// --seeds of the study commands: parsed, every sequence once per seed, and each seed's drive
// generated by ppf_sim with that seed into its own directory (a stand-in ppf_sim on PATH records
// its arguments: no sequence is simulated).
TEST(StudySeeds, ParsedExpandedAndGeneratedPerSeed) {
  std::vector<int> seeds;
  std::string error;
  ASSERT_TRUE(ppf::tools::ParseSeedList("2,4-6", &seeds, &error)) << error;
  EXPECT_EQ(seeds, (std::vector<int>{2, 4, 5, 6}));
  for (const char* bad : {"0", "3-1", "x", "", "1-", "-2", "1,,2", "2.5", "9999999999"}) {
    EXPECT_FALSE(ppf::tools::ParseSeedList(bad, &seeds, &error)) << bad;
  }
  EXPECT_FALSE(ppf::tools::ParseSeedList("1-3,2", &seeds, &error));
  EXPECT_EQ(error, "--seeds: seed 2 given twice");
  EXPECT_FALSE(ppf::tools::ParseSeedList("1-999999999", &seeds, &error));  // no hang either
  EXPECT_EQ(error, "--seeds: more than 1000 seeds");
  ASSERT_TRUE(ppf::tools::ParseSeedList("1-1000", &seeds, &error)) << error;
  EXPECT_EQ(seeds.size(), 1000u);

  std::vector<ppf::tools::SequenceSpec> seqs;
  ASSERT_TRUE(ppf::tools::ParseSequenceList("urban:vlp16,park:hdl32", &seqs, &error)) << error;
  seqs = ppf::tools::WithSeeds(seqs, {1, 3});
  ASSERT_EQ(seqs.size(), 4u);
  EXPECT_EQ(seqs[0].Name(), "urban/vlp16");  // seed 1 keeps the names of every earlier study
  EXPECT_EQ(seqs[1].Name(), "urban/vlp16#3");
  EXPECT_EQ(seqs[1].FileStem(), "urban_vlp16_seed3");
  EXPECT_EQ(seqs[2].FileStem(), "park_hdl32");
  EXPECT_EQ(seqs[3].Name(), "park/hdl32#3");

  const fs::path dir = fs::temp_directory_path() / ("ppf_study_seeds_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "bin");
  {
    std::ofstream sim(dir / "bin" / "ppf_sim");
    sim << "#!/bin/sh\nfor a; do [ \"$prev\" = --out ] && out=$a; prev=$a; done\n"
           "mkdir -p \"$out\" && echo \"$*\" > \"$out/args\" && touch \"$out/metadata.yaml\" "
           "\"$out/groundtruth.tum\"\n";
  }
  fs::permissions(dir / "bin" / "ppf_sim", fs::perms::owner_all);
  const char* old_path = std::getenv("PATH");
  const std::string saved = old_path ? old_path : "";
  setenv("PATH", ((dir / "bin").string() + ":" + saved).c_str(), 1);
  std::ostringstream log;
  seqs[1].sim_extra = "--silence 6:3";
  std::string bag1, bag3;
  try {
    bag1 = ppf::tools::EnsureSequence(seqs[0], 12, (dir / "work").string(), log);
    bag3 = ppf::tools::EnsureSequence(seqs[1], 12, (dir / "work").string(), log);
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what();
  }
  setenv("PATH", saved.c_str(), 1);
  EXPECT_EQ(fs::path(bag1).filename(), "urban_vlp16_12s");
  EXPECT_EQ(fs::path(bag3).filename(), "urban_vlp16_12s_seed3___silence_6_3");
  auto args = [](const std::string& bag) {
    std::ifstream f(bag + "/args");
    std::string line;
    std::getline(f, line);
    return line;
  };
  EXPECT_NE(args(bag1).find("--seed 1 "), std::string::npos) << args(bag1);
  EXPECT_NE(args(bag3).find("--seed 3 "), std::string::npos) << args(bag3);
  EXPECT_NE(args(bag3).find("--silence 6:3"), std::string::npos) << args(bag3);
  fs::remove_all(dir);
}

const ppf::Mode kKnn = ppf::Mode::kKnn;
const ppf::Mode kPpf = ppf::Mode::kPpf;

INSTANTIATE_TEST_SUITE_P(
    Simulated, Accuracy,
    ::testing::Values(
        Case{"urban_hdl32_knn", "--scene urban --lidar hdl32", "hdl32", 12, kKnn, 0.5, 0},
        Case{"urban_hdl32_ppf", "--scene urban --lidar hdl32", "hdl32", 12, kPpf, 0.5, 0},
        // LiDAR-only on the same 12 s drive (no extra sequence): 1 % of the path
        // (docs/decisions.md, "Accuracy test cases").
        Case{"urban_hdl32_lidar_only_knn", "--scene urban --lidar hdl32", "hdl32", 12, kKnn, 1.0, 0,
             0.0, true},
        Case{"urban_hdl32_lidar_only_ppf", "--scene urban --lidar hdl32", "hdl32", 12, kPpf, 1.0, 0,
             0.0, true},
        Case{"urban_hdl64_knn", "--scene urban --lidar hdl64", "hdl64", 8, kKnn, 0.5, 0},
        Case{"urban_hdl64_ppf", "--scene urban --lidar hdl64", "hdl64", 8, kPpf, 0.5, 0},
        Case{"urban_vlp16_knn", "--scene urban --lidar vlp16", "vlp16", 12, kKnn, 0.5, 0},
        // Through the first turn (14-17 s), where the world can tilt (docs/decisions.md,
        // "Accuracy test cases").
        Case{"urban_vlp16_turn_knn", "--scene urban --lidar vlp16", "vlp16", 24, kKnn, 0.5, 0, 17},
        Case{"urban_vlp16_turn_ppf", "--scene urban --lidar vlp16", "vlp16", 24, kPpf, 0.5, 0, 17},
        Case{"urban_os1_64_ppf", "--scene urban --lidar os1_64", "os1_64", 8, kPpf, 0.5, 0},
        Case{"indoor_vlp16_knn", "--scene indoor --lidar vlp16 --motion car --speed 1.5", "vlp16",
             12, kKnn, 0.5, 0},
        Case{"indoor_vlp16_ppf", "--scene indoor --lidar vlp16 --motion car --speed 1.5", "vlp16",
             12, kPpf, 0.5, 0},
        // LiDAR-only on the indoor car drive (1 % of the path).
        Case{"indoor_vlp16_lidar_only_knn", "--scene indoor --lidar vlp16 --motion car --speed 1.5",
             "vlp16", 12, kKnn, 1.0, 0, 0.0, true},
        Case{"indoor_vlp16_lidar_only_ppf", "--scene indoor --lidar vlp16 --motion car --speed 1.5",
             "vlp16", 12, kPpf, 1.0, 0, 0.0, true},
        Case{"indoor_os1_128_knn", "--scene indoor --lidar os1_128 --motion car --speed 1.5",
             "os1_128", 8, kKnn, 0.5, 0},
        Case{"park_hdl32_knn", "--scene park --lidar hdl32", "hdl32", 12, kKnn, 1.0, 0},
        Case{"park_hdl32_ppf", "--scene park --lidar hdl32", "hdl32", 12, kPpf, 1.0, 0},
        Case{"ramps_hdl32_ppf", "--scene ramps --lidar hdl32", "hdl32", 12, kPpf, 0.5, 0},
        // Hand-held shake (up to 150 deg/s) turns the accelerometer bias early: the gravity
        // bounds from 10 s on, as the study states them. Rows of a scan counted as independent
        // tilt these runs beyond 0.2 deg (docs/decisions.md, "Row noise and gravity").
        Case{"handheld_indoor_vlp16_knn", "--scene indoor --lidar vlp16 --motion handheld", "vlp16",
             20, kKnn, 0, 0.05, 10},
        Case{"handheld_indoor_vlp16_ppf", "--scene indoor --lidar vlp16 --motion handheld", "vlp16",
             20, kPpf, 0, 0.05, 10},
        // LiDAR-only on the same hand-held walk (1 % of the path), with the hand-held setting
        // lidar_only.redeskew_iterations 2: de-skewed with the constant-velocity model alone
        // (the default, 0) it misses the bound (docs/decisions.md, "Accuracy test cases").
        Case{"handheld_indoor_vlp16_lidar_only_knn",
             "--scene indoor --lidar vlp16 --motion handheld", "vlp16", 20, kKnn, 1.0, 0, 0.0, true,
             2},
        Case{"handheld_indoor_vlp16_lidar_only_ppf",
             "--scene indoor --lidar vlp16 --motion handheld", "vlp16", 20, kPpf, 1.0, 0, 0.0, true,
             2}),
    [](const ::testing::TestParamInfo<Case>& info) { return info.param.name; });

}  // namespace
