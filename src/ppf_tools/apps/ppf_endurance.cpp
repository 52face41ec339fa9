// ppf_endurance: a long simulated drive streamed into the core in-process (no bag on disk), with
// the local map size and the process memory every minute of simulated time, to show that both
// stay bounded.
//
//   ppf_endurance                                  # 10 minutes, urban, VLP-16, kNN mode
//   ppf_endurance --mode ppf --lidar hdl32 --duration 300
#include <algorithm>
#include <cstdlib>
#include <exception>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

#include "ppf_core/config.hpp"
#include "ppf_sim/lidar_model.hpp"
#include "ppf_sim/world.hpp"
#include "ppf_tools/endurance.hpp"

#ifndef PPF_DEFAULT_CONFIG_DIR
#define PPF_DEFAULT_CONFIG_DIR "config"
#endif

namespace {

constexpr const char* kUsage = R"(usage: ppf_endurance [options]

Simulates a drive with ppf_sim's generator and streams it into ppf::LioPpf in the same process
(nothing is written to disk). Every minute of simulated time it prints the distance driven, the
local map (points, voxels; in PPF mode also the plane patches), the process memory (VmRSS), the APE
of the trajectory so far (SE(3)-aligned and position+yaw-aligned), the largest tilt between the
estimated and the true gravity so far (degrees, from --tilt-after on) and the height error (first
pose matched by translation + yaw); at the end the map maximum in each half of the drive, the
memory growth over the second half, how often the drive left the map's bound radius, and the APE,
tilt and height error against the exact ground truth.

  --duration S        simulated seconds (default 600)
  --scene NAME        urban | park | ramps | indoor (default urban)
  --lidar NAME        vlp16 | hdl32 | hdl64 | os1_64 | os1_128 (default vlp16)
  --mode knn|ppf      registration mode (default knn)
  --roam-radius M     the drive turns back towards its start beyond M metres (default 600;
                      0 = the scene's own, 150 m for urban)
  --config FILE       core config (default: <config-dir>/<lidar>.yaml); the simulator's LiDAR
                      mount replaces its extrinsic
  --config-dir DIR    LiDAR presets (default: the repository's config/)
  --map-radius M      override map.radius (and ppf.patch_radius) of the config
  --threads N         OpenMP threads for the core (default: the config's)
  --seed N            simulation seed (default 1)
  --report-every S    simulated seconds between rows (default 60)
  --tilt-after S      tilt statistics from S seconds after the first pose on (default 10)
  -h, --help          this text
)";

[[noreturn]] void Fail(const std::string& msg) {
  std::cerr << "ppf_endurance: " << msg << "\n";
  std::exit(1);
}

double Number(const std::string& key, const std::string& v) {
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0') Fail(key + ": not a number: '" + v + "'");
  return x;
}

struct Cli {
  ppf::tools::EnduranceOptions opts;
  std::string mode = "knn", config_file, config_dir = PPF_DEFAULT_CONFIG_DIR;
  double map_radius = -1.0;
  int threads = -1;
};

// The command line, checked; exits with a message on anything wrong (0 after --help).
Cli ParseArgs(int argc, char** argv) {
  Cli cli;
  ppf::tools::EnduranceOptions& opts = cli.opts;
  opts.roam_radius = 600.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::cout << kUsage;
      std::exit(0);
    }
    if (a.rfind("--", 0) != 0) Fail("unexpected argument '" + a + "' (see --help)");
    if (i + 1 >= argc) Fail("missing value after " + a + " (see --help)");
    const std::string v = argv[++i];
    if (a == "--duration")
      opts.duration = Number(a, v);
    else if (a == "--scene")
      opts.scene = v;
    else if (a == "--lidar")
      opts.lidar = v;
    else if (a == "--mode")
      cli.mode = v;
    else if (a == "--roam-radius")
      opts.roam_radius = Number(a, v);
    else if (a == "--config")
      cli.config_file = v;
    else if (a == "--config-dir")
      cli.config_dir = v;
    else if (a == "--map-radius")
      cli.map_radius = Number(a, v);
    else if (a == "--threads")
      cli.threads = static_cast<int>(Number(a, v));
    else if (a == "--seed")
      opts.seed = static_cast<uint64_t>(Number(a, v));
    else if (a == "--report-every")
      opts.report_every = Number(a, v);
    else if (a == "--tilt-after")
      opts.tilt_after = Number(a, v);
    else
      Fail("unknown option '" + a + "' (see --help)");
  }
  if (!(opts.duration >= 10.0)) Fail("--duration must be at least 10 s");
  if (!(opts.report_every > 0.0)) Fail("--report-every must be positive");
  if (!(opts.tilt_after >= 0.0)) Fail("--tilt-after must be >= 0");
  if (cli.mode != "knn" && cli.mode != "ppf") {
    Fail("--mode must be knn or ppf, not '" + cli.mode + "'");
  }
  auto known = [](const std::vector<std::string>& names, const std::string& name) {
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    if (std::find(names.begin(), names.end(), name) == names.end()) return list;
    return std::string();
  };
  const std::string scenes = known(ppf::sim::SceneNames(), opts.scene);
  if (!scenes.empty()) Fail("unknown scene '" + opts.scene + "' (" + scenes + ")");
  const std::string lidars = known(ppf::sim::LidarModelNames(), opts.lidar);
  if (!lidars.empty()) Fail("unknown LiDAR '" + opts.lidar + "' (" + lidars + ")");
  return cli;
}

// The LiDAR's preset (or --config) with the command line's overrides.
ppf::Config LoadConfig(Cli* cli) {
  ppf::Config config;
  if (cli->config_file.empty()) {
    cli->config_file = cli->config_dir + "/" + cli->opts.lidar + ".yaml";
  }
  const auto report = ppf::LoadConfigYaml(cli->config_file, &config);
  if (!report.ok) Fail(cli->config_file + ": " + report.error);
  config.mode = cli->mode == "ppf" ? ppf::Mode::kPpf : ppf::Mode::kKnn;
  if (cli->map_radius >= 0.0) config.map.radius = config.ppf.patch_radius = cli->map_radius;
  if (cli->threads >= 0) config.num_threads = cli->threads;
  return config;
}

void PrintHeader(const Cli& cli, const ppf::Config& config) {
  const ppf::tools::EnduranceOptions& opts = cli.opts;
  std::cout << "ppf_endurance: " << opts.scene << " " << opts.lidar << " " << cli.mode << ", "
            << opts.duration << " s simulated, map radius " << config.map.radius << " m, LRU "
            << config.map.max_voxels << " voxels x " << config.map.max_points_per_voxel
            << " points, roam radius " << opts.roam_radius << " m, seed " << opts.seed << "\n\n";
  std::cout << std::right << std::setw(8) << "sim s" << std::setw(9) << "dist km" << std::setw(11)
            << "map pts" << std::setw(10) << "voxels" << std::setw(11) << "max pts" << std::setw(9)
            << "patches" << std::setw(9) << "RSS MB" << std::setw(10) << "APE m" << std::setw(10)
            << "posyaw m" << std::setw(10) << "tilt max" << std::setw(9) << "dz m" << std::setw(8)
            << "posed" << std::setw(9) << "wall s"
            << "\n"
            << std::flush;
}

void PrintRow(const ppf::tools::EnduranceRow& r) {
  std::cout << std::fixed << std::setprecision(0) << std::setw(8) << r.sim_time
            << std::setprecision(2) << std::setw(9) << r.distance / 1000.0 << std::setw(11)
            << r.map_points << std::setw(10) << r.map_voxels << std::setw(11) << r.max_map_points
            << std::setw(9) << r.patches << std::setprecision(1) << std::setw(9) << r.rss_mb
            << std::setprecision(2) << std::setw(10) << r.ape_rmse << std::setw(10)
            << r.ape_posyaw_rmse << std::setprecision(3);
  if (r.tilt_max_deg >= 0) {
    std::cout << std::setw(10) << r.tilt_max_deg;
  } else {
    std::cout << std::setw(10) << "-";  // no pose past --tilt-after yet
  }
  std::cout << std::showpos << std::setprecision(2) << std::setw(9) << r.dz_m << std::noshowpos
            << std::setw(8) << r.posed << std::setprecision(0) << std::setw(9) << r.wall_s << "\n"
            << std::flush;
}

void PrintSummary(const ppf::tools::EnduranceReport& rep, const ppf::Config& config,
                  const ppf::tools::EnduranceOptions& opts) {
  const double growth_pct =
      rep.max_map_first_half > 0
          ? 100.0 * (static_cast<double>(rep.max_map_second_half) / rep.max_map_first_half - 1.0)
          : 0.0;
  std::cout << std::fixed << "\nscans " << rep.scans << ", posed " << rep.posed << ", degenerate "
            << rep.degenerate << ", resets " << rep.resets << ", rejected " << rep.rejected << "\n";
  std::cout << std::setprecision(2) << "distance driven " << rep.distance / 1000.0
            << " km, farthest from the start " << std::setprecision(0)
            << rep.max_distance_from_start << " m, left the " << rep.map_radius << " m map radius "
            << rep.radius_crossings << " times\n";
  std::cout << "map points: max " << rep.max_map_first_half << " in the first half, "
            << rep.max_map_second_half << " in the second (" << std::showpos << std::setprecision(1)
            << growth_pct << std::noshowpos << " %); voxels max " << rep.max_voxels_first_half
            << " / " << rep.max_voxels_second_half << "; LRU bound " << rep.map_capacity_points
            << " points\n";
  if (config.mode == ppf::Mode::kPpf) {
    std::cout << "plane patches: max " << rep.max_patches_first_half << " in the first half, "
              << rep.max_patches_second_half << " in the second (patch radius "
              << config.ppf.patch_radius << " m)\n";
  }
  std::cout << std::setprecision(1) << "VmRSS: " << rep.rss_start_mb << " MB at the start, "
            << rep.rss_half_mb << " MB at half time, max " << rep.rss_max_second_half_mb
            << " MB in the second half (growth " << std::showpos
            << rep.rss_max_second_half_mb - rep.rss_half_mb << std::noshowpos << " MB), "
            << rep.rss_end_mb << " MB at the end\n";
  if (rep.ape.ok) {
    std::cout << std::setprecision(3) << "APE (SE(3)-aligned) rmse " << rep.ape.stats.rmse
              << " m, max " << rep.ape.stats.max << " m over a " << std::setprecision(0)
              << rep.path_length << " m path (" << std::setprecision(3) << rep.ApePercent()
              << " %)\n";
  } else {
    std::cout << "APE: " << rep.ape.error << "\n";
  }
  if (rep.ape_posyaw.ok) {
    std::cout << std::setprecision(3) << "APE (position+yaw-aligned) rmse "
              << rep.ape_posyaw.stats.rmse << " m, max " << rep.ape_posyaw.stats.max << " m ("
              << rep.ApePosYawPercent() << " %)\n";
  } else {
    std::cout << "APE (position+yaw-aligned): " << rep.ape_posyaw.error << "\n";
  }
  if (rep.gravity.ok) {
    std::cout << ppf::FormatGravityLines(rep.gravity, opts.tilt_after);
  }
  std::cout << std::setprecision(0) << "wall time " << rep.wall_s << " s (simulator "
            << rep.sim_wall_s << " s)\n";
}

}  // namespace

int main(int argc, char** argv) {
  Cli cli = ParseArgs(argc, argv);
  const ppf::Config config = LoadConfig(&cli);
  PrintHeader(cli, config);
  ppf::tools::EnduranceReport rep;
  try {
    rep = ppf::tools::RunEndurance(cli.opts, config, PrintRow);
  } catch (const std::exception& e) {
    Fail(e.what());
  }
  PrintSummary(rep, config, cli.opts);
  return 0;
}
