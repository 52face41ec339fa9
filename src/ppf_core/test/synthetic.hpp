// Synthetic data for the core's tests: a box room with pillars (cast with ppf_sim's scene), an analytic trajectory with IMU
// samples from exact (or finite-difference) derivatives, a spinning multi-beam LiDAR with
// per-point time, and a CloudView encoder for every time-field convention.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/cloud_view.hpp"
#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/imu_sample.hpp"
#include "ppf_core/lio/so3.hpp"
#include "ppf_sim/scene.hpp"

namespace ppf::test {

constexpr double kPi = 3.14159265358979323846;
const Eigen::Vector3d kGravity(0.0, 0.0, -9.81);

// Axis-aligned box; `room` boxes are seen from inside (walls), others from outside (obstacles).
struct Box {
  Eigen::Vector3d lo, hi;
  bool room = false;
};

// Boxes cast with the simulator's scene (ppf_sim_gen), the one ray caster of the project: a room
// becomes six wall quads that overlap by 1 cm at the edges (a ray into a corner hits one), an
// obstacle a box. Built on the first cast after `boxes` changed; tests cast from one thread.
struct Scene {
  std::vector<Box> boxes;

  // Distance along unit `d` from `o` to the first surface, or +inf.
  double Raycast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    if (!built_ || built_boxes_ != boxes.size()) Build();
    sim::Ray ray;
    ray.o = o;
    ray.d = d;
    ray.tmin = 1e-6;
    sim::Hit hit;
    return built_->Intersect(ray, &hit) ? hit.t : std::numeric_limits<double>::infinity();
  }

 private:
  void Build() const {
    auto s = std::make_shared<sim::Scene>();
    const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                          Z = Eigen::Vector3d::UnitZ();
    for (const Box& b : boxes) {
      const Eigen::Vector3d c = 0.5 * (b.lo + b.hi), h = 0.5 * (b.hi - b.lo);
      if (!b.room) {
        s->Add(sim::MakeBox(c.x(), c.y(), 0.0, h.x(), h.y(), b.lo.z(), b.hi.z(), 0.3f));
        continue;
      }
      const Eigen::Vector3d e = h + Eigen::Vector3d::Constant(0.01);
      for (const double x : {b.lo.x(), b.hi.x()}) {
        s->Add(sim::MakeQuad({x, c.y(), c.z()}, Y, e.y(), Z, e.z(), 0.3f));
      }
      for (const double y : {b.lo.y(), b.hi.y()}) {
        s->Add(sim::MakeQuad({c.x(), y, c.z()}, X, e.x(), Z, e.z(), 0.3f));
      }
      for (const double z : {b.lo.z(), b.hi.z()}) {
        s->Add(sim::MakeQuad({c.x(), c.y(), z}, X, e.x(), Y, e.y(), 0.3f));
      }
    }
    s->Build();
    built_ = s;
    built_boxes_ = boxes.size();
  }

  mutable std::shared_ptr<const sim::Scene> built_;
  mutable size_t built_boxes_ = 0;
};

inline Scene MakeRoomScene() {
  Scene s;
  s.boxes.push_back({Eigen::Vector3d(-14, -10, -2.0), Eigen::Vector3d(14, 10, 4.0), true});
  s.boxes.push_back({Eigen::Vector3d(6, 4, -2.0), Eigen::Vector3d(7, 5, 4.0), false});
  s.boxes.push_back({Eigen::Vector3d(-8, -5, -2.0), Eigen::Vector3d(-6, -4, 1.0), false});
  s.boxes.push_back({Eigen::Vector3d(-2, 6, -2.0), Eigen::Vector3d(0.5, 7.5, 0.5), false});
  s.boxes.push_back({Eigen::Vector3d(3, -7, -2.0), Eigen::Vector3d(4.5, -6, 4.0), false});
  s.boxes.push_back({Eigen::Vector3d(-11, 3, -2.0), Eigen::Vector3d(-10, 8, 2.0), false});
  return s;
}

using PoseFn = std::function<Eigen::Isometry3d(double)>;  // T_world_imu(t)

// The angle of a rotation, degrees.
inline double Deg(const Eigen::Matrix3d& R) { return SO3Log(R).norm() * 180.0 / M_PI; }

// A pose from a position and a rotation vector.
inline Eigen::Isometry3d Pose(const Eigen::Vector3d& p, const Eigen::Vector3d& rotvec) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = SO3Exp(rotvec);
  T.translation() = p;
  return T;
}

inline Eigen::Isometry3d MakePose(const Eigen::Vector3d& p, double roll, double pitch,
                                  double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = p;
  return T;
}

// Static until t_start, then a smooth 3D wiggle inside MakeRoomScene (|v| up to ~2 m/s,
// yaw rate up to ~0.3 rad/s). The envelope makes velocity start at zero.
inline PoseFn WiggleTrajectory(double t_start) {
  return [t_start](double t) {
    const double tau = std::max(0.0, t - t_start);
    const double e = 1.0 - std::exp(-tau * tau);
    const Eigen::Vector3d p(e * 4.0 * std::sin(0.5 * tau), e * 2.5 * std::sin(0.7 * tau),
                            e * 0.3 * std::sin(0.9 * tau));
    return MakePose(p, e * 0.05 * std::sin(1.1 * tau), e * 0.05 * std::sin(0.9 * tau),
                    e * 0.6 * std::sin(0.4 * tau));
  };
}

// IMU sample from finite differences of the pose (h = 1e-3 s: errors ~1e-7, far below noise).
inline ImuSample ImuFromPose(const PoseFn& pose, double t, const Eigen::Vector3d& g = kGravity) {
  const double h = 1e-3;
  const Eigen::Isometry3d Tm = pose(t - h), T0 = pose(t), Tp = pose(t + h);
  ImuSample s;
  s.stamp_s = t;
  s.angular_velocity = ppf::SO3Log(Tm.linear().transpose() * Tp.linear()) / (2 * h);
  const Eigen::Vector3d acc_world =
      (Tp.translation() - 2.0 * T0.translation() + Tm.translation()) / (h * h);
  s.linear_acceleration = T0.linear().transpose() * (acc_world - g);
  return s;
}

// The pose trace the filter's IMU propagation gives from the true state at t0 to t_end, with
// 200 Hz noiseless IMU samples of `pose` (what de-skew uses).
inline PoseTrace TraceFromTruth(const PoseFn& pose, double t0, double t_end) {
  std::vector<ImuSample> imu;
  for (int i = 0; t0 - 0.03 + i / 200.0 <= t_end + 0.2; ++i) {
    imu.push_back(ImuFromPose(pose, t0 - 0.03 + i / 200.0));
  }
  NavState s;
  s.stamp_s = t0;
  s.R_world_imu = pose(t0).linear();
  s.p_world_imu = pose(t0).translation();
  s.v_world = (pose(t0 + 1e-4).translation() - pose(t0 - 1e-4).translation()) / 2e-4;
  s.gravity_world = kGravity;
  PoseTrace trace;
  PropagateImu(imu, t_end, 1.0, ImuNoise(), &s, &trace);
  return trace;
}

struct SimPoint {
  Eigen::Vector3f p;  // LiDAR frame at the point's own time
  double t = 0.0;     // absolute
};

struct LidarModel {
  int rings = 16;
  double min_elevation_deg = -15.0;
  double max_elevation_deg = 15.0;
  int azimuth_steps = 720;  // per revolution
  double period = 0.1;
  double range_noise = 0.0;  // metres, Gaussian
  double max_range = 100.0;
};

// One revolution starting at t0 (clockwise seen from above, starting at azimuth 0).
inline std::vector<SimPoint> SimulateScan(const Scene& scene, const PoseFn& T_world_imu,
                                          const Eigen::Isometry3d& T_imu_lidar, double t0,
                                          const LidarModel& m, std::mt19937* rng = nullptr) {
  std::vector<SimPoint> out;
  std::normal_distribution<double> noise(0.0, m.range_noise);
  for (int k = 0; k < m.azimuth_steps; ++k) {
    const double t = t0 + m.period * k / m.azimuth_steps;
    const Eigen::Isometry3d T_world_lidar = T_world_imu(t) * T_imu_lidar;
    const double az = -2.0 * kPi * k / m.azimuth_steps;
    for (int r = 0; r < m.rings; ++r) {
      const double el = (m.min_elevation_deg + (m.max_elevation_deg - m.min_elevation_deg) * r /
                                                   std::max(1, m.rings - 1)) *
                        kPi / 180.0;
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                              std::sin(el));
      double range = scene.Raycast(T_world_lidar.translation(), T_world_lidar.linear() * d);
      if (!(range < m.max_range)) continue;
      if (rng && m.range_noise > 0.0) range += noise(*rng);
      out.push_back({(range * d).cast<float>(), t});
    }
  }
  return out;
}

// How the per-point time is written into the cloud.
struct TimeEncoding {
  std::string name = "time";         // "" = no time field
  FieldType type = FieldType::kFloat32;
  double unit_s = 1.0;               // seconds per stored unit (1e-9 for uint32 ns)
  bool absolute = false;
  bool stamp_at_end = false;         // header stamp = scan end
  bool relative_to_end = false;      // stored values are t - t_end (<= 0), else t - t_begin
};

struct CloudBuffer {
  std::vector<uint8_t> bytes;
  CloudView view;
};

inline CloudBuffer MakeCloud(const std::vector<SimPoint>& pts, double t_begin, double t_end,
                             const TimeEncoding& enc) {
  CloudBuffer c;
  CloudView& v = c.view;
  v.stamp_s = enc.stamp_at_end ? t_end : t_begin;
  v.frame_id = "lidar";
  v.fields = {{"x", 0, FieldType::kFloat32, 1},
              {"y", 4, FieldType::kFloat32, 1},
              {"z", 8, FieldType::kFloat32, 1},
              {"intensity", 12, FieldType::kFloat32, 1}};
  uint32_t step = 16;
  if (!enc.name.empty()) {
    v.fields.push_back({enc.name, 16, enc.type, 1});
    step = 16 + static_cast<uint32_t>(std::max<size_t>(4, FieldTypeSize(enc.type)));
    step = (step + 7) / 8 * 8;
  }
  v.point_step = step;
  v.width = static_cast<uint32_t>(pts.size());
  v.height = 1;
  v.row_step = step * v.width;
  c.bytes.assign(static_cast<size_t>(v.row_step), 0);
  for (size_t i = 0; i < pts.size(); ++i) {
    uint8_t* p = c.bytes.data() + i * step;
    const float xyz[4] = {pts[i].p.x(), pts[i].p.y(), pts[i].p.z(), 1.0f};
    std::memcpy(p, xyz, sizeof(xyz));
    if (enc.name.empty()) continue;
    // Relative values are offsets from the first point (>= 0) unless relative_to_end (<= 0).
    double value = enc.absolute          ? pts[i].t
                   : enc.relative_to_end ? pts[i].t - t_end
                                         : pts[i].t - t_begin;
    value /= enc.unit_s;
    switch (enc.type) {
      case FieldType::kFloat32: {
        const float f = static_cast<float>(value);
        std::memcpy(p + 16, &f, 4);
        break;
      }
      case FieldType::kFloat64:
        std::memcpy(p + 16, &value, 8);
        break;
      case FieldType::kUint32: {
        const uint32_t u = static_cast<uint32_t>(std::llround(value));
        std::memcpy(p + 16, &u, 4);
        break;
      }
      case FieldType::kInt32: {
        const int32_t v32 = static_cast<int32_t>(std::llround(value));
        std::memcpy(p + 16, &v32, 4);
        break;
      }
      default:
        break;
    }
  }
  v.data = c.bytes.data();
  v.size = c.bytes.size();
  return c;
}

}  // namespace ppf::test
