#include "ppf_sim/simulation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "ppf_trajectory/trajectory_io.hpp"

namespace ppf::sim {

namespace {

double Since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string Vec(const double* v, int n, int prec = 9) {
  std::ostringstream s;
  s << std::setprecision(prec) << "[";
  for (int i = 0; i < n; ++i) s << (i ? ", " : "") << v[i];
  s << "]";
  return s.str();
}

// The IMU's stamp in the bag (ns): the simulation's start plus the sample's time.
int64_t ImuStamp(const SimConfig& cfg, const ImuMeasurement& m) {
  return cfg.start_ns + static_cast<int64_t>(std::llround(m.t * 1e9));
}

// Ground truth: the IMU (body) frame in the gravity-aligned world frame, at every IMU sample;
// the biases the IMU simulation drew, at the same stamps.
void WriteGroundTruth(const SimConfig& cfg, const World& world,
                      const std::vector<ImuMeasurement>& imu) {
  auto imu_stamp = [&](size_t i) { return ImuStamp(cfg, imu[i]); };
  TumWriter gt(
      cfg.out_dir + "/groundtruth.tum",
      "timestamp tx ty tz qx qy qz qw: T_world_imu (IMU/body frame in the gravity-aligned "
      "world frame, z up), at every IMU sample");
  std::ofstream bias(cfg.out_dir + "/imu_bias.csv");
  bias << "t,bgx,bgy,bgz,bax,bay,baz\n" << std::setprecision(12);
  for (size_t i = 0; i < imu.size(); ++i) {
    gt.Write(imu_stamp(i), world.trajectory.Pose(imu[i].t));
    const int64_t s = imu_stamp(i);
    bias << s / 1000000000LL << "." << std::setw(9) << std::setfill('0') << s % 1000000000LL
         << std::setfill(' ') << std::setw(0);
    for (int k = 0; k < 3; ++k) bias << "," << imu[i].gyro_bias[k];
    for (int k = 0; k < 3; ++k) bias << "," << imu[i].accel_bias[k];
    bias << "\n";
  }
}

// calibration.yaml: T_imu_lidar in the core config's keys, to layer over a preset.
void WriteCalibration(const SimConfig& cfg, const ScanOptions& so) {
  const Eigen::Isometry3d& T = so.T_imu_lidar;
  const Eigen::Quaterniond q(T.linear());
  const double t[3] = {T.translation().x(), T.translation().y(), T.translation().z()};
  const double qw[4] = {q.w(), q.x(), q.y(), q.z()};
  const Eigen::Matrix3d& R = T.linear();
  const double e[3] = {std::atan2(R(1, 0), R(0, 0)) * 180 / M_PI,
                       -std::asin(std::clamp(R(2, 0), -1.0, 1.0)) * 180 / M_PI,
                       std::atan2(R(2, 1), R(2, 2)) * 180 / M_PI};  // yaw, pitch, roll
  std::ofstream cal(cfg.out_dir + "/calibration.yaml");
  cal << std::setprecision(12);
  cal << "# ppf_sim calibration. Transforms are named T_<to>_<from>: p_to = T_to_from * p_from.\n"
      << "# Same keys as the LIO-PPF config (config/*.yaml): layer this file after a preset\n"
      << "# (ppf_offline --config preset.yaml --config calibration.yaml). What else describes\n"
      << "# the sequence is in sequence.yaml.\n"
      << "extrinsic:\n"
      << "  T_imu_lidar:\n"
      << "    translation: " << Vec(t, 3) << "\n"
      << "    quaternion_wxyz: " << Vec(qw, 4, 15) << "\n"
      << "    # same rotation as rpy_deg [roll, pitch, yaw] (R = Rz Ry Rx): [" << e[2] << ", "
      << e[1] << ", " << e[0] << "]\n";
  if (cfg.disturbances.gyro_range > 0.0) {
    // The IMU's datasheet full scale, as a user would configure it.
    cal << "imu:\n  noise:\n    gyro_range: " << cfg.disturbances.gyro_range << "\n";
  }
}

// sequence.yaml: sensors, noise, ground truth and scenario of the sequence.
void WriteSequenceInfo(const SimConfig& cfg, const ScanOptions& so, const LidarModel& model,
                       const World& world) {
  std::ofstream info(cfg.out_dir + "/sequence.yaml");
  info << std::setprecision(12);
  info << "# ppf_sim sequence description: sensors, noise, ground truth, scenario.\n"
      << "lidar:\n"
      << "  model: " << model.name << "\n"
      << "  frame_id: " << so.frame_id << "\n"
      << "  topic: " << cfg.bag.points_topic << "\n"
      << "  rate_hz: " << model.rate_hz << "\n"
      << "  beams: " << model.elevation_deg.size() << "\n"
      << "  columns: " << model.columns << "\n"
      << "  max_range: " << (so.max_range > 0 ? so.max_range : model.max_range) << "\n"
      << "  point_layout: "
      << (model.layout == PointLayout::kVelodyne
              ? (so.time_field == ScanOptions::TimeField::kNone
                     ? "velodyne without per-point time (x y z intensity f32, ring u16)"
                 : so.time_field == ScanOptions::TimeField::kAbsoluteF64
                     ? "velodyne with absolute time (x y z intensity f32, ring u16, timestamp "
                       "f64 s since the epoch)"
                     : "velodyne (x y z intensity f32, ring u16, time f32 s from the header "
                       "stamp)")
              : "ouster (x y z intensity f32, t u32 ns from scan start, reflectivity u16, "
                "ring u16, ambient u16, range u32 mm; organized)")
      << "\n"
      << "  header_stamp: " << (so.stamp_at_end ? "scan_end" : "scan_start") << "\n"
      << "  spin: clockwise seen from above, first column behind the sensor (azimuth +180 deg)\n"
      << "  range_noise_std: " << so.range_noise << "\n"
      << "imu:\n"
      << "  frame_id: " << cfg.imu_frame << "\n"
      << "  topic: " << cfg.bag.imu_topic << "\n"
      << "  rate_hz: " << cfg.imu_rate << "\n"
      << "  gravity: " << cfg.gravity << "\n"
      << "  gyro_noise: " << cfg.imu_noise.gyro_noise << "        # rad/s/sqrt(Hz)\n"
      << "  acc_noise: " << cfg.imu_noise.accel_noise << "        # m/s^2/sqrt(Hz)\n"
      << "  gyro_bias_noise: " << cfg.imu_noise.gyro_bias_rw << "  # rad/s^2/sqrt(Hz)\n"
      << "  acc_bias_noise: " << cfg.imu_noise.accel_bias_rw << "   # m/s^3/sqrt(Hz)\n"
      << "  gyro_bias_init_std: " << cfg.imu_noise.gyro_bias_init << "\n"
      << "  acc_bias_init_std: " << cfg.imu_noise.accel_bias_init << "\n"
      << "groundtruth:\n"
      << "  file: groundtruth.tum\n"
      << "  frame: T_world_imu (IMU/body frame in the gravity-aligned world frame, z up)\n"
      << "  biases: imu_bias.csv\n"
      << "sequence:\n"
      << "  scene: " << cfg.world.scene << "\n"
      << "  motion: " << (world.motion == MotionKind::kCar ? "car" : "handheld") << "\n"
      << "  speed: " << world.speed << "\n"
      << "  duration: " << cfg.world.duration << "\n"
      << "  static_time: " << (cfg.world.moving_start ? 0.0 : cfg.world.static_time) << "\n"
      << "  moving_start: " << (cfg.world.moving_start ? "true" : "false") << "\n"
      << "  moving_start_offset: " << world.start_offset
      << "  # s of the planned motion before time 0\n"
      << "  seed: " << cfg.seed << "\n"
      << "  start_time_ns: " << cfg.start_ns << "\n";
  const Disturbances& d = cfg.disturbances;
  if (!d.any()) return;
  info << "disturbances:  # not in the IMU's or the LiDAR's data model; ground truth has them\n";
  for (const Jolt& j : d.jolts) {
    info << "  - {jolt_t: " << j.t << ", yaw_deg: " << j.yaw_rad * 180.0 / M_PI
         << ", dx_m: " << j.dx_m << "}\n";
  }
  for (const TimeWindow& w : d.imu_gaps) {
    info << "  - {imu_gap_t: " << w.t << ", length_s: " << w.length << "}\n";
  }
  for (const TimeWindow& w : d.silences) {
    info << "  - {silence_t: " << w.t << ", length_s: " << w.length << "}\n";
  }
  if (d.gyro_range > 0.0) info << "  - {gyro_range_rad_s: " << d.gyro_range << "}\n";
}

}  // namespace

SimConfig::SimConfig() { scan.T_imu_lidar = DefaultImuLidarExtrinsic(); }

SimSummary RunSimulation(const SimConfig& cfg, std::ostream& log) {
  SimSummary sum;
  const auto t_start = std::chrono::steady_clock::now();
  auto t0 = std::chrono::steady_clock::now();
  WorldOptions wo = cfg.world;
  wo.seed = cfg.seed;
  World world = BuildWorld(wo);
  world.trajectory.SetJolts(cfg.disturbances.jolts);
  sum.seconds_world = Since(t0);

  t0 = std::chrono::steady_clock::now();
  std::vector<ImuMeasurement> imu =
      SimulateImu(world.trajectory, cfg.imu_rate, cfg.world.duration, cfg.imu_noise, cfg.seed,
                  cfg.gravity);
  const Disturbances& dist = cfg.disturbances;
  if (dist.gyro_range > 0.0) {
    for (ImuMeasurement& m : imu) {
      for (int k = 0; k < 3; ++k) m.gyro[k] = std::clamp(m.gyro[k], -dist.gyro_range, dist.gyro_range);
    }
  }
  auto imu_dropped = [&](double t) {
    for (const TimeWindow& w : dist.imu_gaps)
      if (w.Contains(t)) return true;
    for (const TimeWindow& w : dist.silences)
      if (w.Contains(t)) return true;
    return false;
  };
  sum.seconds_imu = Since(t0);
  sum.imu_samples = static_cast<int>(imu.size());

  ScanOptions so = cfg.scan;
  so.seed = cfg.seed;
  so.start_ns = cfg.start_ns;
  const LidarModel model = GetLidarModel(cfg.lidar);
  ScanGenerator gen(world.scene, world.trajectory, model, so);
  const int n_scans = gen.NumScans(cfg.world.duration);
  const int64_t period_ns = static_cast<int64_t>(std::llround(gen.period() * 1e9));

  BagOutput bag(cfg.out_dir, cfg.bag);
  auto imu_stamp = [&](size_t i) { return ImuStamp(cfg, imu[i]); };
  ImuMessage im;
  im.frame_id = cfg.imu_frame;
  im.gyro_var = cfg.imu_noise.gyro_noise * cfg.imu_noise.gyro_noise * cfg.imu_rate;
  im.accel_var = cfg.imu_noise.accel_noise * cfg.imu_noise.accel_noise * cfg.imu_rate;
  size_t next_imu = 0;
  auto flush_imu = [&](int64_t until_ns) {
    for (; next_imu < imu.size() && imu_stamp(next_imu) <= until_ns; ++next_imu) {
      if (imu_dropped(imu[next_imu].t)) continue;
      im.stamp_ns = imu_stamp(next_imu);
      for (int k = 0; k < 3; ++k) {
        im.gyro[k] = imu[next_imu].gyro[k];
        im.accel[k] = imu[next_imu].accel[k];
      }
      bag.WriteImu(im, im.stamp_ns);
    }
  };
  for (int k = 0; k < n_scans; ++k) {
    bool silent = false;
    for (const TimeWindow& w : dist.silences) silent |= w.Overlaps(k * gen.period(), (k + 1) * gen.period());
    if (silent) continue;
    t0 = std::chrono::steady_clock::now();
    const CloudBuffer cloud = gen.Generate(k);
    sum.seconds_scans += Since(t0);
    t0 = std::chrono::steady_clock::now();
    // A driver publishes a sweep when it is complete: the bag time is the scan end.
    const int64_t bag_time = cfg.start_ns + static_cast<int64_t>(k + 1) * period_ns;
    flush_imu(bag_time);
    bag.WriteCloud(cloud, bag_time);
    sum.seconds_write += Since(t0);
    sum.points += cloud.num_points();
    ++sum.scans;
    if ((k + 1) % 100 == 0 || k + 1 == n_scans) {
      log << "  scan " << (k + 1) << "/" << n_scans << "\n" << std::flush;
    }
  }
  t0 = std::chrono::steady_clock::now();
  flush_imu(INT64_MAX);
  bag.Close();
  sum.seconds_write += Since(t0);
  sum.bytes = bag.bytes();

  WriteGroundTruth(cfg, world, imu);
  WriteCalibration(cfg, so);
  WriteSequenceInfo(cfg, so, model, world);
  sum.seconds_total = Since(t_start);
  return sum;
}

}  // namespace ppf::sim
