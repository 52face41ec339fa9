// ppf_compare: kNN mode vs PPF mode of the same pipeline on the same simulated sequences, in one
// run: stage timings, throughput, local map size, APE/RPE, and the issue's targets.
//
//   ppf_compare                    # full: 60 s urban HDL-64 / urban HDL-32 / indoor VLP-16 / park HDL-32
//   ppf_compare --short            # CI: shorter sequences, same table
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "ppf_core/config_yaml.hpp"
#include "ppf_core/evaluation.hpp"
#include "ppf_tools/offline_runner.hpp"
#include "ppf_tools/scan_stats.hpp"

#ifndef PPF_DEFAULT_CONFIG_DIR
#define PPF_DEFAULT_CONFIG_DIR "config"
#endif

namespace fs = std::filesystem;

namespace {

constexpr const char* kUsage = R"(usage: ppf_compare [options]

Runs --mode knn and --mode ppf on the same simulated sequences (generated with ppf_sim on first
use) and prints one table: stage timings, scans per second, local map size, APE/RPE.

  --short               CI form: shorter sequences (default durations 60 s -> 10 s)
  --sequences LIST      comma-separated scene:lidar pairs
                        (default: urban:hdl64,urban:hdl32,indoor:vlp16,park:hdl32)
  --duration S          sequence length in seconds (default 60, --short 10)
  --workdir DIR         where sequences are generated/reused (default: out/compare)
  --config-dir DIR      LiDAR presets <lidar>.yaml (default: the repository's config/)
  --threads N           OpenMP threads for the core (default: all cores)
  -h, --help            this text
)";

struct Sequence {
  std::string scene, lidar;
};

struct ModeResult {
  ppf::tools::RunSummary summary;
  ppf::EvalResult ape, rpe;
  double path_length = 0.0;
};

[[noreturn]] void Fail(const std::string& msg) {
  std::cerr << "ppf_compare: " << msg << "\n";
  std::exit(1);
}

std::vector<Sequence> ParseSequences(const std::string& list) {
  std::vector<Sequence> out;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto colon = item.find(':');
    if (colon == std::string::npos) Fail("sequence '" + item + "' is not scene:lidar");
    out.push_back({item.substr(0, colon), item.substr(colon + 1)});
  }
  return out;
}

std::string EnsureSequence(const Sequence& seq, double duration, const std::string& workdir) {
  std::ostringstream name;
  name << seq.scene << "_" << seq.lidar << "_" << static_cast<int>(duration) << "s";
  const fs::path dir = fs::path(workdir) / name.str();
  if (fs::exists(dir / "metadata.yaml") && fs::exists(dir / "groundtruth.tum")) return dir.string();
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());
  std::ostringstream cmd;
  cmd << "ppf_sim --scene " << seq.scene << " --lidar " << seq.lidar << " --duration " << duration
      << " --seed 1 --storage mcap --out '" << dir.string() << "' > '" << dir.string()
      << ".sim.log' 2>&1";
  std::cerr << "ppf_compare: generating " << name.str() << " with ppf_sim...\n";
  if (std::system(cmd.str().c_str()) != 0) {
    Fail("ppf_sim failed for " + name.str() + " (see " + dir.string() + ".sim.log)");
  }
  return dir.string();
}

ModeResult RunMode(const std::string& bag, const ppf::Config& base, ppf::Mode mode,
                   const ppf::Trajectory& gt) {
  ppf::Config config = base;
  config.mode = mode;
  ModeResult out;
  const auto run = ppf::tools::RunOffline(bag, config);
  out.summary = ppf::tools::Summarize(run.results, run.wall_s);
  ppf::EvalOptions eval;
  eval.align = ppf::Alignment::kSE3;
  out.ape = ppf::ComputeApe(gt, run.trajectory, eval);
  out.rpe = ppf::ComputeRpe(gt, run.trajectory, eval);
  out.path_length = ppf::PathLength(gt);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  bool short_form = false;
  std::string sequences = "urban:hdl64,urban:hdl32,indoor:vlp16,park:hdl32";
  double duration = -1.0;
  std::string workdir = "out/compare";
  std::string config_dir = PPF_DEFAULT_CONFIG_DIR;
  int threads = -1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) Fail("missing value after " + a);
      return argv[++i];
    };
    if (a == "-h" || a == "--help") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--short") {
      short_form = true;
    } else if (a == "--sequences") {
      sequences = value();
    } else if (a == "--duration") {
      duration = std::atof(value().c_str());
    } else if (a == "--workdir") {
      workdir = value();
    } else if (a == "--config-dir") {
      config_dir = value();
    } else if (a == "--threads") {
      threads = std::atoi(value().c_str());
    } else {
      Fail("unknown argument '" + a + "' (see --help)");
    }
  }
  if (duration <= 0) duration = short_form ? 10.0 : 60.0;

  struct Row {
    Sequence seq;
    ModeResult knn, ppf;
  };
  std::vector<Row> rows;
  for (const auto& seq : ParseSequences(sequences)) {
    const std::string bag = EnsureSequence(seq, duration, workdir);
    ppf::Config config;
    const std::string preset = config_dir + "/" + seq.lidar + ".yaml";
    const auto report = ppf::LoadConfigYaml(preset, &config);
    if (!report.ok) Fail(preset + ": " + report.error);
    // The simulated robot's calibration (its T_imu_lidar) on top of the LiDAR preset.
    const auto calib = ppf::LoadConfigYaml(bag + "/calibration.yaml", &config);
    if (!calib.ok) Fail(bag + "/calibration.yaml: " + calib.error);
    if (threads >= 0) config.num_threads = threads;
    ppf::Trajectory gt;
    std::string error;
    if (!ppf::ReadTum(bag + "/groundtruth.tum", &gt, &error)) Fail(error);
    std::cerr << "ppf_compare: " << seq.scene << "/" << seq.lidar << ": knn...\n";
    Row row{seq, RunMode(bag, config, ppf::Mode::kKnn, gt), {}};
    std::cerr << "ppf_compare: " << seq.scene << "/" << seq.lidar << ": ppf...\n";
    row.ppf = RunMode(bag, config, ppf::Mode::kPpf, gt);
    rows.push_back(row);
  }

  std::cout << "\nkNN vs PPF, " << duration << " s sequences (mean per scan; ms; map in points)\n";
  std::cout << std::left << std::setw(15) << "sequence" << std::setw(6) << "mode" << std::right
            << std::setw(9) << "scans/s" << std::setw(8) << "total" << std::setw(8) << "ppf"
            << std::setw(8) << "resid" << std::setw(8) << "update" << std::setw(8) << "map-ins"
            << std::setw(10) << "map pts" << std::setw(9) << "skel pts" << std::setw(9) << "APE m"
            << std::setw(8) << "APE %" << std::setw(9) << "RPE m" << "\n";
  auto print = [](const std::string& name, const char* mode, const ModeResult& m) {
    const auto& s = m.summary;
    std::cout << std::left << std::setw(15) << name << std::setw(6) << mode << std::right
              << std::fixed << std::setprecision(1) << std::setw(9) << s.scans_per_s
              << std::setprecision(2) << std::setw(8) << s.mean.total << std::setw(8) << s.mean.ppf
              << std::setw(8) << s.mean.residuals << std::setw(8) << s.mean.update << std::setw(8)
              << s.mean.map_insert << std::setprecision(0) << std::setw(10) << s.mean_map_size
              << std::setw(9) << s.mean_skeleton_points << std::setprecision(3) << std::setw(9)
              << (m.ape.ok ? m.ape.stats.rmse : -1.0) << std::setprecision(2) << std::setw(8)
              << (m.ape.ok && m.path_length > 0 ? 100.0 * m.ape.stats.rmse / m.path_length : -1.0)
              << std::setprecision(3) << std::setw(9) << (m.rpe.ok ? m.rpe.stats.rmse : -1.0)
              << "\n";
  };
  bool all_ok = true;
  std::ostringstream targets;
  for (const auto& r : rows) {
    const std::string name = r.seq.scene + "/" + r.seq.lidar;
    print(name, "knn", r.knn);
    print(name, "ppf", r.ppf);
    const double speedup = r.knn.summary.scans_per_s > 0 ? r.ppf.summary.scans_per_s / r.knn.summary.scans_per_s : 0;
    const double resid = r.ppf.summary.mean.residuals > 0 ? r.knn.summary.mean.residuals / r.ppf.summary.mean.residuals : 0;
    const double map = r.knn.summary.mean_map_size > 0 ? r.ppf.summary.mean_map_size / r.knn.summary.mean_map_size : 0;
    const double ape = r.knn.ape.ok && r.knn.ape.stats.rmse > 0 && r.ppf.ape.ok ? r.ppf.ape.stats.rmse / r.knn.ape.stats.rmse : 0;
    std::cout << std::left << std::setw(15) << "" << std::setw(6) << "ratio" << std::right
              << std::setprecision(2) << std::setw(8) << speedup << "x" << std::setw(24) << ""
              << "resid " << resid << "x, map " << std::setprecision(0) << 100 * map << "%, APE "
              << std::setprecision(2) << ape << "x\n";
    // Targets of the issue (beat the paper): checked on HDL-64 for speed, everywhere for map/APE.
    auto check = [&](const std::string& what, bool ok) {
      targets << "  " << (ok ? "met   " : "MISSED") << "  " << name << ": " << what << "\n";
      all_ok = all_ok && ok;
    };
    if (r.seq.lidar == "hdl64") {
      check("scans/s >= 2x kNN (" + std::to_string(speedup) + "x)", speedup >= 2.0);
      check("residuals >= 4x faster (" + std::to_string(resid) + "x)", resid >= 4.0);
    }
    check("local map <= 36% of kNN (" + std::to_string(100 * map) + "%)", map <= 0.36);
    check("APE <= kNN + 5% (" + std::to_string(ape) + "x)", ape > 0 && ape <= 1.05);
  }
  std::cout << "\ntargets:\n" << targets.str();
  std::cout << (all_ok ? "all targets met\n" : "some targets missed\n");
  return 0;  // a benchmark reports; the test suite asserts bounds separately
}
