// A scene together with the ground-truth trajectory that moves through it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ppf_sim/scene.hpp"
#include "ppf_sim/trajectory.hpp"

namespace ppf::sim {

enum class MotionKind { kCar, kHandheld };

struct WorldOptions {
  std::string scene = "urban";  // urban | indoor | park | ramps
  MotionKind motion = MotionKind::kCar;
  bool motion_is_default = true;  // true: use the scene's default motion
  double speed = 0.0;             // m/s; 0 = default (car 10, park car 5, walking 1.3)
  double duration = 30.0;         // s the trajectory must cover
  double static_time = 2.5;       // s at rest at the start
  // The sequence begins in motion: the trajectory is planned with a short rest, then time zero
  // is moved to after the acceleration to cruise speed plus a second (static_time is ignored).
  bool moving_start = false;
  double max_rate_deg = 150.0;    // hand-held shake: peak rate of the shake, deg/s (turns add)
  // m; open-ground car drives (urban, park, ramps) turn back towards the origin beyond this
  // distance. 0 = the scene's own (150 m, park 100 m). Larger values let long drives (endurance
  // runs) keep reaching new ground instead of circling the same few blocks.
  double roam_radius = 0.0;
  uint64_t seed = 1;
};

struct World {
  Scene scene;
  Trajectory trajectory;
  MotionKind motion = MotionKind::kCar;
  double speed = 0.0;
  double start_offset = 0.0;  // moving_start: time of the planned motion that became time zero
};

std::vector<std::string> SceneNames();
MotionKind DefaultMotion(const std::string& scene);
// Throws std::invalid_argument for an unknown scene.
World BuildWorld(const WorldOptions& opt);

}  // namespace ppf::sim
