#include "ppf_tools/study.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "ppf_core/config.hpp"
#include "ppf_sim/lidar_model.hpp"
#include "ppf_sim/world.hpp"
#include "ppf_tools/offline_runner.hpp"

namespace fs = std::filesystem;

namespace ppf::tools {

namespace {

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

bool Contains(const std::vector<std::string>& v, const std::string& x) {
  return std::find(v.begin(), v.end(), x) != v.end();
}

}  // namespace

bool ParseSequenceList(const std::string& list, std::vector<SequenceSpec>* out,
                       std::string* error) {
  out->clear();
  const auto scenes = sim::SceneNames();
  const auto lidars = sim::LidarModelNames();
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto colon = item.find(':');
    if (colon == std::string::npos) {
      *error = "sequence '" + item + "' is not scene:lidar (e.g. urban:hdl64)";
      return false;
    }
    SequenceSpec seq{item.substr(0, colon), item.substr(colon + 1), ""};
    if (!Contains(scenes, seq.scene)) {
      *error = "sequence '" + item + "': unknown scene '" + seq.scene + "' (" + Join(scenes) + ")";
      return false;
    }
    if (!Contains(lidars, seq.lidar)) {
      *error = "sequence '" + item + "': unknown LiDAR '" + seq.lidar + "' (" + Join(lidars) + ")";
      return false;
    }
    out->push_back(seq);
  }
  if (out->empty()) {
    *error = "no sequences given";
    return false;
  }
  return true;
}

bool ParseSeedList(const std::string& list, std::vector<int>* out, std::string* error) {
  out->clear();
  // A whole number >= 1 that fits an int, or false.
  auto seed = [](const std::string& s, int* v) {
    if (s.empty() || s.size() > 9 || !std::all_of(s.begin(), s.end(), [](char c) {
          return std::isdigit(static_cast<unsigned char>(c));
        })) {
      return false;
    }
    *v = std::stoi(s);
    return *v >= 1;
  };
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto dash = item.find('-');
    int first = 0, last = 0;
    const bool ok = dash == std::string::npos
                        ? seed(item, &first) && seed(item, &last)
                        : seed(item.substr(0, dash), &first) && seed(item.substr(dash + 1), &last);
    if (!ok || last < first) {
      *error = "--seeds: '" + item +
               "' is not a seed or a range A-B of seeds (whole numbers >= 1, A <= B)";
      return false;
    }
    // Each seed is a simulated drive and a run per mode: a list past this is a typo.
    constexpr int kMaxSeeds = 1000;
    if (last - first >= kMaxSeeds || out->size() + static_cast<size_t>(last - first) >= kMaxSeeds) {
      *error = "--seeds: more than " + std::to_string(kMaxSeeds) + " seeds";
      return false;
    }
    for (int s = first; s <= last; ++s) {
      if (std::find(out->begin(), out->end(), s) != out->end()) {
        *error = "--seeds: seed " + std::to_string(s) + " given twice";
        return false;
      }
      out->push_back(s);
    }
  }
  if (out->empty()) {
    *error = "--seeds: no seeds given";
    return false;
  }
  return true;
}

std::vector<SequenceSpec> WithSeeds(const std::vector<SequenceSpec>& sequences,
                                    const std::vector<int>& seeds) {
  std::vector<SequenceSpec> out;
  for (const SequenceSpec& seq : sequences) {
    for (const int seed : seeds) {
      out.push_back(seq);
      out.back().seed = seed;
    }
  }
  return out;
}

int ParseStudyOption(int argc, char** argv, int* i, StudyOptions* opts, std::string* error) {
  const std::string a = argv[*i];
  auto value = [&](std::string* v) {
    if (*i + 1 >= argc) {
      *error = "missing value after " + a;
      return false;
    }
    *v = argv[++*i];
    return true;
  };
  auto number = [&](double* v) {
    std::string s;
    if (!value(&s)) return false;
    char* end = nullptr;
    *v = std::strtod(s.c_str(), &end);
    if (s.empty() || *end != '\0') {
      *error = a + ": not a number: '" + s + "'";
      return false;
    }
    return true;
  };
  double n = 0;
  if (a == "--short") {
    opts->short_form = true;
  } else if (a == "--sequences") {
    if (!value(&opts->sequences)) return -1;
  } else if (a == "--duration") {
    if (!number(&opts->duration)) return -1;
    if (!(opts->duration > 0)) {
      *error = "--duration must be positive";
      return -1;
    }
  } else if (a == "--seeds") {
    std::string list;
    if (!value(&list) || !ParseSeedList(list, &opts->seeds, error)) return -1;
  } else if (a == "--workdir") {
    if (!value(&opts->workdir)) return -1;
  } else if (a == "--config-dir") {
    if (!value(&opts->config_dir)) return -1;
  } else if (a == "--threads") {
    if (!number(&n)) return -1;
    opts->threads = static_cast<int>(n);
  } else if (a == "--tilt-after") {
    if (!number(&opts->tilt_after)) return -1;
    if (!(opts->tilt_after >= 0)) {
      *error = "--tilt-after must be >= 0";
      return -1;
    }
  } else {
    return 0;
  }
  return 1;
}

bool ParseStudyCommandLine(int argc, char** argv, StudyOptions* opts, bool* help,
                           std::string* error, const OptionParser& own) {
  *help = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    int used = ParseStudyOption(argc, argv, &i, opts, error);
    if (used == 0 && (a == "-h" || a == "--help")) {
      *help = true;
      return true;
    }
    if (used == 0 && own) used = own(argc, argv, &i, error);
    if (used < 0) return false;
    if (used == 0) {
      *error = "unknown argument '" + a + "' (see --help)";
      return false;
    }
  }
  return true;
}

std::string StudyOptionsHelp(const std::string& default_sequences) {
  return "  --short               CI form: shorter sequences (default durations 60 s -> 10 s)\n"
         "  --sequences LIST      comma-separated scene:lidar pairs\n"
         "                        (default: " +
         default_sequences +
         ")\n"
         "  --duration S          sequence length in seconds (default 60, --short 10)\n"
         "  --seeds LIST          ppf_sim seeds, e.g. 1-8 or 1,3,5: every sequence once per seed\n"
         "                        (default 1; other seeds are named scene/lidar#seed)\n"
         "  --workdir DIR         where sequences are generated/reused (default: out/compare,\n"
         "                        shared by ppf_compare and ppf_accuracy_study)\n"
         "  --config-dir DIR      LiDAR presets <lidar>.yaml (default: the repository's config/)\n"
         "  --threads N           OpenMP threads for the core (default: the preset's)\n"
         "  --tilt-after S        tilt statistics from S seconds after the first pose on\n"
         "                        (default 10, --short 2)\n";
}

namespace {
bool CompleteSequence(const fs::path& dir) {
  // groundtruth.tum is written after the bag is closed: its presence means a complete sequence.
  return fs::exists(dir / "metadata.yaml") && fs::exists(dir / "groundtruth.tum");
}
}  // namespace

std::string LastLogLine(const std::string& path) {
  std::ifstream file(path);
  std::string line, last;
  while (std::getline(file, line)) {
    if (!line.empty()) last = line;
  }
  return last;
}

bool GenerateSequenceOnce(const std::string& dir_name,
                          const std::function<bool(const std::string& out)>& generate) {
  const fs::path dir(dir_name);
  if (CompleteSequence(dir)) return true;
  // Same base name inside a private parent: ppf_sim names the bag files after the directory.
  const fs::path staging = dir.parent_path() / (".staging_" + dir.filename().string() + "_" +
                                                std::to_string(::getpid()));
  fs::remove_all(staging);
  fs::create_directories(staging);  // and the work directory itself
  const fs::path out = staging / dir.filename();
  const bool ok = generate(out.string()) && CompleteSequence(out);
  std::error_code ec;
  if (ok) {
    // rename() refuses a non-empty target, so a copy another process moved there first is never
    // replaced (readers may have it open). A target that is there but incomplete can only be the
    // leftover of an interrupted run of an older version: cleared, then one more try.
    fs::rename(out, dir, ec);
    if (ec && !CompleteSequence(dir)) {
      fs::remove_all(dir, ec);
      fs::rename(out, dir, ec);
    }
  }
  fs::remove_all(staging, ec);
  return ok && CompleteSequence(dir);
}

std::string EnsureSequence(const SequenceSpec& seq, double duration, const std::string& workdir,
                           std::ostream& log, const std::string& log_prefix) {
  std::ostringstream name;
  name << seq.scene << "_" << seq.lidar << "_" << static_cast<int>(duration) << "s";
  if (seq.seed != 1) name << "_seed" << seq.seed;
  if (!seq.sim_extra.empty()) {
    std::string extra = seq.sim_extra;
    for (char& ch : extra) {
      if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.') ch = '_';
    }
    name << "_" << extra;
  }
  const fs::path dir = fs::path(workdir) / name.str();
  if (CompleteSequence(dir)) return dir.string();
  const std::string sim_log = dir.string() + ".sim.log";
  log << log_prefix << "generating " << name.str() << " with ppf_sim...\n" << std::flush;
  const bool ok = GenerateSequenceOnce(dir.string(), [&](const std::string& out) {
    std::ostringstream cmd;
    cmd << "ppf_sim --scene " << seq.scene << " --lidar " << seq.lidar << " --duration " << duration
        << " --seed " << seq.seed << " --storage mcap " << seq.sim_extra << " --out '" << out
        << "' > '" << sim_log << "' 2>&1";
    return std::system(cmd.str().c_str()) == 0;
  });
  if (!ok) {
    // The log's last line usually says why ("ppf_sim: not found" when it is not on PATH).
    throw std::runtime_error("ppf_sim failed for " + name.str() + ": " + LastLogLine(sim_log) +
                             " (see " + sim_log + ")");
  }
  return dir.string();
}

bool LoadSequenceConfig(const std::string& config_dir, const std::string& lidar,
                        const std::string& bag, int threads, Config* config, std::string* error) {
  const std::string preset = config_dir + "/" + lidar + ".yaml";
  if (!fs::exists(preset)) {
    *error = preset + ": no such preset";
    return false;
  }
  const auto report = LoadConfigYaml(preset, config);
  if (!report.ok) {
    *error = preset + ": " + report.error;
    return false;
  }
  const auto calib = LoadConfigYaml(bag + "/calibration.yaml", config);
  if (!calib.ok) {
    *error = bag + "/calibration.yaml: " + calib.error;
    return false;
  }
  if (threads >= 0) config->num_threads = threads;
  return true;
}

std::string SequenceMotion(const std::string& bag) {
  std::ifstream in(bag + "/sequence.yaml");
  std::string line;
  while (std::getline(in, line)) {
    const auto k = line.find("motion:");
    if (k == std::string::npos) continue;
    std::string v = line.substr(k + 7);
    v.erase(0, v.find_first_not_of(" \t"));
    v.erase(v.find_last_not_of(" \t\r") + 1);
    return v;
  }
  return "";
}

void Evaluate(const Trajectory& gt, const Trajectory& est, double tilt_after, ModeRun* run) {
  EvalOptions eval;
  eval.align = Alignment::kSE3;
  eval.tilt_after_s = tilt_after;
  run->ape = ComputeApe(gt, est, eval);
  run->rpe = ComputeRpe(gt, est, eval);
  eval.align = Alignment::kPosYaw;
  run->ape_posyaw = ComputeApe(gt, est, eval);
  run->gravity = run->ape.gravity;
  run->tilt_after = tilt_after;
  run->path_length = PathLength(gt);
}

ModeRun RunAndEvaluate(const std::string& bag, const Config& base, Mode mode, const Trajectory& gt,
                       double tilt_after) {
  Config config = base;
  config.mode = mode;
  ModeRun out;
  auto run = RunOffline(bag, config);
  out.summary = Summarize(run.results, run.wall_s);
  Evaluate(gt, run.trajectory, tilt_after, &out);
  out.trajectory = std::move(run.trajectory);
  out.results = std::move(run.results);
  return out;
}

std::string AccuracyBound::Describe() const {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "<=%g%%", max_percent);
  std::string s = buf;
  if (max_abs_m > 0) {
    std::snprintf(buf, sizeof(buf), ",%gcm", 100.0 * max_abs_m);
    s += buf;
  }
  return s;
}

bool AccuracyBound::Met(const ModeRun& run) const {
  if (!run.ape.ok) return false;
  if (run.ApePercent() > max_percent) return false;
  return max_abs_m <= 0 || run.ape.stats.rmse <= max_abs_m;
}

AccuracyBound BoundFor(const std::string& scene, const std::string& motion) {
  AccuracyBound b;
  b.max_percent = scene == "park" ? 1.0 : 0.5;
  if (motion == "handheld") b.max_abs_m = 0.05;
  return b;
}

double GravityBound::PosYawLimit(const ModeRun& run) const {
  return max_posyaw_ratio * run.ape.stats.rmse + posyaw_slack_m;
}

bool GravityBound::PosYawMet(const ModeRun& run) const {
  return run.ape.ok && run.ape_posyaw.ok && run.ape_posyaw.stats.rmse <= PosYawLimit(run);
}

bool GravityBound::TiltMet(const ModeRun& run) const {
  return run.gravity.ok && run.gravity.tilt.count > 0 && run.gravity.tilt.max <= max_tilt_deg;
}

std::string DescribeGravityBounds(const GravityBound& bound, const std::string& name,
                                  const ModeRun& run, bool* all_met) {
  char buf[256];
  std::string out;
  auto line = [&](bool met, const char* what) {
    out += std::string("  ") + (met ? "met   " : "MISSED") + "  " + name + ": " + what + "\n";
    if (all_met) *all_met = *all_met && met;
  };
  if (run.ape.ok && run.ape_posyaw.ok) {
    std::snprintf(buf, sizeof(buf),
                  "position+yaw APE %.3f m <= %g x SE(3) APE %.3f m + %g m = %.3f m",
                  run.ape_posyaw.stats.rmse, bound.max_posyaw_ratio, run.ape.stats.rmse,
                  bound.posyaw_slack_m, bound.PosYawLimit(run));
  } else {
    std::snprintf(buf, sizeof(buf), "position+yaw APE <= %g x SE(3) APE + %g m: no APE",
                  bound.max_posyaw_ratio, bound.posyaw_slack_m);
  }
  line(bound.PosYawMet(run), buf);
  if (run.gravity.ok && run.gravity.tilt.count > 0) {
    std::snprintf(buf, sizeof(buf), "max tilt after %g s %.3f deg <= %g deg", run.tilt_after,
                  run.gravity.tilt.max, bound.max_tilt_deg);
  } else {
    std::snprintf(buf, sizeof(buf), "max tilt after %g s <= %g deg: no pose after %g s",
                  run.tilt_after, bound.max_tilt_deg, run.tilt_after);
  }
  line(bound.TiltMet(run), buf);
  return out;
}

Recovery ComputeRecovery(const Trajectory& gt, const Trajectory& est, double t_s, double settle_s) {
  Recovery rec;
  if (gt.empty() || est.empty()) {
    rec.error = "empty trajectory";
    return rec;
  }
  const double t_abs = gt.front().stamp_s + t_s;
  const auto pairs = AssociateByStamp(gt, est, 0.01, 0.0);
  std::vector<Eigen::Vector3d> src, dst;
  for (const auto& [i, j] : pairs) {
    if (gt[i].stamp_s >= t_abs) break;
    src.push_back(est[j].T.translation());
    dst.push_back(gt[i].T.translation());
  }
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  if (!AlignPositionYaw(src, dst, &R, &t)) {
    rec.error = "too few poses (or no horizontal motion) before the disturbance to align";
    return rec;
  }
  auto heading = [](const Eigen::Matrix3d& R_world_body) {
    return std::atan2(R_world_body(1, 0), R_world_body(0, 0));
  };
  for (const auto& [i, j] : pairs) {
    if (gt[i].stamp_s < t_abs) continue;
    const double tilt = TiltDeg(gt[i].T, est[j].T);
    rec.max_tilt_deg = std::max(rec.max_tilt_deg, tilt);
    if (gt[i].stamp_s < t_abs + settle_s) continue;
    rec.max_tilt_settled_deg = std::max(rec.max_tilt_settled_deg, tilt);
    double dh = heading(R * est[j].T.linear()) - heading(gt[i].T.linear());
    dh = std::abs(std::remainder(dh, 2.0 * M_PI)) * 180.0 / M_PI;
    const double dp = (R * est[j].T.translation() + t - gt[i].T.translation()).norm();
    if (rec.poses_after == 0) {
      rec.heading_at_settle_deg = dh;
      rec.position_at_settle_m = dp;
    }
    ++rec.poses_after;
    rec.max_heading_deg = std::max(rec.max_heading_deg, dh);
    rec.max_position_m = std::max(rec.max_position_m, dp);
  }
  rec.ok = rec.poses_after > 0;
  if (!rec.ok) rec.error = "no pose after the disturbance settled";
  return rec;
}

}  // namespace ppf::tools
