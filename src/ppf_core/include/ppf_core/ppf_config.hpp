// Parameters of plane pre-fitting (PPF) and skeleton tracking.
//
// Every field has a default that works for a 32-beam sensor; PpfConfigForBeams() scales the
// density-dependent ones. The reference implementation crashed when a YAML key was missing; here a
// missing key simply keeps the default (see LoadPpfConfig in ppf_config_yaml.hpp when yaml-cpp is
// available), and ValidatePpfConfig() clamps nonsensical values instead of failing later.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ppf {

struct PpfConfig {
  // --- sandwich layer (paper Sec. IV-C) -------------------------------------------------------
  // Half-thickness of the strict band: |n.p + d| < delta -> skeleton point (Omega). Metres.
  double delta = 0.1;
  // Semi-inliers: delta <= |n.p + d| < semi_band_factor * delta are discarded (no residual, not in
  // the map). 4 -> semi band up to 0.4 m, i.e. at least 2 eps beyond the strict band so a point
  // that stays for later rounds cannot pass the skeleton gate of this plane.
  double semi_band_factor = 4.0;

  // --- skeleton residual (paper Eq. 10) -------------------------------------------------------
  // Gate eps: a skeleton point is matched to its nearest window plane only if closer than this.
  double point_to_plane_thresh = 0.2;

  // --- fit-remove-fit --------------------------------------------------------------------------
  // Minimum strict inliers for a plane (guess or RANSAC) to be accepted. Must scale with density:
  // 150 for 16/32 beams, 400 for 64 beams, 600 for 128 beams (after 0.5 m downsampling).
  int plane_least_inliers = 150;
  // At most this many planes are accepted per scan (guesses + RANSAC).
  int max_planes_per_scan = 5;
  // Stop fitting once fewer than this fraction of the input points remain.
  double min_remaining_ratio = 0.25;
  // Incremental fitting: try the window planes moved by the IMU-predicted motion before RANSAC.
  // Paper: worth it for >= 64 beams (~6 ms -> ~1.5 ms), off for 16/32 beams.
  bool incremental_fitting = false;

  // --- RANSAC ----------------------------------------------------------------------------------
  int ransac_max_iterations = 300;          // cap on the adaptive k = log(1-p)/log(1-w^3)
  double ransac_confidence = 0.99;          // p in the adaptive iteration count
  int ransac_max_degenerate_samples = 300;  // give up after this many rejected 3-point samples
  // A 3-point sample is degenerate if |(p1-p0)x(p2-p0)| (twice the triangle area) is below this
  // (m^2). Guards the normalisation against collinear and coincident samples.
  double ransac_min_sample_area = 1e-4;
  uint64_t ransac_seed = 0x5eed1234abcdULL;  // fixed: same scan -> same planes (reproducible runs)

  // --- iPCA (paper Sec. IV-A2) -----------------------------------------------------------------
  int ipca_iterations_new = 3;    // refinement iterations for planes found by RANSAC
  int ipca_iterations_guess = 5;  // refinement iterations for accepted incremental guesses

  // --- skeleton window F (paper Sec. IV-B) -----------------------------------------------------
  int window_size = 5;  // max planes kept in the world-frame window
  // A track not re-observed for more than this many scans leaves the window. 0 reproduces the
  // reference behaviour with incremental fitting (window = this scan's planes only).
  int window_max_missed_scans = 2;
  // Track association (keeps ids stable for the same physical plane across scans): a new plane
  // continues a track if the normals agree within this angle and the new plane's inlier centroid
  // lies within this distance of the tracked plane.
  double track_max_angle_deg = 5.0;
  double track_max_offset = 0.2;

  // --- threading -------------------------------------------------------------------------------
  int num_threads = 0;  // OpenMP threads for PPF loops; 0 = leave the OpenMP default
};

// Defaults for a sensor with `beams` rows (16, 32, 64, 128; other values round to the nearest
// class). Density-dependent: plane_least_inliers and incremental_fitting.
PpfConfig PpfConfigForBeams(int beams);

// Clamps out-of-range values to safe ones and returns a human-readable note per fix (empty if the
// config was already valid). Never throws.
std::vector<std::string> ValidatePpfConfig(PpfConfig* config);

}  // namespace ppf
