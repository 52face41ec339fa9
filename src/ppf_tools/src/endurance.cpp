#include "ppf_tools/endurance.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "ppf_sim/cloud_buffer.hpp"
#include "ppf_sim/imu_simulator.hpp"
#include "ppf_sim/lidar_model.hpp"
#include "ppf_sim/scan_generator.hpp"
#include "ppf_sim/world.hpp"

namespace ppf::tools {

namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// The generator's buffer as the core's view (same PointCloud2 layout, no copy).
CloudView ToView(const sim::CloudBuffer& c) {
  CloudView v;
  v.stamp_s = static_cast<double>(c.stamp_ns) * 1e-9;
  v.frame_id = c.frame_id;
  v.height = c.height;
  v.width = c.width;
  v.point_step = c.point_step;
  v.row_step = c.row_step;
  v.is_bigendian = c.is_bigendian;
  for (const auto& f : c.fields) {
    v.fields.push_back({f.name, f.offset, static_cast<FieldType>(f.datatype), f.count});
  }
  v.data = c.data.data();
  v.size = c.data.size();
  return v;
}

}  // namespace

double CurrentRssMb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;  // kB
  }
  return 0.0;
}

EnduranceReport RunEndurance(const EnduranceOptions& options, const Config& config_in,
                             const std::function<void(const EnduranceRow&)>& on_row) {
  const auto t_start = Clock::now();
  EnduranceReport rep;

  // The world and its IMU stream (a few MB for 10 minutes), made before the drive so that the
  // memory measured during the drive is the core's.
  sim::WorldOptions wo;
  wo.scene = options.scene;
  wo.duration = options.duration;
  wo.seed = options.seed;
  wo.roam_radius = options.roam_radius;
  const sim::World world = sim::BuildWorld(wo);
  const sim::LidarModel model = sim::GetLidarModel(options.lidar);
  const double imu_rate = 200.0;
  const sim::ImuNoise noise;
  const std::vector<sim::ImuMeasurement> imu =
      sim::SimulateImu(world.trajectory, imu_rate, options.duration, noise, options.seed);
  sim::ScanOptions so;
  so.seed = options.seed;
  so.T_imu_lidar = sim::DefaultImuLidarExtrinsic();
  so.start_ns = 1700000000LL * 1000000000LL;
  const double start_s = static_cast<double>(so.start_ns) * 1e-9;
  const sim::ScanGenerator gen(world.scene, world.trajectory, model, so);
  const int n_scans = gen.NumScans(options.duration);
  rep.sim_wall_s = Since(t_start);

  Config config = config_in;
  config.T_imu_lidar = so.T_imu_lidar;
  LioPpf lio(config);
  rep.map_radius = config.map_radius;
  rep.map_capacity_points = lio.map().capacity_points();

  Trajectory est, gt;
  est.reserve(n_scans);
  gt.reserve(n_scans);
  const Eigen::Vector3d p0 = world.trajectory.Pose(0.0).translation();
  Eigen::Vector3d anchor = p0, prev_p = p0;
  const double half = 0.5 * options.duration;
  double next_report = options.report_every;
  size_t max_map = 0;
  rep.rss_start_mb = CurrentRssMb();

  auto consume = [&](std::vector<ScanResult>&& batch) {
    for (const ScanResult& r : batch) {
      ++rep.scans;
      rep.resets += r.status == Status::kReset;
      rep.rejected += r.status == Status::kRejected;
      rep.degenerate += r.status == Status::kDegenerate;
      const double t = r.stamp_s - start_s;
      const Eigen::Isometry3d T_gt =
          world.trajectory.Pose(std::min(t, world.trajectory.end_time()));
      const Eigen::Vector3d p = T_gt.translation();
      rep.distance += (p - prev_p).norm();
      prev_p = p;
      rep.max_distance_from_start = std::max(rep.max_distance_from_start, (p - p0).norm());
      if (rep.map_radius > 0 && (p - anchor).norm() > rep.map_radius) {
        ++rep.radius_crossings;
        anchor = p;
      }
      const size_t voxels = lio.map().num_voxels();
      const double rss = CurrentRssMb();
      const bool second = t >= half;
      if (!second) {
        rep.max_map_first_half = std::max(rep.max_map_first_half, r.map_size);
        rep.max_voxels_first_half = std::max(rep.max_voxels_first_half, voxels);
        rep.max_patches_first_half = std::max(rep.max_patches_first_half, r.skeleton_patches);
        rep.rss_half_mb = rss;  // the last value before the second half starts
      } else {
        rep.max_map_second_half = std::max(rep.max_map_second_half, r.map_size);
        rep.max_voxels_second_half = std::max(rep.max_voxels_second_half, voxels);
        rep.max_patches_second_half = std::max(rep.max_patches_second_half, r.skeleton_patches);
        rep.rss_max_second_half_mb = std::max(rep.rss_max_second_half_mb, rss);
      }
      max_map = std::max(max_map, r.map_size);
      if (r.pose_valid) {
        ++rep.posed;
        est.push_back({r.stamp_s, r.T_world_imu});
        gt.push_back({r.stamp_s, T_gt});
      }
      if (t + 1e-6 >= next_report || rep.scans == static_cast<size_t>(n_scans)) {
        EnduranceRow row;
        row.sim_time = t;
        row.distance = rep.distance;
        row.map_points = r.map_size;
        row.map_voxels = voxels;
        row.max_map_points = max_map;
        row.patches = r.skeleton_patches;
        row.rss_mb = rss;
        EvalOptions eval;
        eval.align = Alignment::kSE3;
        eval.tilt_after_s = options.tilt_after;
        const EvalResult ape = ComputeApe(gt, est, eval);
        row.ape_rmse = ape.ok ? ape.stats.rmse : -1.0;
        eval.align = Alignment::kPosYaw;
        const EvalResult ape_posyaw = ComputeApe(gt, est, eval);
        row.ape_posyaw_rmse = ape_posyaw.ok ? ape_posyaw.stats.rmse : -1.0;
        if (ape.gravity.ok) {
          row.tilt_max_deg = ape.gravity.tilt.count > 0 ? ape.gravity.tilt.max : -1.0;
          row.dz_m = ape.gravity.final_dz_m;
        }
        row.wall_s = Since(t_start);
        row.scans = rep.scans;
        row.posed = rep.posed;
        rep.rows.push_back(row);
        if (on_row) on_row(row);
        while (next_report <= t + 1e-6) next_report += options.report_every;
      }
    }
  };

  const int64_t period_ns = static_cast<int64_t>(std::llround(gen.period() * 1e9));
  size_t next_imu = 0;
  for (int k = 0; k < n_scans; ++k) {
    auto t0 = Clock::now();
    const sim::CloudBuffer cloud = gen.Generate(k);
    // What a driver delivers by the scan end: the IMU up to then, then the sweep.
    const int64_t scan_end_ns = so.start_ns + static_cast<int64_t>(k + 1) * period_ns;
    for (; next_imu < imu.size(); ++next_imu) {
      const int64_t stamp_ns =
          so.start_ns + static_cast<int64_t>(std::llround(imu[next_imu].t * 1e9));
      if (stamp_ns > scan_end_ns) break;
      ImuSample s;
      s.stamp_s = static_cast<double>(stamp_ns) * 1e-9;
      s.angular_velocity = imu[next_imu].gyro;
      s.linear_acceleration = imu[next_imu].accel;
      lio.AddImu(s);
    }
    rep.sim_wall_s += Since(t0);
    lio.AddScan(ToView(cloud));
    consume(lio.Process());
  }
  for (; next_imu < imu.size(); ++next_imu) {
    ImuSample s;
    s.stamp_s = start_s + imu[next_imu].t;
    s.angular_velocity = imu[next_imu].gyro;
    s.linear_acceleration = imu[next_imu].accel;
    lio.AddImu(s);
  }
  consume(lio.Process(/*flush=*/true));
  rep.rss_end_mb = CurrentRssMb();

  EvalOptions eval;
  eval.align = Alignment::kSE3;
  eval.tilt_after_s = options.tilt_after;
  rep.ape = ComputeApe(gt, est, eval);
  rep.gravity = rep.ape.gravity;
  eval.align = Alignment::kPosYaw;
  rep.ape_posyaw = ComputeApe(gt, est, eval);
  rep.path_length = PathLength(gt);
  rep.wall_s = Since(t_start);
  return rep;
}

}  // namespace ppf::tools
