// ppf_sim: deterministic LiDAR-inertial sequence generator writing a rosbag2 directory.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "cli_args.hpp"
#include "ppf_sim/simulation.hpp"

namespace {

const char* kHelp = R"(usage: ppf_sim --out DIR [options]

Generates a deterministic (seeded) LiDAR-inertial sequence with exact ground truth and writes
DIR as a rosbag2 directory (metadata.yaml + one .mcap or .db3 file) with
  /points  sensor_msgs/msg/PointCloud2   one message per 10 Hz sweep
  /imu     sensor_msgs/msg/Imu           --imu-rate Hz
plus DIR/groundtruth.tum, DIR/calibration.yaml, DIR/sequence.yaml and DIR/imu_bias.csv.

Time conventions
  PointCloud2 header.stamp = scan START time (time of the first firing). Per-point time is
  relative to that stamp: velodyne models `time` float32 seconds, ouster models `t` uint32 ns.
  (--stamp end / --time-field change this on purpose, for testing the core's detection.)
  The bag (receive) time of a cloud is the scan END (when a driver publishes it); IMU bag time
  = its stamp. The sensor pose is evaluated at each firing time (motion distortion is real).
  Sim time 0 = --start-time; the platform is static for --static seconds at the start
  (or already moving with --moving-start).
Frames
  groundtruth.tum: T_world_imu, the IMU/body frame in the gravity-aligned world frame (z up),
  one line per IMU sample ("t x y z qx qy qz qw"). calibration.yaml: T_imu_lidar
  (p_imu = T_imu_lidar * p_lidar), with the same keys as the LIO-PPF config.

Options
  --out DIR             output bag directory (must not exist or be empty)       [required]
  --scene NAME          urban | indoor | park | ramps                              [urban]
  --lidar NAME          vlp16 | hdl32 | hdl64 | os1_64 | os1_128                   [hdl64]
  --duration S          sequence length in seconds                                 [30]
  --seed N              random seed: same seed and options -> identical bytes      [1]
  --storage S           mcap | sqlite3                                             [mcap]
  --compression C       mcap chunk compression: none | lz4 | zstd                  [none]
  --motion M            car | handheld (default: handheld indoors, car elsewhere)
  --speed V             m/s (default: car 10 urban, 8 ramps, 5 park; handheld 1.3)
  --static S            seconds at rest at the start (>= 2 for LIO initialization) [2.5]
  --moving-start        no rest: the first scan and IMU sample are already at cruise speed
                        and turning as the drive does (sim time 0 is a point past the
                        acceleration of the planned motion; excludes --static)
  --max-rate DEG        hand-held shake peak angular rate, deg/s (turns add)       [150]
  --range-noise M       LiDAR range noise, 1 sigma, metres                         [0.02]
  --dropout P           probability that a return is lost at random                [0.005]
  --max-range M         override the model's maximum range
  --imu-rate HZ         IMU rate, 50..1000                                         [200]
  --gyro-noise D        gyro white noise density, rad/s/sqrt(Hz)                   [2e-4]
  --accel-noise D       accel white noise density, m/s^2/sqrt(Hz)                  [2e-3]
  --gyro-bias-rw D      gyro bias random walk, rad/s^2/sqrt(Hz)                    [2e-5]
  --accel-bias-rw D     accel bias random walk, m/s^3/sqrt(Hz)                     [3e-4]
  --gyro-bias-init S    std of the turn-on gyro bias, rad/s                        [2e-3]
  --accel-bias-init S   std of the turn-on accel bias, m/s^2                       [3e-2]
  --no-imu-noise        all IMU noise and biases zero
  --gravity G           m/s^2                                                      [9.81]
  --extrinsic X,Y,Z,R,P,Y   T_imu_lidar: translation (m) and roll,pitch,yaw (deg, R = Rz Ry Rx)
                        [0.2,0.05,0.15,1.0,-1.5,2.0]
  --start-time S        absolute time of sim time 0, seconds since the epoch      [1700000000]
  --time-field T        velodyne models only, other drivers' conventions for testing time
                        detection: driver (`time` f32 s) | none (no per-point time) |
                        abs_f64 (`timestamp` f64 absolute seconds, Hesai-style)    [driver]
  --stamp S             velodyne models only: start | end. `end` puts header.stamp at the
                        scan end (ROS 1 velodyne style; relative times negative)   [start]
  --lidar-frame F       PointCloud2 frame_id                                       [lidar]
  --imu-frame F         Imu frame_id                                               [imu]
  --points-topic T      [/points]      --imu-topic T   [/imu]

Disturbances (faults the filter's models do not contain; ground truth has them exactly, and
sequence.yaml lists them; each option takes a comma-separated list):
  --jolt T:YAW_DEG[:DX_M]   at sim time T the true path steps: the rest of it turns by YAW_DEG
                        about the vertical through the position at T and moves DX_M along the
                        heading. No IMU sample contains the step (a saturated gyro on a bump,
                        a packet lost in a turn, a slipping mount).
  --imu-gap T:S         no IMU sample in [T, T+S) (the LiDAR goes on)
  --silence T:S         neither IMU samples nor sweeps overlapping [T, T+S) (a driver restart)
  --gyro-range RAD_S    every gyro axis saturates at +-RAD_S
  --threads N           OpenMP threads for ray casting (default: all cores)
  --help                this text
)";

using ppf::sim::CliArgs;
using ppf::sim::SimConfig;

// Each Parse* step reads one group of options into cfg and rejects bad values with
// std::invalid_argument. main runs them in a fixed order: with several bad options, the first
// one in that order is the one reported.

// What to generate and where: output, scene, LiDAR, length, seed, storage.
void ParseSequence(const CliArgs& args, SimConfig* cfg) {
  if (!args.Has("out")) throw std::invalid_argument("--out DIR is required (see --help)");
  cfg->out_dir = args.Str("out", "");
  cfg->world.scene = args.Str("scene", "urban");
  cfg->lidar = args.Str("lidar", "hdl64");
  ppf::sim::GetLidarModel(cfg->lidar);  // validate early
  cfg->world.duration = args.Num("duration", 30.0);
  if (!(cfg->world.duration > 0.0 && cfg->world.duration <= 3600.0))
    throw std::invalid_argument("--duration must be in (0, 3600]");
  const double seed = args.Num("seed", 1);
  if (seed < 0 || seed != static_cast<double>(static_cast<uint64_t>(seed)))
    throw std::invalid_argument("--seed must be a non-negative integer");
  cfg->seed = static_cast<uint64_t>(seed);
  cfg->bag.storage = args.Str("storage", "mcap");
  cfg->bag.compression = args.Str("compression", "none");
}

// How the platform moves: car or hand-held, speed, rest at the start, shake rate.
void ParseMotion(const CliArgs& args, ppf::sim::WorldOptions* world) {
  using ppf::sim::MotionKind;
  if (args.Has("motion")) {
    const std::string m = args.Str("motion", "");
    if (m != "car" && m != "handheld") throw std::invalid_argument("--motion: car | handheld");
    world->motion = m == "car" ? MotionKind::kCar : MotionKind::kHandheld;
    world->motion_is_default = false;
  }
  world->speed = args.Num("speed", 0.0);
  if (world->speed < 0.0 || world->speed > 40.0)
    throw std::invalid_argument("--speed must be in [0, 40] m/s");
  world->static_time = args.Num("static", 2.5);
  if (world->static_time < 0.0) throw std::invalid_argument("--static must be >= 0");
  world->moving_start = args.Has("moving-start");
  if (world->moving_start && args.Has("static"))
    throw std::invalid_argument("--moving-start and --static exclude each other");
  world->max_rate_deg = args.Num("max-rate", 150.0);
}

// LiDAR measurement errors and reach.
void ParseLidarNoise(const CliArgs& args, ppf::sim::ScanOptions* scan) {
  scan->range_noise = args.Num("range-noise", 0.02);
  scan->dropout = args.Num("dropout", 0.005);
  if (scan->range_noise < 0 || scan->dropout < 0 || scan->dropout > 1)
    throw std::invalid_argument("--range-noise must be >= 0, --dropout in [0, 1]");
  scan->max_range = args.Num("max-range", 0.0);
}

// IMU rate, noise densities and biases, gravity.
void ParseImu(const CliArgs& args, SimConfig* cfg) {
  cfg->imu_rate = args.Num("imu-rate", 200.0);
  if (cfg->imu_rate < 50.0 || cfg->imu_rate > 1000.0)
    throw std::invalid_argument("--imu-rate must be in [50, 1000] Hz");
  ppf::sim::ImuNoise& n = cfg->imu_noise;
  if (args.Has("no-imu-noise")) n = ppf::sim::ImuNoise::Zero();
  n.gyro_noise = args.Num("gyro-noise", n.gyro_noise);
  n.accel_noise = args.Num("accel-noise", n.accel_noise);
  n.gyro_bias_rw = args.Num("gyro-bias-rw", n.gyro_bias_rw);
  n.accel_bias_rw = args.Num("accel-bias-rw", n.accel_bias_rw);
  n.gyro_bias_init = args.Num("gyro-bias-init", n.gyro_bias_init);
  n.accel_bias_init = args.Num("accel-bias-init", n.accel_bias_init);
  cfg->gravity = args.Num("gravity", 9.81);
}

// The LiDAR mount (T_imu_lidar), the clock origin and the driver time conventions.
void ParseMountAndTime(const CliArgs& args, SimConfig* cfg) {
  using ppf::sim::ScanOptions;
  const auto ex = args.List("extrinsic", 6, {0.2, 0.05, 0.15, 1.0, -1.5, 2.0});
  cfg->scan.T_imu_lidar = Eigen::Isometry3d::Identity();
  cfg->scan.T_imu_lidar.translation() = Eigen::Vector3d(ex[0], ex[1], ex[2]);
  cfg->scan.T_imu_lidar.linear() =
      ppf::sim::EulerToRotation(Eigen::Vector3d(ex[3], ex[4], ex[5]) * M_PI / 180.0);
  cfg->start_ns = static_cast<int64_t>(std::llround(args.Num("start-time", 1700000000.0) * 1e9));
  const std::string tf = args.Str("time-field", "driver"), st = args.Str("stamp", "start");
  if (tf != "driver" && tf != "none" && tf != "abs_f64")
    throw std::invalid_argument("--time-field: driver | none | abs_f64");
  if (st != "start" && st != "end") throw std::invalid_argument("--stamp: start | end");
  if ((tf != "driver" || st != "start") &&
      ppf::sim::GetLidarModel(cfg->lidar).layout != ppf::sim::PointLayout::kVelodyne)
    throw std::invalid_argument("--time-field/--stamp apply to velodyne models only");
  cfg->scan.time_field = tf == "none"      ? ScanOptions::TimeField::kNone
                         : tf == "abs_f64" ? ScanOptions::TimeField::kAbsoluteF64
                                           : ScanOptions::TimeField::kDriverDefault;
  cfg->scan.stamp_at_end = st == "end";
}

// Frame ids and topic names.
void ParseNames(const CliArgs& args, SimConfig* cfg) {
  cfg->scan.frame_id = args.Str("lidar-frame", "lidar");
  cfg->imu_frame = args.Str("imu-frame", "imu");
  cfg->bag.points_topic = args.Str("points-topic", "/points");
  cfg->bag.imu_topic = args.Str("imu-topic", "/imu");
}

// "A:B[:C],A:B..." -> lists of 2 (or 3) numbers.
std::vector<std::vector<double>> ColonLists(const CliArgs& args, const std::string& key,
                                            size_t min_n, size_t max_n) {
  std::vector<std::vector<double>> out;
  if (!args.Has(key)) return out;
  std::string all = args.Str(key, "");
  size_t start = 0;
  while (start <= all.size()) {
    const size_t comma = std::min(all.find(',', start), all.size());
    const std::string item = all.substr(start, comma - start);
    std::vector<double> nums;
    size_t p = 0;
    while (p <= item.size()) {
      const size_t colon = std::min(item.find(':', p), item.size());
      const std::string num = item.substr(p, colon - p);
      char* end = nullptr;
      const double v = std::strtod(num.c_str(), &end);
      if (num.empty() || *end != '\0' || !std::isfinite(v))
        throw std::invalid_argument("--" + key + ": not a number: '" + num + "' in '" + item + "'");
      nums.push_back(v);
      p = colon + 1;
    }
    if (nums.size() < min_n || nums.size() > max_n)
      throw std::invalid_argument("--" + key + ": '" + item + "' needs " + std::to_string(min_n) +
                                  (max_n > min_n ? " or " + std::to_string(max_n) : "") +
                                  " numbers separated by ':'");
    out.push_back(nums);
    start = comma + 1;
  }
  return out;
}

void ParseDisturbances(const CliArgs& args, SimConfig* cfg) {
  ppf::sim::Disturbances& d = cfg->disturbances;
  for (const auto& v : ColonLists(args, "jolt", 2, 3)) {
    if (v[0] < 0.0) throw std::invalid_argument("--jolt: time must be >= 0");
    d.jolts.push_back({v[0], v[1] * M_PI / 180.0, v.size() > 2 ? v[2] : 0.0});
  }
  for (const auto& v : ColonLists(args, "imu-gap", 2, 2)) {
    if (v[0] < 0.0 || v[1] <= 0.0) throw std::invalid_argument("--imu-gap: T >= 0, S > 0");
    d.imu_gaps.push_back({v[0], v[1]});
  }
  for (const auto& v : ColonLists(args, "silence", 2, 2)) {
    if (v[0] < 0.0 || v[1] <= 0.0) throw std::invalid_argument("--silence: T >= 0, S > 0");
    d.silences.push_back({v[0], v[1]});
  }
  d.gyro_range = args.Num("gyro-range", 0.0);
  if (d.gyro_range < 0.0 || !std::isfinite(d.gyro_range))
    throw std::invalid_argument("--gyro-range must be > 0 (0 = no saturation)");
}

void ApplyThreads(const CliArgs& args) {
  if (!args.Has("threads")) return;
  const double threads = args.Num("threads", 1);
  if (threads < 1 || threads > 256 || threads != static_cast<int>(threads))
    throw std::invalid_argument("--threads must be an integer >= 1");
  omp_set_num_threads(static_cast<int>(threads));
}

void PrintSummary(const ppf::sim::SimSummary& s) {
  std::printf("\n%-28s %10s\n", "stage", "seconds");
  std::printf("%-28s %10.3f\n", "world (scene + trajectory)", s.seconds_world);
  std::printf("%-28s %10.3f\n", "imu synthesis", s.seconds_imu);
  std::printf("%-28s %10.3f\n", "ray casting (scans)", s.seconds_scans);
  std::printf("%-28s %10.3f\n", "serialize + write bag", s.seconds_write);
  std::printf("%-28s %10.3f\n", "total incl. ground truth", s.seconds_total);
  std::printf("\n%d scans, %.0f points/scan, %d IMU samples, %.1f MB payload, %.1f ms/scan\n",
              s.scans, s.scans ? static_cast<double>(s.points) / s.scans : 0.0, s.imu_samples,
              s.bytes / 1e6, s.scans ? 1e3 * s.seconds_total / s.scans : 0.0);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace ppf::sim;
  try {
    const CliArgs args(
        argc, argv,
        {"out", "scene", "lidar", "duration", "seed", "storage", "compression", "motion", "speed",
         "static", "max-rate", "range-noise", "dropout", "max-range", "imu-rate", "gyro-noise",
         "accel-noise", "gyro-bias-rw", "accel-bias-rw", "gyro-bias-init", "accel-bias-init",
         "gravity", "extrinsic", "start-time", "lidar-frame", "imu-frame", "points-topic",
         "imu-topic", "threads", "time-field", "stamp", "jolt", "imu-gap", "silence",
         "gyro-range"},
        {"help", "no-imu-noise", "moving-start"});
    if (args.Has("help")) {
      std::fputs(kHelp, stdout);
      return 0;
    }
    SimConfig cfg;
    ParseSequence(args, &cfg);
    ParseMotion(args, &cfg.world);
    ParseLidarNoise(args, &cfg.scan);
    ParseImu(args, &cfg);
    ParseMountAndTime(args, &cfg);
    ParseNames(args, &cfg);
    ParseDisturbances(args, &cfg);
    ApplyThreads(args);

    std::printf("ppf_sim: scene %s, lidar %s, %.1f s, seed %llu -> %s (%s)\n",
                cfg.world.scene.c_str(), cfg.lidar.c_str(), cfg.world.duration,
                static_cast<unsigned long long>(cfg.seed), cfg.out_dir.c_str(),
                cfg.bag.storage.c_str());
    PrintSummary(RunSimulation(cfg, std::cout));
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ppf_sim: error: %s\n", e.what());
    return 2;
  }
}
