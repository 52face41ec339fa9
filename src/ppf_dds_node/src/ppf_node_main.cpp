// ppf_node --config FILE: LiDAR-inertial odometry on plain DDS (ROS 2 compatible topics).
#include <signal.h>

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include "ppf_dds_node/logging.hpp"
#include "ppf_dds_node/node_config.hpp"
#include "ppf_dds_node/ppf_node.hpp"

namespace {

void Usage(const char* argv0) {
  std::fprintf(stderr,
               "usage: %s [--config FILE] [--calibration FILE] [--domain ID]\n"
               "  --config FILE       node YAML (every key optional, see config/node.yaml)\n"
               "  --calibration FILE  core YAML layered over core.config_file (e.g. the robot's\n"
               "                      T_imu_lidar); overrides core.calibration_file\n"
               "  --domain ID         overrides dds.domain_id\n"
               "SIGINT/SIGTERM stop it (trajectory.tum_file and outputs.map_file written);\n"
               "SIGUSR1 writes outputs.map_file and it goes on.\n",
               argv0);
}

struct Args {
  std::string config_file;
  std::string calibration_file;
  int domain_override = -1;
};

// Returns -1 to go on, else the exit code (0 for --help, 2 for a bad argument).
int ParseArgs(int argc, char** argv, Args* args) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--config" && i + 1 < argc) {
      args->config_file = argv[++i];
    } else if (a == "--calibration" && i + 1 < argc) {
      args->calibration_file = argv[++i];
    } else if (a == "--domain" && i + 1 < argc) {
      args->domain_override = std::atoi(argv[++i]);
    } else if (a == "-h" || a == "--help") {
      Usage(argv[0]);
      return 0;
    } else {
      Usage(argv[0]);
      return 2;
    }
  }
  return -1;
}

// The node config with the command line's overrides; false (logged) if the file is refused.
bool LoadConfig(const Args& args, ppf::dds::NodeConfig* config) {
  using ppf::dds::Level;
  using ppf::dds::Log;
  if (!args.config_file.empty()) {
    const auto report = ppf::dds::LoadNodeConfig(args.config_file, config);
    for (const auto& w : report.warnings) Log(Level::kWarn, "config: " + w);
    if (!report.ok) {
      Log(Level::kError, "config: " + report.error);
      return false;
    }
  }
  if (args.domain_override >= 0) config->participant.domain_id = args.domain_override;
  if (!args.calibration_file.empty()) config->core_calibration_file = args.calibration_file;
  return true;
}

// libgomp reads OMP_WAIT_POLICY when it is loaded, before main: to apply the configured policy
// the process re-executes itself once with it set (same pid, nothing created yet). Returns only
// if that was not needed or failed (logged).
void ApplyOmpWaitPolicy(const std::string& policy, char** argv) {
  if (policy.empty() || std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  setenv("OMP_WAIT_POLICY", policy.c_str(), 1);
  // The real path, not /proc/self/exe: the process name (ps, pgrep) stays "ppf_node".
  char self[4096];
  const ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n > 0) {
    self[n] = '\0';
    execv(self, argv);
  }
  ppf::dds::Log(ppf::dds::Level::kWarn,
                std::string("could not apply OMP_WAIT_POLICY (re-exec failed: ") +
                    std::strerror(errno) + "); continuing with the default");
}

// The end-of-run summary: a readable block on stderr, one machine-readable line on stdout.
void PrintSummary(const ppf::dds::NodeSummary& s) {
  using ppf::dds::Level;
  using ppf::dds::Log;
  const std::string line = ppf::dds::PpfNode::FormatSummary(s);
  Log(Level::kInfo, "summary: scans processed " + std::to_string(s.scans_processed) + ", dropped " +
                        std::to_string(s.scans_dropped) + ", malformed " +
                        std::to_string(s.scans_malformed + s.imu_malformed) +
                        "; latency/core/overhead p50-p99 ms in the SUMMARY line");
  std::fprintf(
      stderr,
      "ppf_node summary\n"
      "  scans      received %llu  processed %llu  odometry %llu  dropped %llu  "
      "malformed %llu  rejected %llu  initializing %llu  resets %llu\n"
      "  imu        received %llu  malformed %llu  overflow %llu\n"
      "  input      lost scans %llu  lost imu %llu  imu gaps bridged %llu (longest %.3f s)\n"
      "  imu loss   LiDAR-only fallbacks %llu (%llu scans)\n"
      "  no imu     LiDAR-only scans %llu  LIO started late %llu\n"
      "  stalls     points %llu  imu %llu  (publisher matched, data stopped for "
      "diagnostics.stall_warn_s)\n"
      "  latency    p50 %.2f ms  p99 %.2f ms  (DDS receive -> odometry published)\n"
      "  core       p50 %.2f ms  p99 %.2f ms\n"
      "  overhead   p50 %.2f ms  p99 %.2f ms  (latency - core - waits for IMU / busy core)\n",
      (unsigned long long)s.scans_received, (unsigned long long)s.scans_processed,
      (unsigned long long)s.odometry_published, (unsigned long long)s.scans_dropped,
      (unsigned long long)s.scans_malformed, (unsigned long long)s.scans_rejected,
      (unsigned long long)s.scans_initializing, (unsigned long long)s.resets,
      (unsigned long long)s.imu_received, (unsigned long long)s.imu_malformed,
      (unsigned long long)s.imu_overflow, (unsigned long long)s.scans_lost,
      (unsigned long long)s.imu_lost, (unsigned long long)s.imu_gaps_bridged, s.imu_gap_max_s,
      (unsigned long long)s.imu_fallbacks, (unsigned long long)s.imu_fallback_scans,
      (unsigned long long)s.lidar_only_scans, (unsigned long long)s.lio_started_late,
      (unsigned long long)s.points_stalls, (unsigned long long)s.imu_stalls, s.latency_p50_ms,
      s.latency_p99_ms, s.core_p50_ms, s.core_p99_ms, s.overhead_p50_ms, s.overhead_p99_ms);
  std::printf("PPF_NODE_SUMMARY %s\n", line.c_str());
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  using ppf::dds::Level;
  using ppf::dds::Log;
  Args args;
  const int parsed = ParseArgs(argc, argv, &args);
  if (parsed >= 0) return parsed;
  ppf::dds::NodeConfig config;
  if (!LoadConfig(args, &config)) return 2;
  ApplyOmpWaitPolicy(config.omp_wait_policy, argv);

  // Signals are handled by a dedicated thread (sigwait), so stop() never runs in a signal handler.
  // SIGUSR1 saves the map (outputs.map_file) and the node goes on.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGUSR1);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);  // inherited by every thread created from here on

  ppf::dds::PpfNode node(config);
  std::string error;
  if (!node.init(&error)) {
    Log(Level::kError, "ppf_node: " + error);
    return 1;
  }
  std::printf("PPF_NODE_READY domain=%d\n", config.participant.domain_id);
  std::fflush(stdout);

  std::thread signal_thread([&node, set] {
    int sig = 0;
    while (sigwait(&set, &sig) == 0 && sig == SIGUSR1) node.SaveMap();
    if (sig != 0) Log(Level::kInfo, std::string("ppf_node: ") + strsignal(sig) + ", stopping");
    node.stop();
  });
  node.run();
  // run() may also end without a signal (never today); unblock the watcher in that case.
  pthread_kill(signal_thread.native_handle(), SIGTERM);
  signal_thread.join();

  PrintSummary(node.summary());
  return 0;
}
