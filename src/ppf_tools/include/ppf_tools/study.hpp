// Shared by the study commands (ppf_compare, ppf_accuracy_study): which simulated sequences to
// run, generating them once with ppf_sim, the LiDAR preset + the sequence's calibration, one run of
// the core per mode scored against ground truth, and the issues' accuracy bounds.
#pragma once

#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "ppf_core/lio_ppf.hpp"
#include "ppf_tools/scan_stats.hpp"
#include "ppf_trajectory/evaluation.hpp"

namespace ppf::tools {

struct SequenceSpec {
  std::string scene, lidar;
  // More ppf_sim options (the disturbances: "--jolt 8:5"); part of the sequence's directory name.
  std::string sim_extra;
  int seed = 1;  // ppf_sim --seed: another drive along the same kind of path
  // "urban/hdl64", and "urban/hdl64#3" for seed 3 (seed 1 keeps the plain name).
  std::string Name() const {
    return scene + "/" + lidar + (seed == 1 ? "" : "#" + std::to_string(seed));
  }
  // File names of its outputs: "urban_hdl64", "urban_hdl64_seed3".
  std::string FileStem() const {
    return scene + "_" + lidar + (seed == 1 ? "" : "_seed" + std::to_string(seed));
  }
};

// "scene:lidar[,scene:lidar...]" with scenes and LiDARs that ppf_sim knows. False and *error
// (naming the bad item and the valid names) for anything else, including an empty list.
bool ParseSequenceList(const std::string& list, std::vector<SequenceSpec>* out, std::string* error);

// "1-8", "1,3,5" or "2,4-6": the ppf_sim seeds a study runs every sequence with, each at least 1,
// in the order given, without repeats. False and *error (naming the bad item) otherwise.
bool ParseSeedList(const std::string& list, std::vector<int>* out, std::string* error);
// Every sequence once per seed, sequence-major (urban#1, urban#2, ..., indoor#1, ...).
std::vector<SequenceSpec> WithSeeds(const std::vector<SequenceSpec>& sequences,
                                    const std::vector<int>& seeds);

// Options every study command takes. ParseStudyOption consumes argv[*i] (and its value) if it is
// one of them: returns 1 when consumed, 0 when the argument is not a study option, -1 on an error
// (*error says why).
struct StudyOptions {
  bool short_form = false;
  std::string sequences;   // command's default
  double duration = -1.0;  // <= 0: 60 s, or 10 s with --short
  std::string workdir = "out/compare";
  std::string config_dir;
  int threads = -1;  // < 0: the preset's num_threads
  // Tilt statistics from this long after the first pose on (the gravity bound is taken after
  // 10 s, docs/decisions.md, "Accuracy and gravity bounds"; a --short sequence is only 10 s long,
  // so it looks from 2 s on instead). < 0: that default.
  double tilt_after = -1.0;
  // --seeds: every sequence is generated and run once per seed. A figure measured on one drive
  // can be that drive's luck; the same scene and LiDAR on other seeds tells.
  std::vector<int> seeds{1};

  double EffectiveDuration() const { return duration > 0 ? duration : (short_form ? 10.0 : 60.0); }
  double EffectiveTiltAfter() const {
    return tilt_after >= 0 ? tilt_after : (short_form ? 2.0 : kIssueTiltAfterS);
  }
  static constexpr double kIssueTiltAfterS = 10.0;
};
int ParseStudyOption(int argc, char** argv, int* i, StudyOptions* opts, std::string* error);
// A command's own options, with ParseStudyOption's contract.
using OptionParser = std::function<int(int argc, char** argv, int* i, std::string* error)>;
// The whole command line of a study command, in order: the study options, -h/--help (sets *help
// and stops there), the command's own options (`own`, may be empty). False on the first argument
// that is wrong or that nobody takes (*error says why).
bool ParseStudyCommandLine(int argc, char** argv, StudyOptions* opts, bool* help,
                           std::string* error, const OptionParser& own = nullptr);
// Help text lines for the options above (with the command's default sequence list).
std::string StudyOptionsHelp(const std::string& default_sequences);

// The last non-empty line of a log file ("" if none): why a child process failed, usually.
std::string LastLogLine(const std::string& path);

// Makes `dir` hold a complete simulated sequence (metadata.yaml and groundtruth.tum present),
// calling generate(out) only if it does not yet. generate writes into `out`, a private directory
// with dir's name, which then takes dir's place in one rename: processes sharing a work directory
// (ctest -j, two studies) never read or delete each other's half-written sequence. Returns false
// if generate did; `dir` is then left as it was.
bool GenerateSequenceOnce(const std::string& dir,
                          const std::function<bool(const std::string& out)>& generate);

// The sequence's directory under `workdir` (<scene>_<lidar>_<seconds>s, then _seed<N> for a seed
// other than 1, then the disturbance), generated with ppf_sim (seq.seed, MCAP) unless a complete
// one is already there. ppf_sim is taken from PATH. Progress goes to `log`, each line starting with
// `log_prefix`. Throws std::runtime_error if ppf_sim fails (its log file is named in the message).
std::string EnsureSequence(const SequenceSpec& seq, double duration, const std::string& workdir,
                           std::ostream& log, const std::string& log_prefix = "");

// config_dir/<lidar>.yaml, then <bag>/calibration.yaml (the simulated robot's T_imu_lidar) on top,
// as a user layers a calibration over a preset. threads >= 0 overrides num_threads.
bool LoadSequenceConfig(const std::string& config_dir, const std::string& lidar,
                        const std::string& bag, int threads, Config* config, std::string* error);

// "handheld" or "car", from <bag>/sequence.yaml; empty if it cannot be read.
std::string SequenceMotion(const std::string& bag);

struct ModeRun {
  RunSummary summary;
  EvalResult ape, rpe;  // SE(3)-aligned, like evo; rpe over consecutive poses
  // Position + yaw (4-DoF) aligned: a world tilted away from gravity shows here, not in `ape`.
  EvalResult ape_posyaw;
  // Tilt and height error (alignment-free), tilt from tilt_after s after the first pose on.
  GravityMetrics gravity;
  double tilt_after = 0.0;
  double path_length = 0.0;  // ground truth, metres
  Trajectory trajectory;     // T_world_imu of every scan with a pose
  std::vector<ScanResult> results;
  double ApePercent() const {
    return ape.ok && path_length > 0 ? 100.0 * ape.stats.rmse / path_length : -1.0;
  }
};

// RunOffline with config.mode = mode, scored against gt. Throws what RunOffline throws.
ModeRun RunAndEvaluate(const std::string& bag, const Config& base, Mode mode, const Trajectory& gt,
                       double tilt_after = StudyOptions::kIssueTiltAfterS);

// SE(3) and position+yaw APE and the gravity metrics of a trajectory against gt, stored in run
// (ape, ape_posyaw, rpe, gravity, tilt_after, path_length).
void Evaluate(const Trajectory& gt, const Trajectory& est, double tilt_after, ModeRun* run);

// How a run came back from a disturbance (ppf_sim --jolt, --imu-gap, --silence, --gyro-range) at
// `t_s` seconds after the ground truth's first stamp. The estimate is aligned to the ground truth
// by position + yaw on the poses before t_s only, so an error the disturbance left is not
// averaged away by the alignment; then every pose from t_s + settle_s on is compared: heading
// (angle between the body x axes projected on the horizontal plane, degrees) and position
// (metres). The tilt needs no alignment.
struct Recovery {
  bool ok = false;
  std::string error;
  size_t poses_after = 0;            // poses from t_s + settle_s on
  double heading_at_settle_deg = 0;  // the first of them
  double position_at_settle_m = 0;
  double max_heading_deg = 0;  // all of them
  double max_position_m = 0;
  double max_tilt_deg = 0;          // from t_s on
  double max_tilt_settled_deg = 0;  // from t_s + settle_s on
};
Recovery ComputeRecovery(const Trajectory& gt, const Trajectory& est, double t_s, double settle_s);

// The accuracy bounds for one sequence: APE RMSE at most 0.5 % of the path length (urban,
// indoor, ramps) or 1 % (park); hand-held motion additionally at most 5 cm (docs/decisions.md,
// "Accuracy and gravity bounds").
struct AccuracyBound {
  double max_percent = 0.5;
  double max_abs_m = 0.0;        // 0: none
  std::string Describe() const;  // "<=0.5%", "<=0.5%,5cm"
  bool Met(const ModeRun& run) const;
};
AccuracyBound BoundFor(const std::string& scene, const std::string& motion);

// The gravity bounds for every run (docs/decisions.md, "Accuracy and gravity bounds"):
// position+yaw APE RMSE at most 1.5x the SE(3) one plus 5 cm (the extra DoF SE(3) may use are
// exactly the tilt of the world), and the estimated gravity within 0.2 degrees of the truth
// after the first 10 s.
struct GravityBound {
  double max_posyaw_ratio = 1.5;
  double posyaw_slack_m = 0.05;
  double max_tilt_deg = 0.2;
  double PosYawLimit(const ModeRun& run) const;  // metres
  bool PosYawMet(const ModeRun& run) const;
  // Not met either when no pose lies after the offset: nothing was shown.
  bool TiltMet(const ModeRun& run) const;
};

// The bound of a disturbance the LiDAR must correct (issue 27; test_disturbance, and
// ppf_accuracy_study --disturb): the disturbed run's SE(3) APE at most `factor` times the same
// drive's undisturbed APE, plus slack_m for runs whose undisturbed APE is a few millimetres.
struct DisturbanceBound {
  double factor = 1.2;
  double slack_m = 0.002;
  double Limit(double undisturbed_ape_m) const { return factor * undisturbed_ape_m + slack_m; }
};

// One line per bound, the way the study commands print them:
//   "  met     urban/vlp16 knn: position+yaw APE <value> <= 1.5 x SE(3) APE + 0.05 m = <limit>"
//   "  MISSED  urban/vlp16 knn: max tilt after 10 s <value> <= 0.2 deg"
std::string DescribeGravityBounds(const GravityBound& bound, const std::string& name,
                                  const ModeRun& run, bool* all_met);

}  // namespace ppf::tools
