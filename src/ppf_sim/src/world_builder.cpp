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

namespace {

// Default cruise speed per motion and scene when --speed is not given.
double CruiseSpeed(const WorldOptions& opt, bool handheld) {
  if (opt.speed <= 0.0) {
    if (handheld) return 1.3;
    if (opt.scene == "park") return 5.0;
    if (opt.scene == "indoor") return 1.0;
    if (opt.scene == "ramps") return 8.0;
    return 10.0;
  }
  return opt.speed;
}

// Knot timing shared by the path planner and the trajectory.
struct PathTiming {
  double static_time;   // rest at the start, s
  double move_time;     // first knot that may move, s
  double path_accel;    // longitudinal acceleration of the planned path, m/s^2
  double start_offset;  // sim time 0 on the planned path (moving start), s
  int n_samples;        // knots to plan
};

PathTiming MakePathTiming(const WorldOptions& opt, bool handheld, double speed) {
  PathTiming pt;
  pt.static_time = opt.moving_start ? 0.0 : opt.static_time;
  // The spline reaches 2 knots back and the suspension filter 3 more: start moving late enough
  // that the curve is exactly constant until static_time + 0.1 s.
  pt.move_time = pt.static_time + 6 * kKnotDt;
  pt.path_accel =
      opt.scene == "indoor" ? (handheld ? 0.6 : 0.4) : (handheld ? 0.7 : KinematicLimits().accel);
  // Moving start: skip the rest, the acceleration to cruise speed and one more second (the
  // shakes are fully faded in by then), in whole knots.
  pt.start_offset =
      opt.moving_start ? std::ceil((pt.move_time + speed / pt.path_accel + 1.0) / kKnotDt) * kKnotDt
                       : 0.0;
  pt.n_samples = static_cast<int>(std::ceil((opt.duration + pt.start_offset + 3.0) / kKnotDt)) + 4;
  return pt;
}

// Indoors the path walks the floor plan's loop; outdoors it is planned open-ended within the
// scene's limits (draws from rng only outdoors).
std::vector<PathSample> PlanPath(const WorldOptions& opt, bool handheld, double speed,
                                 const PathTiming& pt, Rng& rng) {
  std::vector<PathSample> path;
  if (opt.scene == "indoor") {
    path = FollowPolyline(IndoorPolyline(speed * (opt.duration + pt.start_offset + 5.0) + 20.0),
                          0.8, speed, pt.path_accel, kKnotDt, pt.n_samples, pt.move_time);
    SmoothYaw(path, kKnotDt, handheld ? 0.3 : 1.0);
    return path;
  }
  KinematicLimits lim;
  lim.cruise_speed = speed;
  if (handheld) {
    lim.accel = pt.path_accel;
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
  path = PlanOpenPath(lim, kKnotDt, pt.n_samples, pt.move_time, rng);
  if (handheld) SmoothYaw(path, kKnotDt, 0.3);
  return path;
}

// Knot poses (position, roll/pitch/yaw) of the sensor platform.
struct KnotPoses {
  std::vector<Eigen::Vector3d> pos, euler;
};

// Indoors the floor is flat: the sensor rides at a fixed height, level.
KnotPoses FlatFloorPoses(const std::vector<PathSample>& path, bool handheld) {
  KnotPoses k{std::vector<Eigen::Vector3d>(path.size()), std::vector<Eigen::Vector3d>(path.size())};
  const double z = handheld ? 1.3 : 0.9;
  for (size_t i = 0; i < path.size(); ++i) {
    k.pos[i] = {path[i].x, path[i].y, z};
    k.euler[i] = {0.0, 0.0, path[i].yaw};
  }
  return k;
}

// Outdoors the platform stands on the terrain: a car tilts with the ground under its wheels, a
// hand-held sensor keeps level at a fixed height above the ground.
KnotPoses TerrainPoses(const std::vector<PathSample>& path, const HeightField& hf, bool handheld) {
  KnotPoses k{std::vector<Eigen::Vector3d>(path.size()), std::vector<Eigen::Vector3d>(path.size())};
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
      ground = 0.25 *
               (hf.Height(p.x + 1.4 * c, p.y + 1.4 * s) + hf.Height(p.x - 1.4 * c, p.y - 1.4 * s) +
                hf.Height(p.x - 0.8 * s, p.y + 0.8 * c) + hf.Height(p.x + 0.8 * s, p.y - 0.8 * c));
    }
    k.pos[i] = {p.x, p.y, ground + mount};
    k.euler[i] = {roll, pitch, p.yaw};
  }
  return k;
}

// Suspension: low-pass height and attitude over +-0.3 s so small bumps do not become large
// accelerations (the shakes add the vibration back in a controlled way).
void ApplySuspension(KnotPoses* k) {
  std::vector<Eigen::Vector3d>& pos = k->pos;
  std::vector<Eigen::Vector3d>& euler = k->euler;
  const int w = 3;
  const auto raw_pos = pos;
  const auto raw_euler = euler;
  for (int i = 0; i < static_cast<int>(pos.size()); ++i) {
    double z = 0, r = 0, pt = 0;
    int cnt = 0;
    for (int j = std::max(0, i - w); j <= std::min(static_cast<int>(pos.size()) - 1, i + w); ++j) {
      z += raw_pos[j].z();
      r += raw_euler[j].x();
      pt += raw_euler[j].y();
      ++cnt;
    }
    pos[i].z() = z / cnt;
    euler[i].x() = r / cnt;
    euler[i].y() = pt / cnt;
  }
}

// Fills world->scene with the scene's objects (and terrain outdoors) and returns the platform's
// knot poses over it. Draws from rng in a fixed order: terrain, then objects.
KnotPoses PopulateScene(const WorldOptions& opt, bool handheld, const std::vector<PathSample>& path,
                        Rng& rng, World* world) {
  const PathIndex idx(path);
  if (opt.scene == "indoor") {
    PopulateIndoor(world->scene, idx, rng);
    return FlatFloorPoses(path, handheld);
  }
  HeightField hf = MakeTerrain(path, opt.scene, rng, 130.0);
  if (opt.scene == "urban") PopulateUrban(world->scene, path, idx, hf, rng);
  if (opt.scene == "park") PopulatePark(world->scene, path, idx, hf, rng);
  if (opt.scene == "ramps") PopulateRamps(world->scene, path, idx, hf, rng);
  KnotPoses k = TerrainPoses(path, hf, handheld);
  ApplySuspension(&k);
  world->scene.SetGround(std::move(hf));
  return k;
}

}  // namespace

World BuildWorld(const WorldOptions& opt) {
  const auto names = SceneNames();
  if (std::find(names.begin(), names.end(), opt.scene) == names.end()) {
    throw std::invalid_argument("unknown scene '" + opt.scene + "' (urban, indoor, park, ramps)");
  }
  World world;
  world.motion = opt.motion_is_default ? DefaultMotion(opt.scene) : opt.motion;
  const bool handheld = world.motion == MotionKind::kHandheld;
  world.speed = CruiseSpeed(opt, handheld);
  // One generator for the whole world, drawn from in a fixed order (path, terrain, objects,
  // shakes): the same seed gives the same bytes.
  Rng rng(opt.seed, 0x5CE7Eu);
  const PathTiming timing = MakePathTiming(opt, handheld, world.speed);
  const std::vector<PathSample> path = PlanPath(opt, handheld, world.speed, timing, rng);
  KnotPoses knots = PopulateScene(opt, handheld, path, rng, &world);
  world.scene.Build(4.0);
  world.trajectory = Trajectory(kKnotDt, std::move(knots.pos), std::move(knots.euler));
  world.trajectory.SetShakes(handheld ? HandheldShakes(rng, opt.max_rate_deg) : CarShakes(rng),
                             timing.static_time + 0.1, 1.5);
  if (opt.moving_start) {
    world.trajectory.StartAt(timing.start_offset);
    world.start_offset = timing.start_offset;
  }
  return world;
}

}  // namespace ppf::sim
