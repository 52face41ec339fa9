// Long simulated drives streamed into the core in-process: the simulator (ppf_sim_gen) makes each
// scan and the IMU samples up to its end, the facade (ppf::LioPpf) consumes them, nothing goes to
// disk (a 10-minute VLP-16 bag would be gigabytes). Measures what a long run must keep bounded:
// the local map (points, voxels) and the process memory (VmRSS), plus the trajectory error and
// how well the estimated world keeps gravity's "up" (tilt, height error).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "ppf_core/lio_ppf.hpp"
#include "ppf_trajectory/evaluation.hpp"

namespace ppf::tools {

struct EnduranceOptions {
  std::string scene = "urban";
  std::string lidar = "vlp16";
  double duration = 600.0;   // s of simulated time, including the static start
  double roam_radius = 0.0;  // m; car drives turn back beyond this (0 = the scene's default)
  uint64_t seed = 1;
  double report_every = 60.0;  // s of simulated time between progress rows
  double tilt_after = 10.0;    // s after the first pose from which the tilt statistics count
};

// One progress row (every report_every s of simulated time, and at the end).
struct EnduranceRow {
  double sim_time = 0;         // s
  double distance = 0;         // m driven (ground truth)
  size_t map_points = 0;       // ScanResult::map_size of the last scan
  size_t map_voxels = 0;       // LioPpf::map_stats().voxels
  size_t max_map_points = 0;   // since the start
  size_t patches = 0;          // ScanResult::skeleton_patches (PPF mode's plane patch map)
  double rss_mb = 0;           // VmRSS
  double ape_rmse = 0;         // m, SE(3)-aligned APE of the trajectory so far (-1: too short)
  double ape_posyaw_rmse = 0;  // m, the same aligned by position + yaw only (-1: too short)
  double tilt_max_deg = -1;    // so far, from tilt_after on (-1: no pose yet)
  double dz_m = 0;             // height error now, first pose matched by translation + yaw
  double wall_s = 0;           // since the drive started
  size_t scans = 0, posed = 0;
};

struct EnduranceReport {
  std::vector<EnduranceRow> rows;
  size_t scans = 0, posed = 0, resets = 0, rejected = 0, degenerate = 0;
  double distance = 0;  // m
  // Local map over the two halves of the drive (by simulated time).
  size_t max_map_first_half = 0, max_map_second_half = 0;
  size_t max_voxels_first_half = 0, max_voxels_second_half = 0;
  // PPF mode: plane patches (the skeleton points' share of the map, bounded by ppf.patch_radius).
  size_t max_patches_first_half = 0, max_patches_second_half = 0;
  size_t map_capacity_points = 0;  // the LRU bound max_voxels * max_points_per_voxel
  // Process memory: VmRSS when the second half starts and its maximum over the second half.
  double rss_half_mb = 0, rss_max_second_half_mb = 0, rss_start_mb = 0, rss_end_mb = 0;
  double map_radius = 0;  // m, Config map.radius
  // Times the sensor got farther than map_radius from where it was at the previous count (the
  // first: from the start), i.e. everything mapped there had to leave the map.
  int radius_crossings = 0;
  double max_distance_from_start = 0;  // m
  EvalResult ape;          // SE(3)-aligned, against the exact ground truth at the scan stamps
  EvalResult ape_posyaw;   // position + yaw aligned
  GravityMetrics gravity;  // tilt from options.tilt_after on, height error
  double path_length = 0;
  double ApePercent() const {
    return ape.ok && path_length > 0 ? 100.0 * ape.stats.rmse / path_length : -1.0;
  }
  double ApePosYawPercent() const {
    return ape_posyaw.ok && path_length > 0 ? 100.0 * ape_posyaw.stats.rmse / path_length : -1.0;
  }
  double wall_s = 0, sim_wall_s = 0;  // whole drive; of which making scans and IMU
};

// VmRSS of this process in MB (from /proc/self/status); 0 if unavailable.
double CurrentRssMb();

// Builds the world, streams the drive into a LioPpf with `config` (its T_imu_lidar is replaced by
// the simulator's mount) and reports. on_row is called for every progress row as it is made.
// Throws std::invalid_argument for an unknown scene or LiDAR.
EnduranceReport RunEndurance(const EnduranceOptions& options, const Config& config,
                             const std::function<void(const EnduranceRow&)>& on_row = {});

}  // namespace ppf::tools
