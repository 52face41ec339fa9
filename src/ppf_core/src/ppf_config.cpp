#include "ppf_core/ppf_config.hpp"

#include <cmath>
#include <sstream>

namespace ppf {

PpfConfig PpfConfigForBeams(int beams) {
  PpfConfig c;
  // After 0.5 m downsampling a 32-beam scan keeps a few thousand points; the reference configs
  // use 150 for 16 and 32 beams. 64 beams keep ~3x more points on the same surfaces.
  // Incremental fitting is not density-dependent any more: the reference enables it for 64 beams
  // only, here its default (on) holds for every class, as on 32 and 16 beams it was both faster
  // and at least as accurate (docs/decisions.md, "Incremental fitting").
  if (beams >= 96) {
    c.plane_least_inliers = 600;
  } else if (beams >= 48) {
    c.plane_least_inliers = 400;
  } else if (beams >= 24) {
    c.plane_least_inliers = 150;
  } else {
    // Half the 32-beam count: a 16-beam scan keeps ~1000 points after downsampling, and 150 left
    // the walls of short corridors to kNN (docs/decisions.md, "Least inliers for 16 beams").
    c.plane_least_inliers = 80;
  }
  return c;
}

namespace {

template <typename T>
void Fix(bool bad, T* value, T fallback, const char* name, std::vector<std::string>* notes) {
  if (!bad) return;
  std::ostringstream msg;
  msg << "ppf." << name << " = " << *value << " is invalid; using " << fallback;
  notes->push_back(msg.str());
  *value = fallback;
}

bool BadPositive(double v) { return !std::isfinite(v) || v <= 0.0; }

}  // namespace

std::vector<std::string> ValidatePpfConfig(PpfConfig* c) {
  const PpfConfig d;  // defaults
  std::vector<std::string> notes;
  Fix(BadPositive(c->delta), &c->delta, d.delta, "delta", &notes);
  Fix(!std::isfinite(c->semi_band_factor) || c->semi_band_factor < 1.0, &c->semi_band_factor,
      d.semi_band_factor, "semi_band_factor", &notes);
  Fix(BadPositive(c->point_to_plane_thresh), &c->point_to_plane_thresh, d.point_to_plane_thresh,
      "point_to_plane_thresh", &notes);
  Fix(!std::isfinite(c->skeleton_normal_gate_deg) || c->skeleton_normal_gate_deg < 0.0,
      &c->skeleton_normal_gate_deg, d.skeleton_normal_gate_deg, "skeleton_normal_gate_deg", &notes);
  Fix(c->skeleton_rows_per_plane < 0, &c->skeleton_rows_per_plane, d.skeleton_rows_per_plane,
      "skeleton_rows_per_plane", &notes);
  Fix(c->plane_least_inliers < 3, &c->plane_least_inliers, d.plane_least_inliers,
      "plane_least_inliers", &notes);
  Fix(!std::isfinite(c->min_elevation_spread_deg) || c->min_elevation_spread_deg < 0.0 ||
          c->min_elevation_spread_deg > 90.0,
      &c->min_elevation_spread_deg, d.min_elevation_spread_deg, "min_elevation_spread_deg",
      &notes);
  Fix(!std::isfinite(c->max_band_rms_ratio) || c->max_band_rms_ratio < 0.0,
      &c->max_band_rms_ratio, d.max_band_rms_ratio, "max_band_rms_ratio", &notes);
  Fix(c->max_planes_per_scan < 0, &c->max_planes_per_scan, d.max_planes_per_scan,
      "max_planes_per_scan", &notes);
  Fix(!std::isfinite(c->min_remaining_ratio) || c->min_remaining_ratio < 0.0 ||
          c->min_remaining_ratio > 1.0,
      &c->min_remaining_ratio, d.min_remaining_ratio, "min_remaining_ratio", &notes);
  Fix(c->ransac_max_iterations < 1, &c->ransac_max_iterations, d.ransac_max_iterations,
      "ransac_max_iterations", &notes);
  Fix(!std::isfinite(c->ransac_confidence) || c->ransac_confidence <= 0.0 ||
          c->ransac_confidence >= 1.0,
      &c->ransac_confidence, d.ransac_confidence, "ransac_confidence", &notes);
  Fix(c->ransac_max_degenerate_samples < 1, &c->ransac_max_degenerate_samples,
      d.ransac_max_degenerate_samples, "ransac_max_degenerate_samples", &notes);
  Fix(!std::isfinite(c->ransac_min_sample_area) || c->ransac_min_sample_area < 0.0,
      &c->ransac_min_sample_area, d.ransac_min_sample_area, "ransac_min_sample_area", &notes);
  Fix(c->ipca_iterations_new < 0, &c->ipca_iterations_new, d.ipca_iterations_new,
      "ipca_iterations_new", &notes);
  Fix(c->ipca_iterations_guess < 0, &c->ipca_iterations_guess, d.ipca_iterations_guess,
      "ipca_iterations_guess", &notes);
  Fix(c->window_size < 0, &c->window_size, d.window_size, "window_size", &notes);
  Fix(c->window_max_missed_scans < 0, &c->window_max_missed_scans, d.window_max_missed_scans,
      "window_max_missed_scans", &notes);
  Fix(!std::isfinite(c->track_max_angle_deg) || c->track_max_angle_deg < 0.0 ||
          c->track_max_angle_deg > 90.0,
      &c->track_max_angle_deg, d.track_max_angle_deg, "track_max_angle_deg", &notes);
  Fix(!std::isfinite(c->track_max_offset) || c->track_max_offset < 0.0, &c->track_max_offset,
      d.track_max_offset, "track_max_offset", &notes);
  Fix(BadPositive(c->patch_size), &c->patch_size, d.patch_size, "patch_size", &notes);
  Fix(c->patch_max_points < 3, &c->patch_max_points, d.patch_max_points, "patch_max_points",
      &notes);
  Fix(!std::isfinite(c->patch_radius) || c->patch_radius < 0.0, &c->patch_radius, d.patch_radius,
      "patch_radius", &notes);
  Fix(c->num_threads < 0, &c->num_threads, d.num_threads, "num_threads", &notes);
  return notes;
}

}  // namespace ppf
