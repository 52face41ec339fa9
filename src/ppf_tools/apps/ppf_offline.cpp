// ppf_offline: runs the LIO-PPF core on a rosbag2 bag (sqlite3 or MCAP) without DDS, as fast as
// the machine allows, and writes the trajectory, per-scan statistics and, if asked, the map.
//
//   ppf_offline --bag DIR --config FILE --mode knn|ppf --out traj.tum --stats stats.csv
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "ppf_bag/bag.hpp"
#include "ppf_core/config.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_tools/map_export.hpp"
#include "ppf_tools/offline_runner.hpp"
#include "ppf_tools/scan_stats.hpp"
#include "ppf_trajectory/evaluation.hpp"

namespace {

constexpr const char* kUsage = R"(usage: ppf_offline --bag DIR [options]

Runs the LIO-PPF core on a rosbag2 bag (sqlite3 .db3 or MCAP) or a ROS 1 .bag without DDS, as fast as possible.

  --bag PATH            bag directory (metadata.yaml), a single .db3/.mcap file or a ROS 1
                        .bag file (required)
  --config FILE         YAML config (config/<lidar>.yaml); every key optional. Repeatable:
                        later files override earlier ones (e.g. a LiDAR preset, then the
                        robot's calibration.yaml with its T_imu_lidar)
  --mode knn|ppf        overrides the config's mode
  --out FILE            trajectory output (default: trajectory.tum)
  --format tum|kitti    trajectory format (default: tum; KITTI writes 3x4 rows, no stamps)
  --frame imu|lidar     which frame's pose to write (default: imu, the ground truth frame of ppf_sim)
  --stats FILE          per-scan statistics, CSV (.csv) or JSON (.json)
  --planes FILE         --mode ppf: the skeleton-plane window after every scan, CSV (one row per
                        plane: stamp, track id, age, hits, world normal/offset/centroid, inliers)
  --points-topic NAME   PointCloud2 topic (default: the first one in the bag)
  --imu-topic NAME      Imu topic (default: the first one in the bag)
  --imu-gap S L         drop the IMU samples from S to S+L seconds after the first message (an
                        IMU dropout, like the node test peer's --imu-gap; the core continues
                        LiDAR-only meanwhile, imu.loss_timeout)
  --drop-scans K [S L]  drop every K-th scan (2 drops half) before the core sees it, as a
                        node starved of CPU drops them; with S L only the scans from S to S+L
                        seconds after the first message (with --imu-gap: scans lost during an
                        IMU dropout); K = 1 drops all of them (a burst, needs S L)
  --threads N           OpenMP threads for the core (default: config, else all cores)
  --omp-wait-policy P   passive | active | default: how idle OpenMP threads wait (libgomp's
                        OMP_WAIT_POLICY; default passive, as the node's core.omp_wait_policy:
                        spinning threads collapse the core on a loaded machine). Applied with
                        more than one thread by re-executing once with OMP_WAIT_POLICY set
                        (under valgrind add --trace-children=yes); an OMP_WAIT_POLICY already
                        in the environment wins; default: libgomp's own
  --dump-scan N         write scan N's registered points and skeleton planes (N counts every
                        scan result in bag order from 0; the scan must have a pose) to
                        --dump-dir: scan_points.csv (x,y,z world frame, PPF label),
                        scan_planes.csv (the skeleton-plane window after the scan: normal,
                        offset, centroid, in-plane axes with half extents) and scan_info.csv
                        (stamp, status, T_world_lidar). Adds one copy of each scan's points
                        to the loop
  --dump-dir DIR        where --dump-scan writes (created; default: .)
  --map-out FILE        the map: every scan with a pose (status ok or degenerate, not
                        re-localized after a long gap) adds its registered points
                        (range-filtered, downsampled by preprocess.scan_voxel_size, de-skewed)
                        in the world frame to a voxel grid of --map-voxel; one point per voxel,
                        the mean of its points. FILE.pcd: binary PCD (PCL, CloudCompare);
                        FILE.ply: binary little-endian PLY (--ply-ascii for ASCII). Fields x y z
                        intensity (float32); the core keeps no intensity, so "intensity" is the
                        number of points in the voxel. Memory grows with the occupied voxels,
                        not with the scans
  --map-voxel M         voxel size of --map-out in metres (default: 0.1)
  --local-map-out FILE  the core's local kNN map at the end (what the last scan was
                        registered against, bounded by map.max_voxels and map.radius), as
                        stored, world frame, intensity 1; .pcd or .ply as --map-out. In ppf
                        mode the skeleton points are not in it (the core keeps them as
                        plane patches)
  --ply-ascii           write .ply maps as ASCII instead of binary
  --read-only           only read and decode the bag (every scan and IMU message), no core:
                        what reading the bag alone costs in time and memory (ppf_bench)
  --quiet               no progress bar and no per-run summary
  -h, --help            this text

Exit status: 0 on success, 1 on a bad bag/config/argument, 2 if no scan produced a pose.
)";

struct Args {
  std::vector<std::string> configs;
  std::string bag, mode, out = "trajectory.tum", format = "tum", frame = "imu", stats, planes,
      points_topic, imu_topic, dump_dir = ".";
  int threads = -1;
  std::string omp_wait_policy = "passive";
  long dump_scan = -1;
  std::string map_out, local_map_out;
  double map_voxel = 0.1;
  bool ply_ascii = false;
  double imu_gap_begin = 0.0, imu_gap_length = 0.0;
  int drop_every = 0;
  double drop_begin = 0.0, drop_length = 0.0;
  bool quiet = false;
  bool read_only = false;
};

[[noreturn]] void Fail(const std::string& msg) {
  std::cerr << "ppf_offline: " << msg << "\n";
  std::exit(1);
}

Args ParseArgs(int argc, char** argv) {
  Args a;
  auto value = [&](int& i) -> std::string {
    if (i + 1 >= argc) Fail(std::string("missing value after ") + argv[i]);
    return argv[++i];
  };
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help") {
      std::cout << kUsage;
      std::exit(0);
    } else if (arg == "--bag") {
      a.bag = value(i);
    } else if (arg == "--config") {
      a.configs.push_back(value(i));
    } else if (arg == "--mode") {
      a.mode = value(i);
    } else if (arg == "--out") {
      a.out = value(i);
    } else if (arg == "--format") {
      a.format = value(i);
    } else if (arg == "--frame") {
      a.frame = value(i);
    } else if (arg == "--stats") {
      a.stats = value(i);
    } else if (arg == "--planes") {
      a.planes = value(i);
    } else if (arg == "--points-topic") {
      a.points_topic = value(i);
    } else if (arg == "--imu-topic") {
      a.imu_topic = value(i);
    } else if (arg == "--imu-gap") {
      const std::string b = value(i), l = value(i);
      char *end_b = nullptr, *end_l = nullptr;
      a.imu_gap_begin = std::strtod(b.c_str(), &end_b);
      a.imu_gap_length = std::strtod(l.c_str(), &end_l);
      if (b.empty() || l.empty() || *end_b != '\0' || *end_l != '\0' || !(a.imu_gap_begin >= 0) ||
          !(a.imu_gap_length > 0)) {
        Fail("--imu-gap needs START >= 0 and LENGTH > 0 in seconds");
      }
    } else if (arg == "--drop-scans") {
      const std::string k = value(i);
      char* end = nullptr;
      a.drop_every = static_cast<int>(std::strtol(k.c_str(), &end, 10));
      if (k.empty() || *end != '\0' || a.drop_every < 1) Fail("--drop-scans needs K >= 1");
      // An optional window: two numbers follow.
      if (i + 2 < argc && argv[i + 1][0] != '-') {
        const std::string b = value(i), l = value(i);
        char *end_b = nullptr, *end_l = nullptr;
        a.drop_begin = std::strtod(b.c_str(), &end_b);
        a.drop_length = std::strtod(l.c_str(), &end_l);
        if (*end_b != '\0' || *end_l != '\0' || !(a.drop_begin >= 0) || !(a.drop_length > 0)) {
          Fail("--drop-scans K S L needs START >= 0 and LENGTH > 0 in seconds");
        }
      }
      if (a.drop_every == 1 && !(a.drop_length > 0)) {
        Fail("--drop-scans 1 (every scan) needs a window: --drop-scans 1 START LENGTH");
      }
    } else if (arg == "--threads") {
      a.threads = std::atoi(value(i).c_str());
    } else if (arg == "--omp-wait-policy") {
      a.omp_wait_policy = value(i);
      if (a.omp_wait_policy != "passive" && a.omp_wait_policy != "active" &&
          a.omp_wait_policy != "default") {
        Fail("--omp-wait-policy: passive, active or default");
      }
    } else if (arg == "--dump-scan") {
      const std::string v = value(i);
      char* end = nullptr;
      a.dump_scan = std::strtol(v.c_str(), &end, 10);
      if (v.empty() || *end != '\0' || a.dump_scan < 0) Fail("--dump-scan needs a scan index >= 0");
    } else if (arg == "--dump-dir") {
      a.dump_dir = value(i);
    } else if (arg == "--map-out") {
      a.map_out = value(i);
    } else if (arg == "--local-map-out") {
      a.local_map_out = value(i);
    } else if (arg == "--map-voxel") {
      const std::string v = value(i);
      char* end = nullptr;
      a.map_voxel = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0' || !(a.map_voxel >= 0.01 && a.map_voxel <= 100.0)) {
        Fail("--map-voxel needs a size in metres from 0.01 to 100");
      }
    } else if (arg == "--ply-ascii") {
      a.ply_ascii = true;
    } else if (arg == "--quiet") {
      a.quiet = true;
    } else if (arg == "--read-only") {
      a.read_only = true;
    } else {
      Fail("unknown argument '" + arg + "' (see --help)");
    }
  }
  if (a.bag.empty()) Fail("--bag is required (see --help)");
  if (!a.mode.empty() && a.mode != "knn" && a.mode != "ppf") Fail("--mode must be knn or ppf");
  if (a.format != "tum" && a.format != "kitti") Fail("--format must be tum or kitti");
  if (a.frame != "imu" && a.frame != "lidar") Fail("--frame must be imu or lidar");
  const auto check_map_file = [&](const char* flag, const std::string& file) {
    ppf::tools::MapFormat format;
    if (!file.empty() && !ppf::tools::MapFormatForFile(file, a.ply_ascii, &format)) {
      Fail(std::string(flag) + " needs a file name ending in .pcd or .ply, not '" + file + "'");
    }
  };
  check_map_file("--map-out", a.map_out);
  check_map_file("--local-map-out", a.local_map_out);
  if (a.read_only && !(a.map_out.empty() && a.local_map_out.empty())) {
    Fail("--map-out and --local-map-out need the core: not with --read-only");
  }
  return a;
}

const char* LabelName(ppf::PointLabel l) {
  switch (l) {
    case ppf::PointLabel::kSkeleton: return "skeleton";
    case ppf::PointLabel::kDiscarded: return "discarded";
    case ppf::PointLabel::kScattered: break;
  }
  return "scattered";
}

// One scan as the paper's Fig. 1 shows it: its points in the world with their PPF label, and the
// skeleton planes as rectangles (centroid, two in-plane axes, half extents of a uniform patch with
// the inliers' spread: sqrt(3) standard deviations).
void DumpScan(const std::string& dir, size_t index, const ppf::ScanResult& r, bool ppf_mode) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) Fail("cannot create " + dir + ": " + ec.message());
  const auto path = [&](const char* name) { return (std::filesystem::path(dir) / name).string(); };
  std::ofstream info(path("scan_info.csv"));
  std::ofstream pts(path("scan_points.csv"));
  std::ofstream planes(path("scan_planes.csv"));
  if (!info || !pts || !planes) Fail("cannot write into " + dir);
  const Eigen::Quaterniond q(r.T_world_lidar.linear());
  const Eigen::Vector3d t = r.T_world_lidar.translation();
  info << "index,stamp,status,mode,points,planes,x,y,z,qx,qy,qz,qw\n"
       << index << ',' << std::fixed << std::setprecision(6) << r.stamp_s << ','
       << ppf::StatusName(r.status) << ',' << (ppf_mode ? "ppf" : "knn") << ','
       << r.deskewed_points_lidar.size() << ',' << r.skeleton_planes.size() << ',' << t.x() << ','
       << t.y() << ',' << t.z() << ',' << std::setprecision(9) << q.x() << ',' << q.y() << ','
       << q.z() << ',' << q.w() << '\n';
  pts << "x,y,z,label\n" << std::fixed << std::setprecision(4);
  for (size_t i = 0; i < r.deskewed_points_lidar.size(); ++i) {
    const Eigen::Vector3d w = r.T_world_lidar * r.deskewed_points_lidar[i].cast<double>();
    const ppf::PointLabel l = i < r.deskewed_point_labels.size() ? r.deskewed_point_labels[i]
                                                                 : ppf::PointLabel::kScattered;
    pts << w.x() << ',' << w.y() << ',' << w.z() << ',' << LabelName(l) << '\n';
  }
  planes << "track_id,fitted,age,hits,nx,ny,nz,d,cx,cy,cz,inliers,ux,uy,uz,u_half,vx,vy,vz,v_half\n"
         << std::setprecision(6);
  for (const auto& sp : r.skeleton_planes) {
    const double n = std::max(1, sp.num_inliers);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(sp.scatter / n);
    // Ascending eigenvalues: [0] across the plane, [2] its longest in-plane axis.
    const Eigen::Vector3d u = es.eigenvectors().col(2), v = es.eigenvectors().col(1);
    const double u_half = std::sqrt(3.0 * std::max(0.0, es.eigenvalues()(2)));
    const double v_half = std::sqrt(3.0 * std::max(0.0, es.eigenvalues()(1)));
    planes << sp.track_id << ',' << (sp.missed_scans == 0 ? 1 : 0) << ',' << sp.age << ','
           << sp.hits << ',' << sp.plane.n.x() << ',' << sp.plane.n.y() << ',' << sp.plane.n.z()
           << ',' << sp.plane.d << ',' << sp.centroid.x() << ',' << sp.centroid.y() << ','
           << sp.centroid.z() << ',' << sp.num_inliers << ',' << u.x() << ',' << u.y() << ','
           << u.z() << ',' << u_half << ',' << v.x() << ',' << v.y() << ',' << v.z() << ','
           << v_half << '\n';
  }
  if (!info || !pts || !planes) Fail("cannot write into " + dir);
}

class ProgressBar {
 public:
  explicit ProgressBar(bool enabled) : enabled_(enabled && isatty(STDERR_FILENO)) {}
  void Update(uint64_t done, uint64_t total, double scans_per_s) {
    if (!enabled_ || total == 0) return;
    const auto now = std::chrono::steady_clock::now();
    if (done < total && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    const int width = 40;
    const double frac = std::min(1.0, static_cast<double>(done) / static_cast<double>(total));
    const int filled = static_cast<int>(frac * width);
    std::fprintf(stderr, "\r[%.*s%*s] %3d%% %lu/%lu scans %6.1f scans/s", filled,
                 "========================================", width - filled, "",
                 static_cast<int>(frac * 100), static_cast<unsigned long>(done),
                 static_cast<unsigned long>(total), scans_per_s);
    if (done >= total) std::fprintf(stderr, "\n");
  }
  void Finish() {
    if (enabled_) std::fprintf(stderr, "\n");
  }

 private:
  bool enabled_;
  std::chrono::steady_clock::time_point last_{};
};

// --read-only: the same bag reader and message decoding as a run, with the core left out: the
// baseline ppf_bench subtracts (peak RSS, wall time). The checksum keeps the loop from being
// optimised away.
int ReadOnly(const Args& args) {
  ppf::tools::BagSourceCallbacks callbacks;
  double checksum = 0.0;
  callbacks.on_imu = [&](const ppf::ImuSample& s) { checksum += s.stamp_s; };
  callbacks.on_scan = [&](const ppf::CloudView& v) {
    checksum += static_cast<double>(v.width) * v.height + static_cast<double>(v.size);
    if (v.size > 0) checksum += v.data[v.size - 1];
  };
  callbacks.on_error = [](const std::string& e) { std::cerr << "ppf_offline: skipped " << e << "\n"; };
  const auto t0 = std::chrono::steady_clock::now();
  ppf::tools::BagSourceStats stats;
  try {
    stats = ppf::tools::StreamBag(args.bag, {args.points_topic, args.imu_topic}, callbacks);
  } catch (const std::exception& e) {
    Fail(e.what());
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!args.quiet) {
    std::cout << "ppf_offline (read only): " << stats.scans << " scans, " << stats.imu
              << " IMU messages, " << stats.malformed << " malformed, " << std::fixed
              << std::setprecision(2) << wall_s << " s (checksum " << checksum << ")\n";
  }
  return stats.scans > 0 ? 0 : 2;
}

// The --config files in order (warnings to stderr), then the command line's overrides.
ppf::Config LoadConfig(const Args& args) {
  ppf::Config config;
  for (const auto& file : args.configs) {
    const auto report = ppf::LoadConfigYaml(file, &config);
    for (const auto& w : report.warnings) std::cerr << "ppf_offline: " << file << ": " << w << "\n";
    if (!report.ok) Fail("config " + file + ": " + report.error);
  }
  if (args.mode == "knn") config.mode = ppf::Mode::kKnn;
  if (args.mode == "ppf") config.mode = ppf::Mode::kPpf;
  if (args.threads >= 0) config.num_threads = args.threads;
  if (args.dump_scan >= 0 || !args.map_out.empty()) config.output_deskewed_points = true;
  config.log = [](ppf::LogLevel level, const std::string& msg) {
    if (level >= ppf::LogLevel::kInfo) std::cerr << "\nppf_offline: " << msg << "\n";
  };
  return config;
}

// --stats: CSV, or JSON for a .json file name.
void WriteStats(const std::string& file, const std::vector<ppf::ScanResult>& results) {
  std::ofstream os(file);
  if (!os) Fail("cannot write " + file);
  const bool json = file.size() > 5 && file.substr(file.size() - 5) == ".json";
  if (json) {
    ppf::tools::WriteStatsJson(os, results);
  } else {
    ppf::tools::WriteStatsCsvHeader(os);
    for (const auto& r : results) ppf::tools::WriteStatsCsvRow(os, r);
  }
}

// --planes: the skeleton-plane window after every scan, one row per plane.
void WritePlanes(const std::string& file, const std::vector<ppf::ScanResult>& results) {
  std::ofstream os(file);
  if (!os) Fail("cannot write " + file);
  os << "stamp,track_id,age,hits,missed_scans,nx,ny,nz,d,cx,cy,cz,inliers\n";
  os << std::setprecision(9);
  for (const auto& r : results) {
    for (const auto& sp : r.skeleton_planes) {
      os << std::fixed << std::setprecision(6) << r.stamp_s << std::defaultfloat
         << std::setprecision(9) << "," << sp.track_id << "," << sp.age << "," << sp.hits << ","
         << sp.missed_scans << "," << sp.plane.n.x() << "," << sp.plane.n.y() << ","
         << sp.plane.n.z() << "," << sp.plane.d << "," << sp.centroid.x() << ","
         << sp.centroid.y() << "," << sp.centroid.z() << "," << sp.num_inliers << "\n";
    }
  }
}

// --map-out, --local-map-out (the extension was checked with the arguments).
void WriteMap(const std::string& file, const std::vector<ppf::tools::MapPoint>& points,
              bool ply_ascii) {
  ppf::tools::MapFormat format = ppf::tools::MapFormat::kPcdBinary;
  ppf::tools::MapFormatForFile(file, ply_ascii, &format);
  std::string error;
  if (!ppf::tools::WriteMapFile(file, points, format, &error)) Fail(error);
}

// The per-run summary on stdout, and every scan that reset or was rejected.
void PrintRunSummary(const Args& args, const ppf::Config& config,
                     const ppf::tools::OfflineRun& run) {
  const auto summary = ppf::tools::Summarize(run.results, run.wall_s);
  ppf::tools::PrintSummary(
      std::cout, summary,
      std::string("ppf_offline (") + (config.mode == ppf::Mode::kPpf ? "ppf" : "knn") +
          (run.lidar_only ? ", LiDAR-only" : "") + "): " + std::to_string(run.trajectory.size()) +
          " poses -> " + args.out);
  if (run.source.malformed > 0) {
    std::cout << "  skipped malformed messages: " << run.source.malformed << "\n";
  }
  for (const auto& r : run.results) {
    if (r.status == ppf::Status::kReset || r.status == ppf::Status::kRejected) {
      std::cout << "  scan " << std::fixed << r.stamp_s << ": " << ppf::StatusName(r.status)
                << ": " << r.reason << "\n";
    }
  }
}

}  // namespace

// libgomp reads OMP_WAIT_POLICY when it is loaded, before main: the process re-executes itself
// once with it set (nothing opened or written yet). One thread has no team to wait in.
void ApplyOmpWaitPolicy(const std::string& policy, int threads, char** argv) {
  if (policy == "default" || threads == 1 || std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  setenv("OMP_WAIT_POLICY", policy == "active" ? "ACTIVE" : "PASSIVE", 1);
  char self[4096];
  const ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n > 0) {
    self[n] = '\0';
    execv(self, argv);
  }
  std::cerr << "ppf_offline: could not apply OMP_WAIT_POLICY (re-exec failed); continuing\n";
}

int main(int argc, char** argv) {
  const Args args = ParseArgs(argc, argv);
  if (args.read_only) return ReadOnly(args);
  const ppf::Config config = LoadConfig(args);
  ApplyOmpWaitPolicy(args.omp_wait_policy, config.num_threads, argv);

  ProgressBar progress(!args.quiet);
  ppf::tools::OfflineOptions options;
  options.source = {args.points_topic, args.imu_topic};
  options.lidar_frame = args.frame == "lidar";
  options.imu_gap_begin_s = args.imu_gap_begin;
  options.imu_gap_length_s = args.imu_gap_length;
  options.drop_scans_every = args.drop_every;
  options.drop_scans_begin_s = args.drop_begin;
  options.drop_scans_length_s = args.drop_length;
  options.on_topics_resolved = [&](const ppf::tools::BagSourceStats& s) {
    if (!args.quiet) {
      std::cerr << "ppf_offline: " << args.bag << ": " << s.points_topic << " ("
                << s.total_scans_in_bag << " scans), "
                << (s.imu_topic.empty() ? std::string("no IMU topic: LiDAR-only") : s.imu_topic)
                << ", mode " << (config.mode == ppf::Mode::kPpf ? "ppf" : "knn") << "\n";
    }
  };
  options.on_progress = [&](size_t done, uint64_t total, double core_ms) {
    progress.Update(done, total, core_ms > 0 ? 1000.0 * static_cast<double>(done) / core_ms : 0.0);
  };
  options.on_error = [](const std::string& e) { std::cerr << "\nppf_offline: skipped " << e << "\n"; };
  std::string dump_error = args.dump_scan >= 0 ? "no scan " + std::to_string(args.dump_scan) +
                                                     " in the bag"
                                               : "";
  ppf::tools::MapAccumulator map(args.map_voxel);
  if (args.dump_scan >= 0 || !args.map_out.empty()) {
    options.on_result = [&](size_t index, ppf::ScanResult* r) {
      if (!args.map_out.empty()) map.AddResult(*r);
      if (static_cast<long>(index) == args.dump_scan) {
        if (r->pose_valid) {
          DumpScan(args.dump_dir, index, *r, config.mode == ppf::Mode::kPpf);
          dump_error.clear();
        } else {
          dump_error = "scan " + std::to_string(index) + " has no pose (" +
                       ppf::StatusName(r->status) + "): nothing dumped";
        }
      }
      r->deskewed_points_lidar = {};
      r->deskewed_point_labels = {};
    };
  }

  std::vector<ppf::tools::MapPoint> local_map;
  if (!args.local_map_out.empty()) {
    options.on_finish = [&](const ppf::LioPpf& lio) {
      local_map = ppf::tools::ToMapPoints(lio.LocalMapPoints());
    };
  }

  ppf::tools::OfflineRun run;
  try {
    run = ppf::tools::RunOffline(args.bag, config, options);
  } catch (const std::exception& e) {
    Fail(e.what());
  }
  progress.Finish();

  const bool ok = args.format == "tum" ? ppf::WriteTum(args.out, run.trajectory)
                                       : ppf::WriteKitti(args.out, run.trajectory);
  if (!ok) Fail("cannot write " + args.out);
  if (!args.stats.empty()) WriteStats(args.stats, run.results);
  if (!args.planes.empty()) WritePlanes(args.planes, run.results);
  if (!args.quiet) PrintRunSummary(args, config, run);
  if (!args.map_out.empty()) {
    WriteMap(args.map_out, map.Points(), args.ply_ascii);
    if (!args.quiet) {
      std::cout << "  map: " << map.voxels() << " points (" << std::defaultfloat
                << std::setprecision(6) << args.map_voxel << " m voxels, " << map.points_added()
                << " registered points of " << map.scans_added() << " scans) -> " << args.map_out
                << "\n";
    }
  }
  if (!args.local_map_out.empty()) {
    WriteMap(args.local_map_out, local_map, args.ply_ascii);
    if (!args.quiet) {
      std::cout << "  local map: " << local_map.size() << " points -> " << args.local_map_out
                << "\n";
    }
  }
  if (!dump_error.empty()) Fail("--dump-scan: " + dump_error);
  return run.trajectory.empty() ? 2 : 0;
}
