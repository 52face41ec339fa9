// Parameters of plane pre-fitting (PPF) and skeleton tracking: Config::ppf, YAML section `ppf:`
// (keys = field names; all listed with their defaults in config/reference.yaml, read by the core's
// one loader, config.hpp).
//
// Every field has a default that works for a 16/32-beam sensor; PpfConfigForBeams() scales the
// density-dependent ones (the key `ppf.beams` selects it). The reference implementation crashed
// when a YAML key was missing; here every key is optional, and ValidatePpfConfig() (part of
// ValidateConfig) clamps nonsensical values instead of failing later.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ppf {

struct PpfConfig {
  // --- sandwich layer (paper Sec. IV-C) -------------------------------------------------------
  // Half-thickness of the strict band: |n.p + d| < delta -> skeleton point (Omega). Metres.
  // The paper uses 0.1 m because its skeleton points are matched to the scan-wide planes; here they
  // are matched to the 2 m patch of their own surface (anchor_patches), so the scan plane only
  // classifies and a wider band turns more points of gently curved or slightly rough surfaces into
  // skeleton points instead of discarding them or sending them to kNN. See the measurements below
  // max_planes_per_scan.
  double delta = 0.2;
  // Semi-inliers: delta <= |n.p + d| < semi_band_factor * delta are discarded (no residual, not in
  // the map). 2 with delta 0.2 -> semi band up to 0.4 m (the paper's 0.1 m x 4), i.e. at least
  // 2 eps beyond the plane so a point that stays for later rounds cannot pass the skeleton gate of
  // this plane.
  double semi_band_factor = 2.0;

  // --- skeleton residual (paper Eq. 10) -------------------------------------------------------
  // Gate eps: a skeleton point is matched to its nearest window plane only if closer than this.
  double point_to_plane_thresh = 0.2;
  // Normal-consistency gate (not in the paper; ALGORITHM-NOTES lists it as a possible
  // improvement): a skeleton point is matched only to window planes whose normal is within this
  // angle of its own fitted plane's normal. Degrees; 0 = off (the paper's Eq. 10 as is).
  // Measured: without it 0.6-1.6% of skeleton matches in the core's synthetic room paired a wall
  // point with the floor (new planes not in the window yet); with 10 deg none, and the 64-beam
  // room's APE dropped from 0.022 m to 0.002 m (urban HDL-32 sim: 0.032 -> 0.028 m, others equal).
  double skeleton_normal_gate_deg = 10.0;
  // Map-anchored skeleton residuals (plane_patch_map.hpp; not in the paper, which matches against
  // the previous scan's planes only): skeleton points are matched to the plane patch of their
  // world cell. Points in cells without a usable patch of their surface yet (one whose own points
  // fix its normal) get no residual, or with patch_window_fallback the nearest window plane as in
  // Eq. 10 (measured with the current defaults, that fallback nearly doubled the APE: geometric
  // mean PPF/kNN over eight ppf_sim sequences 1.21 -> 2.34). Patches of patch_size metres,
  // frozen after patch_max_points points, dropped beyond patch_radius metres. Measured (ppf_sim,
  // 30 s, paper's sandwich values, APE RMSE, anchored / anchored + fallback / window only, kNN mode
  // for reference), before patches had to fix their own normal (plane_patch_map.hpp):
  //   urban HDL-64   16.5 / 17.0 /  59 mm   (kNN  6 mm)
  //   urban HDL-32   62   / 76   / 110 mm   (kNN 36 mm)
  //   indoor VLP-16  22.6 / 22.3 /  26 mm   (kNN 16 mm)
  //   park HDL-32    56   / 56   /  80 mm   (kNN 46 mm)
  bool anchor_patches = true;
  bool patch_window_fallback = false;
  double patch_size = 2.0;
  int patch_max_points = 50;
  double patch_radius = 150.0;

  // --- fit-remove-fit --------------------------------------------------------------------------
  // Minimum strict inliers for a plane (guess or RANSAC) to be accepted. Must scale with density:
  // 80 for 16 beams, 150 for 32 beams, 400 for 64 beams, 600 for 128 beams (after 0.5 m
  // downsampling).
  int plane_least_inliers = 80;
  // At most this many planes are accepted per scan (guesses + RANSAC).
  int max_planes_per_scan = 10;
  // Stop fitting once fewer than this fraction of the input points remain.
  double min_remaining_ratio = 0.1;
  // The paper's values (delta 0.1, semi factor 4, 5 planes, stop at 25 % left, 150 inliers for 16
  // beams) left 36-54 % of the points to kNN and discarded up to 27 %. Measured with ppf_offline,
  // 1 thread, ppf_sim 30 s and 60 s sequences (APE RMSE PPF / kNN in mm; scattered share):
  //                     paper values          these defaults
  //   urban HDL-64 30 s  7.1 / 6.1, 36 %      8.8 / 6.1, 21 %
  //   urban HDL-64 60 s 33.7 / 18.9, 37 %    44.5 / 18.9, 17 %
  //   urban HDL-32 30 s 58.6 / 36.5, 47 %    23.7 / 36.5, 20 %
  //   urban HDL-32 60 s  186 / 170, 47 %      113 / 170, 18 %
  //   park HDL-32 30 s  54.4 / 46.4, 36 %    57.4 / 46.4, 15 %
  //   park HDL-32 60 s  52.5 / 47.0, 34 %    73.5 / 47.0, 14 %
  //   indoor VLP-16 30 s 23.2 / 15.8, 54 %   20.4 / 15.8, 19 %
  //   indoor VLP-16 60 s 17.7 / 13.3, 34 %   16.0 / 13.3, 16 %
  // Geometric mean of PPF/kNN APE over these eight: 1.32 -> 1.21, while kNN residuals fall to
  // 15-21 % of the points (residual stage 4-9x faster than kNN mode on 32/64 beams).
  // Incremental fitting: try the window planes moved by the IMU-predicted motion before RANSAC.
  // Paper: worth it for >= 64 beams (~6 ms -> ~1.5 ms). PpfConfigForBeams() enables it from 32
  // beams up (measured, see ppf_config.cpp); this plain default is the 16-beam one (off).
  bool incremental_fitting = false;
  // Shape tests of a candidate plane (RANSAC or guess), not in the paper. RANSAC scores a plane
  // by its inlier count alone, and with a band as wide as delta a count can come from things that
  // are not surfaces. A rejected RANSAC candidate is treated like a failed refinement: its band
  // goes to the scattered points (kNN), so nothing is lost; a rejected guess is skipped. Both
  // tests are measured in README.md (fake skeleton planes); 0 turns a test off (the paper).
  //
  // Thickness: reject when the RMS distance of the strict inliers from the plane exceeds this
  // fraction of delta. Points of a surface crowd the middle of the band; a slab cut through a
  // volume of scattered points (tree canopies, bushes, rough lawn) fills it evenly, RMS
  // delta / sqrt(3), and a slab through all the crowns around the sensor collects as many inliers
  // as a wall. Such a slab is labelled skeleton and anchors map patches with a normal the points
  // do not have.
  double max_band_rms_ratio = 0.5;
  // Beam spread: reject when the strict inliers' elevation angles in the LiDAR frame,
  // atan2(z, hypot(x, y)), span less than this many degrees between their 5th and 95th
  // percentiles. The points one beam returns from walls or trees at similar range lie on a
  // circle or arc that is planar within delta; that "plane" is attached to the sensor, not the
  // world. A surface seen by a multi-beam LiDAR is crossed by several beams. Must exceed the
  // spacing of two adjacent beams of the sensor.
  double min_elevation_spread_deg = 3.0;

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
