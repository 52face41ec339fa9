#include "ppf_tools/scan_stats.hpp"

#include <algorithm>
#include <iomanip>

namespace ppf::tools {
namespace {

// Quote a CSV/JSON string field: reasons are free text.
std::string Quoted(const std::string& s, char quote_escape) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += quote_escape;
    if (c == '\n') {
      out += ' ';
      continue;
    }
    out += c;
  }
  return out + "\"";
}

}  // namespace

void WriteStatsCsvHeader(std::ostream& os) {
  os << "stamp,status,reason,pose_valid,iterations,converged,t_preprocess_ms,t_deskew_ms,"
        "t_downsample_ms,t_ppf_ms,t_residuals_ms,t_update_ms,t_map_insert_ms,t_total_ms,"
        "map_size,input_points,valid_points,downsampled_points,skeleton_points,"
        "scattered_points,discarded_points,knn_residuals,skeleton_residuals,map_inserted,"
        "skeleton_patches,gyro_bias_x,gyro_bias_y,gyro_bias_z,acc_bias_x,acc_bias_y,acc_bias_z,"
        "gravity_map_x,gravity_map_y,gravity_map_z,skeleton_planes,fit,motion_guess,"
        "guesses_tried,t_guesses_ms,correction_rot_deg,correction_pos_m,overruled,"
        "disagreement_rot_deg,disagreement_pos_m,gyro_saturated_s,consistency_search\n";
}

void WriteStatsCsvRow(std::ostream& os, const ScanResult& r) {
  const auto& t = r.timings;
  os << std::fixed << std::setprecision(6) << r.stamp_s << ',' << StatusName(r.status) << ','
     << Quoted(r.reason, '"') << ',' << (r.pose_valid ? 1 : 0) << ',' << r.iterations << ','
     << (r.converged ? 1 : 0) << std::setprecision(3) << ',' << t.preprocess << ',' << t.deskew
     << ',' << t.downsample << ',' << t.ppf << ',' << t.residuals << ',' << t.update << ','
     << t.map_insert << ',' << t.total << ',' << r.map_size << ',' << r.input_points << ','
     << r.valid_points << ',' << r.downsampled_points << ',' << r.skeleton_points << ','
     << r.scattered_points << ',' << r.discarded_points << ',' << r.knn_residuals << ','
     << r.skeleton_residuals << ',' << r.map_inserted << ',' << r.skeleton_patches;
  // The filter's bias and gravity estimates: compare with ppf_sim's imu_bias.csv, or watch them
  // settle on real data.
  os << std::setprecision(6);
  for (int i = 0; i < 3; ++i) os << ',' << r.gyro_bias(i);
  for (int i = 0; i < 3; ++i) os << ',' << r.acc_bias(i);
  for (int i = 0; i < 3; ++i) os << ',' << r.gravity_map(i);
  // LiDAR-only (docs/behaviour.md, "LiDAR-only"): how well the scan fit the map and which guess
  // won.
  os << ',' << r.skeleton_planes.size() << std::setprecision(3) << ',' << r.fit << ','
     << Quoted(r.motion_guess, '"') << ',' << r.guesses_tried << ',' << t.guesses;
  // How far the LiDAR moved the prediction, and whether it overruled it (Config::consistency).
  os << std::setprecision(4) << ',' << r.correction_rot_deg << ',' << r.correction_pos_m << ','
     << (r.overruled ? 1 : 0) << ',' << r.disagreement_rot_deg << ',' << r.disagreement_pos_m;
  // How long a gyro axis read at saturation in this scan's prediction (imu.noise.gyro_range).
  os << ',' << r.gyro_saturated_s;
  // What set the consistency check's search off, if one ran (none, fit, step).
  os << ',' << ConsistencySearchName(r.consistency_search);
  os << '\n';
}

void WriteStatsJson(std::ostream& os, const std::vector<ScanResult>& results) {
  os << "[\n";
  for (size_t i = 0; i < results.size(); ++i) {
    const auto& r = results[i];
    const auto& t = r.timings;
    os << std::fixed << std::setprecision(6) << "  {\"stamp\": " << r.stamp_s << ", \"status\": \""
       << StatusName(r.status) << "\", \"reason\": " << Quoted(r.reason, '\\')
       << ", \"pose_valid\": " << (r.pose_valid ? "true" : "false")
       << ", \"iterations\": " << r.iterations << std::setprecision(3)
       << ", \"t_preprocess_ms\": " << t.preprocess << ", \"t_deskew_ms\": " << t.deskew
       << ", \"t_downsample_ms\": " << t.downsample << ", \"t_ppf_ms\": " << t.ppf
       << ", \"t_residuals_ms\": " << t.residuals << ", \"t_update_ms\": " << t.update
       << ", \"t_map_insert_ms\": " << t.map_insert << ", \"t_total_ms\": " << t.total
       << ", \"map_size\": " << r.map_size << ", \"downsampled_points\": " << r.downsampled_points
       << ", \"skeleton_points\": " << r.skeleton_points
       << ", \"scattered_points\": " << r.scattered_points
       << ", \"knn_residuals\": " << r.knn_residuals
       << ", \"skeleton_residuals\": " << r.skeleton_residuals
       << ", \"skeleton_patches\": " << r.skeleton_patches << "}"
       << (i + 1 < results.size() ? ",\n" : "\n");
  }
  os << "]\n";
}

RunSummary Summarize(const std::vector<ScanResult>& results, double wall_s) {
  RunSummary s;
  s.scans = results.size();
  s.wall_s = wall_s;
  size_t n = 0;
  double core_ms = 0.0;
  for (const auto& r : results) {
    switch (r.status) {
      case Status::kOk: ++s.ok; break;
      case Status::kDegenerate: ++s.degenerate; break;
      case Status::kInitializing: ++s.initializing; break;
      case Status::kReset: ++s.reset; break;
      case Status::kRejected: ++s.rejected; break;
    }
    core_ms += r.timings.total;
    s.imu_lost += r.imu_lost;
    s.overruled += r.overruled;
    s.searched_fit += r.consistency_search == ConsistencySearch::kPoorFit;
    s.searched_step += r.consistency_search == ConsistencySearch::kScanStep;
    if (!r.pose_valid) continue;
    ++n;
    const auto& t = r.timings;
    s.mean.preprocess += t.preprocess;
    s.mean.deskew += t.deskew;
    s.mean.downsample += t.downsample;
    s.mean.ppf += t.ppf;
    s.mean.residuals += t.residuals;
    s.mean.update += t.update;
    s.mean.map_insert += t.map_insert;
    s.mean.total += t.total;
    s.mean_map_size += static_cast<double>(r.map_size);
    s.max_map_size = std::max(s.max_map_size, r.map_size);
    s.mean_skeleton_points += static_cast<double>(r.skeleton_points);
    s.mean_scattered_points += static_cast<double>(r.scattered_points);
    s.mean_knn_residuals += static_cast<double>(r.knn_residuals);
    s.mean_skeleton_residuals += static_cast<double>(r.skeleton_residuals);
  }
  if (n > 0) {
    const double k = 1.0 / static_cast<double>(n);
    for (double* v : {&s.mean.preprocess, &s.mean.deskew, &s.mean.downsample, &s.mean.ppf,
                      &s.mean.residuals, &s.mean.update, &s.mean.map_insert, &s.mean.total,
                      &s.mean_map_size, &s.mean_skeleton_points, &s.mean_scattered_points,
                      &s.mean_knn_residuals, &s.mean_skeleton_residuals}) {
      *v *= k;
    }
  }
  s.scans_per_s = core_ms > 0.0 ? 1000.0 * static_cast<double>(s.scans) / core_ms : 0.0;
  return s;
}

void PrintSummary(std::ostream& os, const RunSummary& s, const std::string& title) {
  os << title << "\n"
     << "  scans " << s.scans << " (ok " << s.ok << ", degenerate " << s.degenerate
     << ", initializing " << s.initializing << ", reset " << s.reset << ", rejected "
     << s.rejected << ")\n"
     << std::fixed << std::setprecision(2) << "  mean ms/scan: preprocess " << s.mean.preprocess
     << ", deskew " << s.mean.deskew << ", downsample " << s.mean.downsample << ", ppf "
     << s.mean.ppf << ", residuals " << s.mean.residuals << ", update " << s.mean.update
     << ", map insert " << s.mean.map_insert << ", total " << s.mean.total << "\n"
     << "  throughput " << std::setprecision(1) << s.scans_per_s << " scans/s (core), wall "
     << std::setprecision(2) << s.wall_s << " s\n"
     << "  local map: mean " << std::setprecision(0) << s.mean_map_size << " points, max "
     << s.max_map_size << "\n";
  if (s.imu_lost > 0) {
    os << "  IMU lost: " << s.imu_lost << " scans registered LiDAR-only (fallback)\n";
  }
  if (s.searched_fit + s.searched_step > 0) {
    // Every search, whether a guess won (overruled) or the pose was kept: a search costs several
    // scans' worth of core time, and one the map never confirms says the check fires on noise.
    os << "  consistency searches: " << s.searched_fit + s.searched_step << " (poor fit "
       << s.searched_fit << ", scan step " << s.searched_step << "), LiDAR overruled the IMU "
       << "prediction on " << s.overruled << " scans\n";
  }
}

}  // namespace ppf::tools
