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
  // Without it a wall point new to the window can be matched to the floor (docs/decisions.md,
  // "Normal gate").
  double skeleton_normal_gate_deg = 10.0;
  // At most this many residual rows per pre-fit plane (not in the paper; 0 = one per skeleton
  // point): every (count / cap)-th of its points in scan order, each row weighted count / cap, so
  // a plane keeps the spread and the information of all its points while a dense LiDAR's plane
  // of thousands of points costs the rows of a few hundred (docs/decisions.md, "Skeleton rows
  // per plane").
  int skeleton_rows_per_plane = 0;
  // Map-anchored skeleton residuals (plane_patch_map.hpp; not in the paper, which matches against
  // the previous scan's planes only): skeleton points are matched to the plane patch of their
  // world cell. Points in cells without a usable patch of their surface yet (one whose own points
  // fix its normal) get no residual, or with patch_window_fallback the nearest window plane as in
  // Eq. 10 (off: the window planes carry the scan-to-scan bias the patches remove). Patches of
  // patch_size metres, frozen after patch_max_points points, dropped beyond patch_radius metres.
  // The APE of anchored / fallback / window-only: docs/decisions.md, "Map-anchored skeleton
  // residuals".
  bool anchor_patches = true;
  bool patch_window_fallback = false;
  double patch_size = 2.0;
  int patch_max_points = 50;
  double patch_radius = 150.0;

  // --- fit-remove-fit --------------------------------------------------------------------------
  // Minimum strict inliers for a plane (guess or RANSAC) to be accepted. Must scale with density
  // (PpfConfigForBeams: 80 for 16 beams up to 600 for 128, after 0.5 m downsampling).
  int plane_least_inliers = 80;
  // At most this many planes are accepted per scan (guesses + RANSAC).
  int max_planes_per_scan = 10;
  // Stop fitting once fewer than this fraction of the input points remain.
  double min_remaining_ratio = 0.1;
  // The paper's values (delta 0.1, semi factor 4, 5 planes, stop at 25 % left, 150 inliers for 16
  // beams) left a third to a half of the points to kNN and discarded many; these defaults leave
  // about a fifth to kNN at a similar APE (docs/decisions.md, "Fit-remove-fit defaults").
  // Incremental fitting: try the window planes moved by the IMU-predicted motion before RANSAC.
  // The paper uses it for >= 64 beams; here it is on for every beam count (docs/decisions.md,
  // "Incremental fitting").
  bool incremental_fitting = true;
  // Shape tests of a candidate plane (RANSAC or guess), not in the paper. RANSAC scores a plane
  // by its inlier count alone, and with a band as wide as delta a count can come from things that
  // are not surfaces. A rejected RANSAC candidate is treated like a failed refinement: its band
  // goes to the scattered points (kNN), so nothing is lost; a rejected guess is skipped. Both
  // tests are measured in docs/results.md (fake skeleton planes); 0 turns a test off (the paper).
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
// class). Density-dependent: plane_least_inliers.
PpfConfig PpfConfigForBeams(int beams);

// Clamps out-of-range values to safe ones and returns a human-readable note per fix (empty if the
// config was already valid). Never throws.
std::vector<std::string> ValidatePpfConfig(PpfConfig* config);

}  // namespace ppf
