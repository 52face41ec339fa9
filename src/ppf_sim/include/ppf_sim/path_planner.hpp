// Planar paths that a vehicle or a walking person could follow: speed- and curvature-limited
// kinematics, sampled at the trajectory's knot spacing. The scene is then built around the path,
// which is what guarantees the sensor never drives through a wall.
#pragma once

#include <vector>

#include "ppf_sim/rng.hpp"

namespace ppf::sim {

struct PathSample {
  double x = 0, y = 0;
  double yaw = 0;    // heading, unwrapped
  double speed = 0;  // m/s
};

struct KinematicLimits {
  double cruise_speed = 10.0;   // m/s
  double accel = 1.5;           // m/s^2, longitudinal
  double lateral_accel = 2.0;   // m/s^2, limits speed in turns
  double max_curvature = 1.0 / 8.0;
  double curvature_rate = 0.01;  // 1/m per m of travel (clothoid-like entry into turns)
  double straight_min = 40.0, straight_max = 160.0;  // m
  double world_radius = 150.0;  // turn back towards the origin beyond this
};

// Random drive on open ground. Sample i is at time (i - 1) * dt; the path is at rest at the
// origin until `move_time`.
std::vector<PathSample> PlanOpenPath(const KinematicLimits& lim, double dt, int n_samples,
                                     double move_time, Rng& rng);

// Follows a polyline with corners rounded to `corner_radius`, accelerating from rest at
// `move_time` to `speed`; the walker stops at its end (pass a long enough polyline).
std::vector<PathSample> FollowPolyline(const std::vector<std::pair<double, double>>& pts,
                                       double corner_radius, double speed, double accel,
                                       double dt, int n_samples, double move_time);

// Moving average of yaw over +-half_window seconds (keeps the ends static).
void SmoothYaw(std::vector<PathSample>& path, double dt, double half_window);

}  // namespace ppf::sim
