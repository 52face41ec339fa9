#include "ppf_tools/endurance.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

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

namespace {

// The world, its IMU stream (a few MB for 10 minutes) and the scan generator, made before the
// drive so that the memory measured during the drive is the core's.
struct Drive {
  explicit Drive(const EnduranceOptions& options)
      : world(MakeWorld(options)),
        model(sim::GetLidarModel(options.lidar)),
        imu(sim::SimulateImu(world.trajectory, 200.0, options.duration, sim::ImuNoise(),
                             options.seed)),
        scan_options(MakeScanOptions(options)),
        start_s(static_cast<double>(scan_options.start_ns) * 1e-9),
        gen(world.scene, world.trajectory, model, scan_options),
        n_scans(gen.NumScans(options.duration)) {}

  static sim::World MakeWorld(const EnduranceOptions& options) {
    sim::WorldOptions wo;
    wo.scene = options.scene;
    wo.duration = options.duration;
    wo.seed = options.seed;
    wo.roam_radius = options.roam_radius;
    return sim::BuildWorld(wo);
  }
  static sim::ScanOptions MakeScanOptions(const EnduranceOptions& options) {
    sim::ScanOptions so;
    so.seed = options.seed;
    so.T_imu_lidar = sim::DefaultImuLidarExtrinsic();
    so.start_ns = 1700000000LL * 1000000000LL;
    return so;
  }

  // Feeds `lio` the IMU samples stamped up to end_ns (all that remain if end_ns < 0).
  void FeedImuUntil(int64_t end_ns, LioPpf* lio) {
    for (; next_imu < imu.size(); ++next_imu) {
      const int64_t stamp_ns =
          scan_options.start_ns + static_cast<int64_t>(std::llround(imu[next_imu].t * 1e9));
      if (end_ns >= 0 && stamp_ns > end_ns) break;
      ImuSample s;
      s.stamp_s = end_ns >= 0 ? static_cast<double>(stamp_ns) * 1e-9 : start_s + imu[next_imu].t;
      s.angular_velocity = imu[next_imu].gyro;
      s.linear_acceleration = imu[next_imu].accel;
      lio->AddImu(s);
    }
  }

  const sim::World world;
  const sim::LidarModel model;
  const std::vector<sim::ImuMeasurement> imu;
  const sim::ScanOptions scan_options;
  const double start_s;
  const sim::ScanGenerator gen;
  const int n_scans;
  size_t next_imu = 0;
};

// SE(3)- and position+yaw-aligned APE of the trajectory so far.
void Score(const Trajectory& gt, const Trajectory& est, double tilt_after, EvalResult* se3,
           EvalResult* posyaw) {
  EvalOptions eval;
  eval.align = Alignment::kSE3;
  eval.tilt_after_s = tilt_after;
  *se3 = ComputeApe(gt, est, eval);
  eval.align = Alignment::kPosYaw;
  *posyaw = ComputeApe(gt, est, eval);
}

// What the drive's results add up to: the report's counts and halves, the trajectories, and a
// progress row every report_every s of simulated time.
class Tally {
 public:
  Tally(const EnduranceOptions& options, const Drive& drive, const LioPpf& lio,
        EnduranceReport* rep, std::function<void(const EnduranceRow&)> on_row,
        Clock::time_point t_start)
      : options_(options),
        drive_(drive),
        lio_(lio),
        rep_(rep),
        on_row_(std::move(on_row)),
        t_start_(t_start),
        p0_(drive.world.trajectory.Pose(0.0).translation()),
        anchor_(p0_),
        prev_p_(p0_),
        next_report_(options.report_every) {
    est_.reserve(drive.n_scans);
    gt_.reserve(drive.n_scans);
  }

  void Add(const std::vector<ScanResult>& batch) {
    for (const ScanResult& r : batch) Add(r);
  }
  const Trajectory& gt() const { return gt_; }
  const Trajectory& est() const { return est_; }

 private:
  void Add(const ScanResult& r) {
    EnduranceReport& rep = *rep_;
    ++rep.scans;
    rep.resets += r.status == Status::kReset;
    rep.rejected += r.status == Status::kRejected;
    rep.degenerate += r.status == Status::kDegenerate;
    const double t = r.stamp_s - drive_.start_s;
    const sim::Trajectory& traj = drive_.world.trajectory;
    const Eigen::Isometry3d T_gt = traj.Pose(std::min(t, traj.end_time()));
    AddDistance(T_gt.translation());
    const size_t voxels = lio_.map_stats().voxels;
    const double rss = CurrentRssMb();
    if (t < 0.5 * options_.duration) {
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
    max_map_ = std::max(max_map_, r.map_size);
    if (r.pose_valid) {
      ++rep.posed;
      est_.push_back({r.stamp_s, r.T_world_imu});
      gt_.push_back({r.stamp_s, T_gt});
    }
    if (t + 1e-6 >= next_report_ || rep.scans == static_cast<size_t>(drive_.n_scans)) {
      AddRow(t, r, voxels, rss);
      while (next_report_ <= t + 1e-6) next_report_ += options_.report_every;
    }
  }

  void AddDistance(const Eigen::Vector3d& p) {
    EnduranceReport& rep = *rep_;
    rep.distance += (p - prev_p_).norm();
    prev_p_ = p;
    rep.max_distance_from_start = std::max(rep.max_distance_from_start, (p - p0_).norm());
    if (rep.map_radius > 0 && (p - anchor_).norm() > rep.map_radius) {
      ++rep.radius_crossings;
      anchor_ = p;
    }
  }

  void AddRow(double t, const ScanResult& r, size_t voxels, double rss) {
    EnduranceRow row;
    row.sim_time = t;
    row.distance = rep_->distance;
    row.map_points = r.map_size;
    row.map_voxels = voxels;
    row.max_map_points = max_map_;
    row.patches = r.skeleton_patches;
    row.rss_mb = rss;
    EvalResult ape, ape_posyaw;
    Score(gt_, est_, options_.tilt_after, &ape, &ape_posyaw);
    row.ape_rmse = ape.ok ? ape.stats.rmse : -1.0;
    row.ape_posyaw_rmse = ape_posyaw.ok ? ape_posyaw.stats.rmse : -1.0;
    if (ape.gravity.ok) {
      row.tilt_max_deg = ape.gravity.tilt.count > 0 ? ape.gravity.tilt.max : -1.0;
      row.dz_m = ape.gravity.final_dz_m;
    }
    row.wall_s = Since(t_start_);
    row.scans = rep_->scans;
    row.posed = rep_->posed;
    rep_->rows.push_back(row);
    if (on_row_) on_row_(row);
  }

  const EnduranceOptions& options_;
  const Drive& drive_;
  const LioPpf& lio_;
  EnduranceReport* rep_;
  std::function<void(const EnduranceRow&)> on_row_;
  Clock::time_point t_start_;
  Trajectory est_, gt_;
  Eigen::Vector3d p0_, anchor_, prev_p_;
  double next_report_;
  size_t max_map_ = 0;
};

}  // namespace

EnduranceReport RunEndurance(const EnduranceOptions& options, const Config& config_in,
                             const std::function<void(const EnduranceRow&)>& on_row) {
  const auto t_start = Clock::now();
  EnduranceReport rep;
  Drive drive(options);
  rep.sim_wall_s = Since(t_start);

  Config config = config_in;
  config.extrinsic.T_imu_lidar = drive.scan_options.T_imu_lidar;
  LioPpf lio(config);
  rep.map_radius = config.map.radius;
  rep.map_capacity_points = lio.map_stats().capacity_points;
  rep.rss_start_mb = CurrentRssMb();
  Tally tally(options, drive, lio, &rep, on_row, t_start);

  const int64_t period_ns = static_cast<int64_t>(std::llround(drive.gen.period() * 1e9));
  for (int k = 0; k < drive.n_scans; ++k) {
    auto t0 = Clock::now();
    const sim::CloudBuffer cloud = drive.gen.Generate(k);
    // What a driver delivers by the scan end: the IMU up to then, then the sweep.
    drive.FeedImuUntil(drive.scan_options.start_ns + static_cast<int64_t>(k + 1) * period_ns,
                       &lio);
    rep.sim_wall_s += Since(t0);
    lio.AddScan(ToView(cloud));
    tally.Add(lio.Process());
  }
  drive.FeedImuUntil(-1, &lio);
  tally.Add(lio.Process(/*flush=*/true));
  rep.rss_end_mb = CurrentRssMb();

  Score(tally.gt(), tally.est(), options.tilt_after, &rep.ape, &rep.ape_posyaw);
  rep.gravity = rep.ape.gravity;
  rep.path_length = PathLength(tally.gt());
  rep.wall_s = Since(t_start);
  return rep;
}

}  // namespace ppf::tools
