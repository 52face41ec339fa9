// Builds the four scenes around a planned path and turns the path into the C2 trajectory.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "ppf_sim/path_planner.hpp"
#include "ppf_sim/rng.hpp"
#include "ppf_sim/world.hpp"
#include "world_detail.hpp"

namespace ppf::sim {

namespace {
constexpr double kKnotDt = 0.1;
}  // namespace

using namespace detail;

std::vector<std::string> SceneNames() { return {"urban", "indoor", "park", "ramps"}; }

MotionKind DefaultMotion(const std::string& scene) {
  return scene == "indoor" ? MotionKind::kHandheld : MotionKind::kCar;
}

World BuildWorld(const WorldOptions& opt) {
  const auto names = SceneNames();
  if (std::find(names.begin(), names.end(), opt.scene) == names.end()) {
    throw std::invalid_argument("unknown scene '" + opt.scene + "' (urban, indoor, park, ramps)");
  }
  World world;
  world.motion = opt.motion_is_default ? DefaultMotion(opt.scene) : opt.motion;
  const bool handheld = world.motion == MotionKind::kHandheld;
  double speed = opt.speed;
  if (speed <= 0.0) {
    if (handheld) speed = 1.3;
    else if (opt.scene == "park") speed = 5.0;
    else if (opt.scene == "indoor") speed = 1.0;
    else if (opt.scene == "ramps") speed = 8.0;
    else speed = 10.0;
  }
  world.speed = speed;
  Rng rng(opt.seed, 0x5CE7Eu);
  const double static_time = opt.moving_start ? 0.0 : opt.static_time;
  // The spline reaches 2 knots back and the suspension filter 3 more: start moving late enough
  // that the curve is exactly constant until static_time + 0.1 s.
  const double move_time = static_time + 6 * kKnotDt;
  const double path_accel =
      opt.scene == "indoor" ? (handheld ? 0.6 : 0.4) : (handheld ? 0.7 : KinematicLimits().accel);
  // Moving start: skip the rest, the acceleration to cruise speed and one more second (the
  // shakes are fully faded in by then), in whole knots.
  const double start_offset =
      opt.moving_start ? std::ceil((move_time + speed / path_accel + 1.0) / kKnotDt) * kKnotDt
                       : 0.0;
  const int n_samples =
      static_cast<int>(std::ceil((opt.duration + start_offset + 3.0) / kKnotDt)) + 4;

  std::vector<PathSample> path;
  if (opt.scene == "indoor") {
    path = FollowPolyline(IndoorPolyline(speed * (opt.duration + start_offset + 5.0) + 20.0), 0.8,
                          speed, path_accel, kKnotDt, n_samples, move_time);
    SmoothYaw(path, kKnotDt, handheld ? 0.3 : 1.0);
  } else {
    KinematicLimits lim;
    lim.cruise_speed = speed;
    if (handheld) {
      lim.accel = path_accel;
      lim.lateral_accel = 1.0;
      lim.max_curvature = 0.5;
      lim.curvature_rate = 0.5;
      lim.straight_min = 10;
      lim.straight_max = 40;
      lim.world_radius = 40;
    } else if (opt.scene == "park") {
      lim.max_curvature = 1.0 / 6.0;
      lim.straight_min = 20;
      lim.straight_max = 80;
      lim.world_radius = 100;
    }
    if (opt.roam_radius > 0.0 && !handheld) lim.world_radius = opt.roam_radius;
    path = PlanOpenPath(lim, kKnotDt, n_samples, move_time, rng);
    if (handheld) SmoothYaw(path, kKnotDt, 0.3);
  }
  const PathIndex idx(path);

  std::vector<Eigen::Vector3d> pos(path.size()), euler(path.size());
  if (opt.scene == "indoor") {
    PopulateIndoor(world.scene, idx, rng);
    const double z = handheld ? 1.3 : 0.9;
    for (size_t i = 0; i < path.size(); ++i) {
      pos[i] = {path[i].x, path[i].y, z};
      euler[i] = {0.0, 0.0, path[i].yaw};
    }
  } else {
    HeightField hf = MakeTerrain(path, opt.scene, rng, 130.0);
    if (opt.scene == "urban") PopulateUrban(world.scene, path, idx, hf, rng);
    if (opt.scene == "park") PopulatePark(world.scene, path, idx, hf, rng);
    if (opt.scene == "ramps") PopulateRamps(world.scene, path, idx, hf, rng);
    const double mount = handheld ? 1.3 : 1.6;
    for (size_t i = 0; i < path.size(); ++i) {
      const PathSample& p = path[i];
      double roll = 0.0, pitch = 0.0;
      if (!handheld) {
        // The body follows the ground under the wheels (1.4 m half wheelbase, 0.8 m half track).
        const double c = std::cos(p.yaw), s = std::sin(p.yaw);
        const double hf_front = hf.Height(p.x + 1.4 * c, p.y + 1.4 * s);
        const double hf_back = hf.Height(p.x - 1.4 * c, p.y - 1.4 * s);
        const double hf_left = hf.Height(p.x - 0.8 * s, p.y + 0.8 * c);
        const double hf_right = hf.Height(p.x + 0.8 * s, p.y - 0.8 * c);
        pitch = -std::atan2(hf_front - hf_back, 2.8);
        roll = std::atan2(hf_left - hf_right, 1.6);
      }
      // Wheels average the ground: the mean of the contact points, not the height at the centre.
      const double c = std::cos(p.yaw), s = std::sin(p.yaw);
      double ground = hf.Height(p.x, p.y);
      if (!handheld) {
        ground = 0.25 * (hf.Height(p.x + 1.4 * c, p.y + 1.4 * s) +
                         hf.Height(p.x - 1.4 * c, p.y - 1.4 * s) +
                         hf.Height(p.x - 0.8 * s, p.y + 0.8 * c) +
                         hf.Height(p.x + 0.8 * s, p.y - 0.8 * c));
      }
      pos[i] = {p.x, p.y, ground + mount};
      euler[i] = {roll, pitch, p.yaw};
    }
    // Suspension: low-pass height and attitude over +-0.3 s so small bumps do not become
    // large accelerations (the shakes add the vibration back in a controlled way).
    const int w = 3;
    const auto raw_pos = pos;
    const auto raw_euler = euler;
    for (int i = 0; i < static_cast<int>(pos.size()); ++i) {
      double z = 0, r = 0, pt = 0;
      int cnt = 0;
      for (int k = std::max(0, i - w); k <= std::min(static_cast<int>(pos.size()) - 1, i + w); ++k) {
        z += raw_pos[k].z();
        r += raw_euler[k].x();
        pt += raw_euler[k].y();
        ++cnt;
      }
      pos[i].z() = z / cnt;
      euler[i].x() = r / cnt;
      euler[i].y() = pt / cnt;
    }
    world.scene.SetGround(std::move(hf));
  }
  world.scene.Build(4.0);
  world.trajectory = Trajectory(kKnotDt, std::move(pos), std::move(euler));
  world.trajectory.SetShakes(handheld ? HandheldShakes(rng, opt.max_rate_deg) : CarShakes(rng),
                             static_time + 0.1, 1.5);
  if (opt.moving_start) {
    world.trajectory.StartAt(start_offset);
    world.start_offset = start_offset;
  }
  return world;
}

}  // namespace ppf::sim
