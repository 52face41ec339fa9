// ppf_eval: APE / RPE of a trajectory against a reference, computed as evo does (see
// ppf_trajectory/evaluation.hpp), printed as an evo-like table.
//
//   ppf_eval ape --ref gt.tum --est traj.tum [--align se3|sim3|posyaw|none] [--max-diff 0.01]
//                [--offset 0.0] [--ref-format tum|kitti] [--est-format tum|kitti]
//                [--tilt-after 0.0]
//   ppf_eval rpe --ref gt.tum --est traj.tum [--delta 1] [--delta-unit f|m]
//                [--align none|se3|sim3|posyaw] [--max-diff 0.01] [--offset 0.0]
//
// After the APE table come the tilt between the estimated and the true gravity direction and the
// height error, whatever the alignment: they compare the two worlds' "up" as they are, so both
// trajectories must be in gravity-aligned, z-up worlds (TUM ground truth of a LiDAR-inertial
// dataset and our estimates are; a KITTI camera frame is not).
//
// Formats follow the file extension (.kitti -> KITTI, anything else TUM) unless given. KITTI files
// have no stamps: poses are numbered 0, 1, 2, ... and associate by index.
// Exit status: 0 ok, 1 usage error, 2 unreadable input or failed evaluation.
#include <cstdio>
#include <cstdlib>
#include <string>

#include "ppf_trajectory/evaluation.hpp"

namespace {

int Usage(const char* msg) {
  if (msg) std::fprintf(stderr, "ppf_eval: %s\n\n", msg);
  std::fprintf(stderr,
               "usage:\n"
               "  ppf_eval ape --ref REF --est EST [--align se3|sim3|posyaw|none] [--max-diff S]\n"
               "               [--offset S] [--ref-format tum|kitti] [--est-format tum|kitti]\n"
               "               [--tilt-after S]\n"
               "  ppf_eval rpe --ref REF --est EST [--delta N] [--delta-unit f|m]\n"
               "               [--align none|se3|sim3|posyaw] [--max-diff S] [--offset S]\n"
               "APE default alignment: se3 (evo_ape -a); RPE default: none (evo_rpe).\n"
               "posyaw: position + yaw (4 DoF), for odometry that observes gravity.\n"
               "APE also prints the tilt between estimated and true gravity (median, max over the\n"
               "poses from --tilt-after S seconds after the first matched stamp on, default 0) and\n"
               "the height error with the first pose matched by translation + yaw; both need\n"
               "gravity-aligned z-up worlds and no alignment.\n");
  return 1;
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool ParseNumber(const std::string& s, double* v) {
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return end != s.c_str() && *end == '\0';
}

bool Load(const std::string& path, const std::string& format, ppf::Trajectory* traj) {
  const bool kitti = format.empty() ? EndsWith(path, ".kitti") : format == "kitti";
  std::string error;
  const bool ok = kitti ? ppf::ReadKitti(path, traj, &error) : ppf::ReadTum(path, traj, &error);
  if (!ok) std::fprintf(stderr, "ppf_eval: %s\n", error.c_str());
  if (ok && traj->empty()) std::fprintf(stderr, "ppf_eval: %s has no poses\n", path.c_str());
  return ok && !traj->empty();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return Usage(nullptr);
  const std::string metric = argv[1];
  if (metric == "-h" || metric == "--help") return Usage(nullptr);
  if (metric != "ape" && metric != "rpe") return Usage("first argument must be ape or rpe");

  std::string ref_path, est_path, ref_format, est_format;
  ppf::EvalOptions o;
  o.align = metric == "ape" ? ppf::Alignment::kSE3 : ppf::Alignment::kNone;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") return Usage(nullptr);
    if (i + 1 >= argc) return Usage(("missing value after " + a).c_str());
    const std::string v = argv[++i];
    double num = 0.0;
    if (a == "--ref") {
      ref_path = v;
    } else if (a == "--est") {
      est_path = v;
    } else if (a == "--ref-format" || a == "--est-format") {
      if (v != "tum" && v != "kitti") return Usage("format must be tum or kitti");
      (a == "--ref-format" ? ref_format : est_format) = v;
    } else if (a == "--align") {
      if (v == "se3") o.align = ppf::Alignment::kSE3;
      else if (v == "sim3") o.align = ppf::Alignment::kSim3;
      else if (v == "posyaw") o.align = ppf::Alignment::kPosYaw;
      else if (v == "none") o.align = ppf::Alignment::kNone;
      else return Usage("--align must be se3, sim3, posyaw or none");
    } else if (a == "--max-diff") {
      if (!ParseNumber(v, &num) || num < 0) return Usage("--max-diff needs a number >= 0");
      o.max_diff = num;
    } else if (a == "--offset") {
      if (!ParseNumber(v, &num)) return Usage("--offset needs a number");
      o.offset = num;
    } else if (a == "--tilt-after" && metric == "ape") {
      if (!ParseNumber(v, &num) || num < 0) return Usage("--tilt-after needs a number >= 0");
      o.tilt_after_s = num;
    } else if (a == "--delta" && metric == "rpe") {
      if (!ParseNumber(v, &num) || num <= 0) return Usage("--delta needs a number > 0");
      o.delta = num;
    } else if (a == "--delta-unit" && metric == "rpe") {
      if (v == "f") o.delta_in_meters = false;
      else if (v == "m") o.delta_in_meters = true;
      else return Usage("--delta-unit must be f (frames) or m (meters)");
    } else {
      return Usage(("unknown option " + a).c_str());
    }
  }
  if (ref_path.empty() || est_path.empty()) return Usage("--ref and --est are required");
  if (!o.delta_in_meters && o.delta != static_cast<double>(static_cast<long>(o.delta))) {
    return Usage("--delta in frames must be an integer");
  }

  ppf::Trajectory ref, est;
  if (!Load(ref_path, ref_format, &ref) || !Load(est_path, est_format, &est)) return 2;
  const ppf::EvalResult r =
      metric == "ape" ? ppf::ComputeApe(ref, est, o) : ppf::ComputeRpe(ref, est, o);
  if (!r.ok) {
    std::fprintf(stderr, "ppf_eval: %s\n", r.error.c_str());
    return 2;
  }
  std::printf("Found %zu of max. %zu possible matching timestamps between\n\t%s\nand:\t%s\n"
              "with max. time diff.: %g (s) and time offset: %g (s).\n\n",
              r.matched, std::min(ref.size(), est.size()), ref_path.c_str(), est_path.c_str(),
              o.max_diff, o.offset);
  if (o.align == ppf::Alignment::kSim3) std::printf("Scale correction: %.6f\n\n", r.scale);
  std::string title;
  if (metric == "ape") {
    title = "APE w.r.t. translation part (m)";
  } else {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "RPE w.r.t. translation part (m)\nfor delta = %g (%s) using "
                  "consecutive pairs", o.delta, o.delta_in_meters ? "m" : "frames");
    title = buf;
  }
  std::printf("%s", ppf::FormatStatsTable(title, ppf::AlignmentDescription(o.align), r.stats).c_str());
  if (metric == "ape") {
    std::printf("\n%s", ppf::FormatGravityLines(r.gravity, o.tilt_after_s).c_str());
  }
  return 0;
}
