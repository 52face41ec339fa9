// Disturbances the IMU does not see, with exact ground truth (ppf_sim --jolt, --imu-gap,
// --silence, --gyro-range): a heading or position step of the true path, an IMU gap in a turn,
// both streams silent while driving, a gyro that saturates on a hand-held walk. The LiDAR must
// correct each (Config::consistency), in both modes. The full bounds: from 1 s after the
// disturbance on, heading within 0.2 deg and position within 0.05 m of the undisturbed run's
// error, APE at most 1.2x the undisturbed run's, the tilt no worse than the undisturbed run's
// (+0.05 deg). Cases that do not meet all of them yet assert what they do meet, and the comment
// says what is missing (docs/decisions.md, "Consistency check"). The undisturbed runs use
// test_accuracy's sequences (same work directory: generated once for both); the cases with the
// check off show the old behaviour failing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <string>

#include "ppf_core/config.hpp"
#include "ppf_tools/offline_runner.hpp"
#include "ppf_tools/study.hpp"
#include "ppf_trajectory/evaluation.hpp"
#include "ppf_trajectory/trajectory_io.hpp"
#include "sim_sequence.hpp"

namespace fs = std::filesystem;

namespace {

struct Case {
  std::string name;
  std::string sim_args;  // the undisturbed sequence (test_accuracy's)
  std::string lidar;
  double duration;
  std::string disturbance;  // ppf_sim options added for the disturbed one
  double at_s;              // sim time of the disturbance
  ppf::Mode mode;
  // kFull: every bound above. kRelocated: heading, position (within relocation_m of the
  // undisturbed run's error) and no reset. kCheckOff: consistency.check false, the old behaviour,
  // which must fail (heading error above 1 deg or APE above 10x).
  enum Expect { kFull, kRelocated, kCheckOff } expect = kFull;
  double relocation_m = 0.05;
  // kRelocated, when >= 0: the tilt at most this much above the undisturbed run's maximum, and
  // APE at most this many times the undisturbed run's.
  double tilt_margin_deg = -1.0;
  double ape_factor = -1.0;
};

std::ostream& operator<<(std::ostream& os, const Case& c) { return os << c.name; }

struct Outcome {
  ppf::tools::Recovery recovery;
  double ape = 0.0;  // SE(3)-aligned RMSE, m
  size_t overruled = 0;
  size_t relocalized = 0;
  // Searches set off by the scan-alone step while the fit stayed good, over an interval the IMU
  // measured whole: they try the update, the scan's own step and the prediction, no turns.
  size_t step_searches = 0;
  size_t searches = 0;  // every search, whatever set it off
};

Outcome RunCase(const std::string& bag, const Case& c) {
  ppf::Config config;
  EXPECT_TRUE(ppf::tools::test::LoadPresetAndCalibration(c.lidar, bag, &config));
  config.mode = c.mode;
  config.consistency.check = c.expect != Case::kCheckOff;
  const auto run = ppf::tools::RunOffline(bag, config);
  ppf::Trajectory gt;
  std::string error;
  EXPECT_TRUE(ppf::ReadTum(bag + "/groundtruth.tum", &gt, &error)) << error;
  Outcome o;
  for (const auto& r : run.results) {
    o.overruled += r.overruled;
    o.relocalized += r.relocalized;
    // The result says what set a search off, as the reason does; only a search overrules, and
    // a LiDAR-inertial scan that was not searched aligned no guesses.
    const bool step_search = r.consistency_search == ppf::ConsistencySearch::kScanStep;
    o.searches += r.consistency_search != ppf::ConsistencySearch::kNone;
    EXPECT_EQ(step_search, r.reason.find("(the scan alone moves it") != std::string::npos)
        << "at " << r.stamp_s << ": " << r.reason;
    EXPECT_EQ(r.consistency_search == ppf::ConsistencySearch::kPoorFit,
              r.reason.find("contradicts the prediction (fit ") != std::string::npos)
        << "at " << r.stamp_s << ": " << r.reason;
    EXPECT_TRUE(!r.overruled || r.consistency_search != ppf::ConsistencySearch::kNone)
        << "overruled without a search at " << r.stamp_s << ": " << r.reason;
    const bool lio_update = r.pose_valid && !r.lidar_only && !r.imu_lost && !r.relocalized;
    if (lio_update && r.consistency_search == ppf::ConsistencySearch::kNone) {
      EXPECT_EQ(r.guesses_tried, 0) << "at " << r.stamp_s << ": " << r.reason;
    }
    if (step_search && r.imu_gap_s == 0.0 && r.gyro_saturated_s == 0.0) {
      ++o.step_searches;
      EXPECT_EQ(r.guesses_tried, 3) << "at " << r.stamp_s << ": " << r.reason;
    }
    EXPECT_NE(r.status, ppf::Status::kReset) << "a reset at " << r.stamp_s << ": " << r.reason;
  }
  ppf::EvalOptions eval;
  eval.align = ppf::Alignment::kSE3;
  const auto ape = ppf::ComputeApe(gt, run.trajectory, eval);
  EXPECT_TRUE(ape.ok) << ape.error;
  o.ape = ape.stats.rmse;
  o.recovery = ppf::tools::ComputeRecovery(gt, run.trajectory, c.at_s, 1.0);
  EXPECT_TRUE(o.recovery.ok) << o.recovery.error;
  return o;
}

class Disturbance : public ::testing::TestWithParam<Case> {};

TEST_P(Disturbance, CorrectedWithinOneSecond) {
  const Case& c = GetParam();
  const std::string clean_bag = ppf::tools::test::GenerateSimSequence(c.sim_args, c.duration);
  const std::string bag =
      ppf::tools::test::GenerateSimSequence(c.sim_args + " " + c.disturbance, c.duration);
  Case clean_case = c;
  clean_case.expect = Case::kFull;
  const Outcome clean = RunCase(clean_bag, clean_case);
  const Outcome o = RunCase(bag, c);
  const auto& r = o.recovery;
  const auto& r0 = clean.recovery;
  std::cout << "[ DISTURBANCE ] " << c.name << " (" << c.disturbance << "): 1 s after, heading "
            << r.heading_at_settle_deg << " deg (max " << r.max_heading_deg << "; undisturbed "
            << r0.max_heading_deg << "), position " << r.position_at_settle_m << " m (max "
            << r.max_position_m << "; undisturbed " << r0.max_position_m << "), APE " << o.ape
            << " m (undisturbed " << clean.ape << "), tilt max " << r.max_tilt_deg
            << " deg (undisturbed " << r0.max_tilt_deg << "), overruled " << o.overruled
            << " scans, re-localized " << o.relocalized << ", step-only searches "
            << o.step_searches << " (undisturbed " << clean.step_searches << ")\n";
  // Undisturbed, the check never searches: a search costs several scans' time, and one the map
  // does not confirm says it fired on noise (the scan-alone step of a hundred scattered rows in
  // kPpf reached 0.16 m on the hand-held walk: consistency.min_step_sigmas).
  EXPECT_EQ(clean.searches, 0u) << "the undisturbed run searched";
  // Only a gap longer than the IMU bridges makes the first scan after it a re-localization.
  if (c.disturbance.find("--silence") != std::string::npos) {
    EXPECT_EQ(o.relocalized, 1u);
  } else {
    EXPECT_EQ(o.relocalized, 0u);
  }
  if (c.expect == Case::kCheckOff) {
    // The rows' low weight and narrow gates leave the disturbance uncorrected.
    EXPECT_TRUE(r.max_heading_deg > 1.0 || o.ape > 10.0 * clean.ape)
        << "the check was off, yet the run came back";
    EXPECT_EQ(o.overruled, 0u);
    return;
  }
  if (c.expect == Case::kRelocated) {
    // 1 s after (a saturating gyro disturbs again at every shake peak: its maxima are not this).
    EXPECT_LE(r.heading_at_settle_deg, 0.2 + r0.max_heading_deg) << "heading not corrected";
    EXPECT_LE(r.position_at_settle_m, c.relocation_m + r0.max_position_m) << "not relocated";
    if (c.tilt_margin_deg >= 0.0) {
      EXPECT_LE(r.max_tilt_deg, r0.max_tilt_deg + c.tilt_margin_deg) << "relocated tilted";
    }
    if (c.ape_factor >= 0.0) {
      ppf::tools::DisturbanceBound bound;
      bound.factor = c.ape_factor;
      EXPECT_LE(o.ape, bound.Limit(clean.ape)) << "APE";
    }
    return;
  }
  EXPECT_LE(r.max_heading_deg, 0.2 + r0.max_heading_deg) << "heading not corrected within 1 s";
  EXPECT_LE(r.max_position_m, 0.05 + r0.max_position_m) << "position not corrected within 1 s";
  EXPECT_LE(o.ape, ppf::tools::DisturbanceBound().Limit(clean.ape))
      << "APE above 1.2x the undisturbed run's";
  EXPECT_LE(r.max_tilt_deg, r0.max_tilt_deg + 0.05) << "the correction tilted the world";
}

const ppf::Mode kKnn = ppf::Mode::kKnn;
const ppf::Mode kPpf = ppf::Mode::kPpf;
const char* kUrban = "--scene urban --lidar vlp16";
const char* kUrbanSeed3 = "--scene urban --lidar vlp16 --seed 3";
const char* kHandheld = "--scene indoor --lidar vlp16 --motion handheld";

INSTANTIATE_TEST_SUITE_P(
    Simulated, Disturbance,
    ::testing::Values(
        // Heading steps the gyro never saw (10 m/s, 3.5 s after the start of the drive).
        Case{"jolt5_knn", kUrban, "vlp16", 12, "--jolt 6:5", 6, kKnn},
        Case{"jolt5_ppf", kUrban, "vlp16", 12, "--jolt 6:5", 6, kPpf},
        Case{"jolt5_knn_check_off", kUrban, "vlp16", 12, "--jolt 6:5", 6, kKnn, Case::kCheckOff},
        Case{"jolt10_knn", kUrban, "vlp16", 12, "--jolt 6:10", 6, kKnn},
        Case{"jolt10_ppf", kUrban, "vlp16", 12, "--jolt 6:10", 6, kPpf},
        // A position step along the way: most points lie on surfaces parallel to it.
        Case{"step05_knn", kUrban, "vlp16", 12, "--jolt 6:0:0.5", 6, kKnn},
        Case{"step05_ppf", kUrban, "vlp16", 12, "--jolt 6:0:0.5", 6, kPpf},
        // Both streams silent for 3 s while accelerating: longer than the IMU bridges, so the
        // first scan after it is re-localized LiDAR-only from guesses along the way (the turn
        // extrapolated about the vertical only, extending no map), solving for its own velocity
        // (coarse to fine), and LIO resumes with the position as uncertain as a re-localization
        // leaves it and that velocity; the sweep is de-skewed with the gyro's turn, its samples
        // being back; its update runs to convergence. Found again within the full bounds 1 s
        // after, APE within the full 1.2x. The tilt: kNN within the full bound; kPpf 0.01 deg
        // more. On this straight, accelerating drive a pitch is what an accelerometer bias along
        // the way also explains, and the two runs settle on it apart: kPpf's undisturbed run
        // below kNN's (0.30 vs 0.32 deg), both re-localized runs at 0.35 (docs/decisions.md,
        // "The re-localized update runs to convergence").
        Case{"silence3_knn", kUrban, "vlp16", 12, "--silence 6:3", 9, kKnn, Case::kRelocated,
             0.05, 0.05, 1.2},
        Case{"silence3_ppf", kUrban, "vlp16", 12, "--silence 6:3", 9, kPpf, Case::kRelocated,
             0.05, 0.06, 1.2},
        // The same on the drive of seed 3 (the road descending, the body bouncing on its
        // suspension), kPpf: the first resumed scans' updates correct the re-localized velocity
        // by decimetres per second, and the scans are de-skewed again with the corrected velocity
        // before their points extend the map (RedeskewVelocity; without it this run's APE is
        // 2.6x the undisturbed run's, docs/decisions.md "Resumed scans de-skewed with the
        // update's velocity").
        Case{"silence3_seed3_ppf", kUrbanSeed3, "vlp16", 12, "--silence 6:3", 9, kPpf,
             Case::kRelocated, 0.05, 0.05, 1.2},
        // An IMU gap of 0.5 s in the first turn (14-17 s), bridged by integration, each scan
        // across it widened for its part of the gap and de-skewed again with the turn missed
        // there: in kKnn the turn the scan alone measured before the update, in kPpf (its kNN
        // map holds the scattered points only) the update's own, the update run again from the
        // same prediction. Every bound in both modes.
        Case{"turn_imu_gap_knn", kUrban, "vlp16", 24, "--imu-gap 15:0.5", 15, kKnn},
        Case{"turn_imu_gap_ppf", kUrban, "vlp16", 24, "--imu-gap 15:0.5", 15, kPpf},
        // A gyro saturating at 2 rad/s on a hand-held walk (its shake peaks at 2.6 rad/s): the
        // rate beyond each saturated reading is searched for the de-skew the map fits best (kPpf:
        // the kNN map and the skeleton's patch map) and the scan de-skewed with it
        // (imu.noise.gyro_range). Position, APE, heading 1 s after and tilt within the full
        // bounds (saturation recurs at every shake peak, so the heading maxima are not the
        // measure).
        Case{"handheld_gyro_range_knn", kHandheld, "vlp16", 20, "--gyro-range 2", 5, kKnn,
             Case::kRelocated, 0.05, 0.05, 1.2},
        Case{"handheld_gyro_range_ppf", kHandheld, "vlp16", 20, "--gyro-range 2", 5, kPpf,
             Case::kRelocated, 0.05, 0.05, 1.2}),
    [](const ::testing::TestParamInfo<Case>& info) { return info.param.name; });

}  // namespace
