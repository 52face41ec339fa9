// Per-scan statistics files written by ppf_offline (and readable by the comparison benchmark).
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "ppf_core/lio_ppf.hpp"

namespace ppf::tools {

// CSV header and one row per ScanResult; JSON is an array of objects with the same keys.
void WriteStatsCsvHeader(std::ostream& os);
void WriteStatsCsvRow(std::ostream& os, const ScanResult& r);
void WriteStatsJson(std::ostream& os, const std::vector<ScanResult>& results);

// Aggregate over a run: means of the stage timings over scans with a pose, throughput, map size.
struct RunSummary {
  size_t scans = 0;
  size_t ok = 0, degenerate = 0, initializing = 0, reset = 0, rejected = 0;
  StageTimings mean;            // ms, over scans with pose_valid
  double wall_s = 0.0;          // whole run, including bag decoding
  double scans_per_s = 0.0;     // processed scans / sum of core total time
  double mean_map_size = 0.0;
  size_t max_map_size = 0;
  double mean_skeleton_points = 0.0, mean_scattered_points = 0.0;
  double mean_knn_residuals = 0.0, mean_skeleton_residuals = 0.0;
  size_t imu_lost = 0;  // scans registered LiDAR-only because the IMU stream was lost
  size_t overruled = 0;  // scans whose IMU prediction the map contradicted and the LiDAR moved
  // Scans the consistency check searched (ScanResult::consistency_search), by what set it off.
  size_t searched_fit = 0, searched_step = 0;
};
RunSummary Summarize(const std::vector<ScanResult>& results, double wall_s);
void PrintSummary(std::ostream& os, const RunSummary& s, const std::string& title);

}  // namespace ppf::tools
