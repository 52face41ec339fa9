// ppf_bench: the speed and memory table. Both modes on simulated urban sequences of every LiDAR
// class, each run as its own ppf_offline process (so its peak RSS is its own), next to a read-only
// pass over the same bag (what reading the bag alone costs); optionally callgrind instructions
// per scan of the core alone.
//
//   ppf_bench                     # 20 s urban VLP-16 / HDL-32 / HDL-64 / OS1-128, 2 threads
//   ppf_bench --short             # CI: 5 s sequences, same table, checked, no time asserted
//   ppf_bench --callgrind         # + Ir per scan (1 thread, ProcessOne + AddScan only)
//   ppf_bench --peers DIR         # + the peer odometries' runners in DIR, same bags and threads
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "ppf_tools/study.hpp"

#ifndef PPF_DEFAULT_CONFIG_DIR
#define PPF_DEFAULT_CONFIG_DIR "config"
#endif

namespace fs = std::filesystem;

namespace {

constexpr const char* kDefaultSequences = "urban:vlp16,urban:hdl32,urban:hdl64,urban:os1_128";
constexpr double kDefaultDuration = 20.0;
constexpr double kShortDuration = 5.0;
constexpr int kDefaultThreads = 2;  // the targets are for 2 threads

// Stage columns of ppf_offline's --stats CSV, in table order.
constexpr const char* kStages[] = {"t_preprocess_ms", "t_deskew_ms",    "t_downsample_ms",
                                   "t_ppf_ms",        "t_residuals_ms", "t_update_ms",
                                   "t_map_insert_ms", "t_total_ms"};
constexpr const char* kStageHeads[] = {"preproc", "deskew", "downsmp", "ppf",
                                       "resid",   "update", "map-ins", "total"};
constexpr int kNumStages = 8;

[[noreturn]] void Fail(const std::string& msg) {
  std::cerr << "ppf_bench: " << msg << "\n";
  std::exit(1);
}

// The directory of this executable: ppf_offline is installed next to it.
std::string SelfDir() {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string(".") : self.parent_path().string();
}

struct ChildResult {
  int exit_code = -1;
  double max_rss_mb = 0.0;  // the child's own peak resident set (ru_maxrss)
  double wall_s = 0.0;
};

// Runs argv[0] (a path, or a name looked up in PATH) with stdout and stderr into `log`, waits,
// and takes the child's own rusage: wait4 gives the peak RSS of that process alone.
ChildResult RunChild(const std::vector<std::string>& args, const std::string& log) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  ChildResult r;
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid < 0) Fail("fork failed");
  if (pid == 0) {
    if (std::freopen(log.c_str(), "w", stdout) == nullptr) std::_Exit(126);
    ::dup2(STDOUT_FILENO, STDERR_FILENO);
    ::execvp(argv[0], argv.data());
    // Said in the log the caller names: a tool not on PATH (an unsourced workspace) is the
    // usual cause, and an empty log would say nothing.
    std::fprintf(stderr, "ppf_bench: cannot run %s: %s\n", argv[0], std::strerror(errno));
    std::fflush(stderr);
    std::_Exit(127);
  }
  int status = 0;
  struct rusage ru {};
  if (::wait4(pid, &status, 0, &ru) != pid) Fail("wait4 failed");
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.max_rss_mb = static_cast<double>(ru.ru_maxrss) / 1024.0;  // kB on Linux
  return r;
}

std::string Quote(const std::vector<std::string>& args) {
  std::string s;
  for (const auto& a : args) s += (s.empty() ? "" : " ") + ("'" + a + "'");
  return s;
}

// Per-scan stage times of the scans with a pose, from a --stats CSV.
struct StageSamples {
  std::vector<double> stage[kNumStages];
  size_t scans = 0;      // every scan result
  size_t with_pose = 0;  // scans with pose_valid
  double core_ms = 0.0;  // sum of t_total_ms over every scan
};

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        cur += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cur += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

bool ReadStats(const std::string& path, StageSamples* s, std::string* error) {
  std::ifstream in(path);
  std::string line;
  if (!std::getline(in, line)) {
    *error = path + ": empty or missing";
    return false;
  }
  const auto head = SplitCsv(line);
  auto column = [&](const std::string& name) {
    const auto it = std::find(head.begin(), head.end(), name);
    return it == head.end() ? -1 : static_cast<int>(it - head.begin());
  };
  int cols[kNumStages];
  for (int k = 0; k < kNumStages; ++k) {
    cols[k] = column(kStages[k]);
    if (cols[k] < 0) {
      *error = path + ": no column " + kStages[k];
      return false;
    }
  }
  const int pose_col = column("pose_valid");
  const int total_col = column("t_total_ms");
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    const auto f = SplitCsv(line);
    if (static_cast<int>(f.size()) != static_cast<int>(head.size())) {
      *error = path + ": a row with " + std::to_string(f.size()) + " fields";
      return false;
    }
    ++s->scans;
    s->core_ms += std::atof(f[total_col].c_str());
    if (f[pose_col] != "1") continue;
    ++s->with_pose;
    for (int k = 0; k < kNumStages; ++k) s->stage[k].push_back(std::atof(f[cols[k]].c_str()));
  }
  return true;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Nearest rank: the smallest sample with at least 95 % of the samples at or below it.
double P95(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t rank = static_cast<size_t>(std::ceil(0.95 * static_cast<double>(v.size())));
  return v[std::max<size_t>(rank, 1) - 1];
}

// Total Ir of a callgrind output file (its "totals:" line, else "summary:").
bool CallgrindTotal(const std::string& path, double* ir) {
  std::ifstream in(path);
  std::string line;
  bool found = false;
  while (std::getline(in, line)) {
    for (const char* key : {"totals:", "summary:"}) {
      if (line.rfind(key, 0) == 0) {
        *ir = std::atof(line.c_str() + std::string(key).size());
        found = true;
      }
    }
  }
  return found;
}

struct ModeRow {
  std::string sequence, mode;
  StageSamples samples;
  double rss_mb = 0.0, read_rss_mb = 0.0;
  double ir_per_scan = -1.0;  // < 0: not measured
};

std::string Cell(double med, double p95) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(2) << med << "/" << p95;
  return os.str();
}

std::string Table(const std::vector<ModeRow>& rows) {
  // Every column after the first starts with a space, so a wide value never runs into the next.
  auto col = [](std::ostream& os, int width) -> std::ostream& {
    return os << ' ' << std::setw(width - 1);
  };
  std::ostringstream os;
  os << std::left << std::setw(14) << "sequence";
  col(os, 5) << "mode" << std::right;
  col(os, 6) << "scans";
  for (const char* h : kStageHeads) col(os, 14) << h;
  col(os, 9) << "scans/s";
  col(os, 9) << "RSS MB";
  col(os, 9) << "read MB";
  col(os, 9) << "+MB";
  col(os, 10) << "MIr/scan";
  os << "\n";
  for (const auto& r : rows) {
    os << std::left << std::setw(14) << r.sequence;
    col(os, 5) << r.mode << std::right;
    col(os, 6) << r.samples.with_pose;
    for (int k = 0; k < kNumStages; ++k) {
      col(os, 14) << Cell(Median(r.samples.stage[k]), P95(r.samples.stage[k]));
    }
    const double scans_per_s =
        r.samples.core_ms > 0 ? 1000.0 * static_cast<double>(r.samples.scans) / r.samples.core_ms
                              : 0.0;
    os << std::fixed << std::setprecision(1);
    col(os, 9) << scans_per_s;
    col(os, 9) << r.rss_mb;
    col(os, 9) << r.read_rss_mb;
    col(os, 9) << (r.rss_mb - r.read_rss_mb);
    if (r.ir_per_scan >= 0) {
      col(os, 10) << std::setprecision(2) << r.ir_per_scan / 1e6;
    } else {
      col(os, 10) << "-";
    }
    os << "\n";
  }
  return os.str();
}

bool ParseNumber(const std::string& s, double* v) {
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return !s.empty() && *end == '\0' && std::isfinite(*v);
}

// Reads the printed table back: every row of every sequence and mode is there, every number
// parses, p95 >= median, the RSS difference is what its columns say. Times are not judged.
bool CheckTable(const std::string& table, const std::vector<std::string>& sequences, bool callgrind,
                std::string* error) {
  std::istringstream in(table);
  std::string line;
  std::getline(in, line);  // header
  std::map<std::string, int> seen;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    std::istringstream ls(line);
    std::vector<std::string> f;
    for (std::string w; ls >> w;) f.push_back(w);
    const size_t expected = 3 + kNumStages + 5;
    auto bad = [&](const std::string& why) {
      *error = "row " + std::to_string(n) + " (" + line + "): " + why;
      return false;
    };
    if (f.size() != expected) return bad(std::to_string(f.size()) + " fields");
    if (f[1] != "knn" && f[1] != "ppf") return bad("mode '" + f[1] + "'");
    ++seen[f[0] + " " + f[1]];
    double v = 0;
    if (!ParseNumber(f[2], &v) || v < 1) return bad("no scan with a pose");
    for (int k = 0; k < kNumStages; ++k) {
      const std::string& c = f[3 + k];
      const auto slash = c.find('/');
      double med = 0, p95 = 0;
      if (slash == std::string::npos || !ParseNumber(c.substr(0, slash), &med) ||
          !ParseNumber(c.substr(slash + 1), &p95)) {
        return bad(std::string(kStageHeads[k]) + " '" + c + "' is not median/p95");
      }
      if (med < 0 || p95 + 1e-9 < med) return bad(std::string(kStageHeads[k]) + ": p95 < median");
    }
    double sps = 0, rss = 0, read = 0, plus = 0;
    const size_t b = 3 + kNumStages;
    if (!ParseNumber(f[b], &sps) || sps <= 0) return bad("scans/s");
    if (!ParseNumber(f[b + 1], &rss) || rss <= 0) return bad("RSS");
    if (!ParseNumber(f[b + 2], &read) || read <= 0) return bad("read RSS");
    if (!ParseNumber(f[b + 3], &plus) || std::abs(rss - read - plus) > 0.11) return bad("+MB");
    if (callgrind) {
      if (!ParseNumber(f[b + 4], &v) || v <= 0) return bad("Ir per scan");
    } else if (f[b + 4] != "-") {
      return bad("Ir per scan without --callgrind");
    }
  }
  for (const auto& s : sequences) {
    for (const char* m : {"knn", "ppf"}) {
      const auto it = seen.find(s + " " + m);
      if (it == seen.end() || it->second != 1) {
        *error = "expected exactly one row for " + s + " " + m;
        return false;
      }
    }
  }
  if (n != static_cast<int>(2 * sequences.size())) {
    *error = std::to_string(n) + " rows for " + std::to_string(sequences.size()) + " sequences";
    return false;
  }
  return true;
}

// ---- Peer odometries (same-run references) ---------------------------------------------------
// The peers are other projects' code built outside the repository; they are only ever run as
// child processes through their runner commands, so nothing of theirs is linked or copied here.
struct PeerSpec {
  const char* label;   // as printed
  const char* runner;  // <runner> in DIR/build/<name>/<runner>, DIR/<runner>, DIR/<runner>.py
  const char* name;
  const char* probe;  // Python module the .py runner needs
};
constexpr PeerSpec kPeers[] = {
    {"RKO-LIO", "rko_lio_runner", "rko_lio", "rko_lio.rko_lio_pybind"},
    {"KISS-ICP", "kiss_icp_runner", "kiss_icp", "kiss_icp.pybind.kiss_icp_pybind"},
};

bool Executable(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
}

// The command prefix that runs `peer` from `dir`, or empty with *why saying what is missing:
// setup_peers.sh's wrapper (DIR = its PEERS_DIR), an executable runner in DIR, or the runner's
// Python source in DIR when python3 can import the peer's built module.
std::vector<std::string> FindPeerRunner(const std::string& dir, const PeerSpec& peer,
                                        const std::string& log, std::string* why) {
  const fs::path d(dir);
  for (const fs::path& p : {d / "build" / peer.name / peer.runner, d / peer.runner}) {
    if (Executable(p)) return {p.string()};
  }
  const fs::path py = d / (std::string(peer.runner) + ".py");
  std::error_code ec;
  if (!fs::is_regular_file(py, ec)) {
    *why = std::string("not found in ") + dir + " (no build/" + peer.name + "/" + peer.runner +
           ", " + peer.runner + " or " + peer.runner + ".py)";
    return {};
  }
  const std::vector<std::string> probe = {"python3", "-c", std::string("import ") + peer.probe};
  if (RunChild(probe, log).exit_code != 0) {
    *why = py.string() + " found, but its dependencies are not installed (python3 cannot import " +
           peer.probe + "; build them with setup_peers.sh and pass its PEERS_DIR)";
    return {};
  }
  return {"python3", py.string()};
}

// Median of the first column of a runner's --times file ('#' lines are comments): the wall ms
// inside the peer's registration call per scan. False with *error if no row parses.
bool ReadPeerTimes(const std::string& path, std::vector<double>* ms, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = path + ": missing";
    return false;
  }
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string first;
    double v = 0;
    ls >> first;
    if (!ParseNumber(first, &v) || v < 0) {
      *error = path + ":" + std::to_string(n) + ": '" + first + "' is not a time in ms";
      return false;
    }
    ms->push_back(v);
  }
  if (ms->empty()) {
    *error = path + ": no scan timed";
    return false;
  }
  return true;
}

// T_imu_lidar of a simulated sequence as the runners take it (translation, yaw in degrees), from
// its calibration.yaml. The runners model yaw only; the sim's small roll and pitch are dropped.
bool ReadExtrinsic(const std::string& calibration, std::vector<std::string>* out) {
  std::ifstream in(calibration);
  std::string line;
  std::vector<double> t, q;
  auto numbers = [](const std::string& l) {
    std::vector<double> v;
    const auto a = l.find('['), b = l.find(']');
    if (a == std::string::npos || b == std::string::npos || b < a) return v;
    std::string body = l.substr(a + 1, b - a - 1);
    std::replace(body.begin(), body.end(), ',', ' ');
    std::istringstream ls(body);
    for (double x; ls >> x;) v.push_back(x);
    return v;
  };
  bool in_block = false;
  while (std::getline(in, line)) {
    if (line.find("T_imu_lidar:") != std::string::npos) {
      in_block = true;
      continue;
    }
    if (!in_block) continue;
    if (line.find("translation:") != std::string::npos) t = numbers(line);
    if (line.find("quaternion_wxyz:") != std::string::npos) q = numbers(line);
    if (t.size() == 3 && q.size() == 4) break;
  }
  if (t.size() != 3 || q.size() != 4) return false;
  const double yaw =
      std::atan2(2.0 * (q[0] * q[3] + q[1] * q[2]), 1.0 - 2.0 * (q[2] * q[2] + q[3] * q[3])) *
      180.0 / M_PI;
  out->clear();
  for (double v : {t[0], t[1], t[2], yaw}) {
    std::ostringstream os;
    os << std::setprecision(9) << v;
    out->push_back(os.str());
  }
  return true;
}

// The same sequence (same ppf_sim options and seed, so the same data) in a rosbag2 sqlite3
// container, which is what the runners read; generated once next to the MCAP one. "" if ppf_sim
// failed, and *why says how (its log's last line) and where its log is.
std::string EnsureSqliteSequence(const ppf::tools::SequenceSpec& seq, const std::string& mcap_bag,
                                 double duration, std::string* why) {
  const std::string dir = mcap_bag + "_sqlite3";
  const std::string sim_log = dir + ".sim.log";
  std::cerr << "ppf_bench: " << seq.Name() << ": sqlite3 copy for the peers...\n";
  const bool ok = ppf::tools::GenerateSequenceOnce(dir, [&](const std::string& out) {
    std::ostringstream d;
    d << duration;
    std::vector<std::string> args = {"ppf_sim", "--scene",    seq.scene, "--lidar",
                                     seq.lidar, "--duration", d.str(),   "--seed",
                                     "1",       "--storage",  "sqlite3"};
    std::istringstream extra(seq.sim_extra);
    for (std::string w; extra >> w;) args.push_back(w);
    args.push_back("--out");
    args.push_back(out);
    return RunChild(args, sim_log).exit_code == 0;
  });
  if (ok) return dir;
  *why = ppf::tools::LastLogLine(sim_log) + "; see " + sim_log;
  return std::string();
}

struct PeerRow {
  std::string sequence, peer;
  size_t scans = 0;
  double median_ms = 0.0;
};

// The peers' medians next to ours: ours/peer < 1 means ours is faster. Our time is the core's
// t_total_ms (decoded scan in, pose out); a runner's is the registration call on a decoded scan.
std::string PeerTable(const std::vector<PeerRow>& peers, const std::vector<ModeRow>& ours) {
  std::ostringstream os;
  os << std::left << std::setw(14) << "sequence" << ' ' << std::setw(9) << "peer" << std::right
     << std::setw(7) << "scans" << std::setw(11) << "median ms" << std::setw(10) << "ppf ms"
     << std::setw(10) << "knn ms" << std::setw(10) << "ppf/peer" << std::setw(10) << "knn/peer"
     << "\n";
  for (const auto& p : peers) {
    double ppf = -1, knn = -1;
    for (const auto& r : ours) {
      if (r.sequence != p.sequence) continue;
      (r.mode == "ppf" ? ppf : knn) = Median(r.samples.stage[kNumStages - 1]);
    }
    os << std::left << std::setw(14) << p.sequence << ' ' << std::setw(9) << p.peer << std::right
       << std::fixed << std::setprecision(2) << std::setw(7) << p.scans << std::setw(11)
       << p.median_ms << std::setw(10) << ppf << std::setw(10) << knn << std::setw(10)
       << (p.median_ms > 0 ? ppf / p.median_ms : 0.0) << std::setw(10)
       << (p.median_ms > 0 ? knn / p.median_ms : 0.0) << "\n";
  }
  return os.str();
}

void PrintHelp() {
  std::cout
      << "usage: ppf_bench [options]\n\n"
         "Runs ppf_offline --mode knn and --mode ppf as child processes on simulated\n"
         "sequences (generated with ppf_sim on first use), plus ppf_offline --read-only\n"
         "on the same bag, and prints one table per scan with a pose: per-stage median/p95\n"
         "(ms), scans/s (scans / summed core time), peak RSS of each process (MB), that of\n"
         "the read-only pass, their difference, and with --callgrind the instructions per\n"
         "scan of the core (valgrind, 1 thread, ProcessOne + AddScan collected). --short\n"
         "then checks the table (complete, every number parses); no time is asserted.\n"
         "Durations: 20 s, --short 5 s; threads: 2 unless --threads.\n\n"
      << ppf::tools::StudyOptionsHelp(kDefaultSequences)
      << "  --callgrind           also the Ir per scan column (slow: about 50x)\n"
         "  --ppf-offline PATH    the ppf_offline that runs the modes (default: the one next\n"
         "                        to ppf_bench, which always does the read-only pass)\n"
         "  --peers DIR           also run the peer odometries (RKO-LIO, KISS-ICP) on the\n"
         "                        same sequences (a rosbag2 sqlite3 copy, same seed) and\n"
         "                        threads, each as a child process, and print their median\n"
         "                        registration ms per scan (the runner's --times column 1)\n"
         "                        and ours over theirs (ppf/peer, knn/peer: < 1 = ours\n"
         "                        faster). DIR is setup_peers.sh's PEERS_DIR (runners in\n"
         "                        build/<peer>/), or a directory holding the runners\n"
         "                        (rko_lio_runner, kiss_icp_runner, executable or .py run\n"
         "                        with python3). A peer that is missing or whose dependencies\n"
         "                        are not installed gets one line saying so; ours prints\n"
         "                        alone and the exit code does not depend on the peers.\n"
         "  --omp-wait-policy P   passive | active | default: OMP_WAIT_POLICY of every child\n"
         "                        (ours and the peers'); default passive, as the node's\n"
         "                        core.omp_wait_policy; an OMP_WAIT_POLICY already in the\n"
         "                        environment wins; default: each child's own\n"
         "  -h, --help            this text\n";
}

// Instructions per scan with a pose of the core (ProcessOne + AddScan) under callgrind, one
// thread: `args` is the ppf_offline command without its output options, `base` the run's path stem.
double CallgrindIrPerScan(const std::vector<std::string>& args, const std::string& base,
                          const std::string& what) {
  std::string error;
  // One thread: callgrind serialises threads and collects them all, and the core's 1-thread
  // arithmetic is the deterministic one.
  const std::string out = base + ".callgrind.out";
  std::vector<std::string> cg = {"valgrind", "--tool=callgrind", "--callgrind-out-file=" + out,
                                 "--toggle-collect=ppf::LioPpf::Impl::ProcessOne*",
                                 "--toggle-collect=ppf::LioPpf::AddScan*"};
  cg.insert(cg.end(), args.begin(), args.end());
  for (const auto& a : {std::string("--threads"), std::string("1"), std::string("--out"),
                        base + "_cg.tum", std::string("--stats"), base + "_cg.csv"}) {
    cg.push_back(a);
  }
  std::cerr << "ppf_bench: " << what << " under callgrind...\n";
  const auto c = RunChild(cg, base + ".callgrind.log");
  if (c.exit_code != 0) Fail(Quote(cg) + " failed (see " + base + ".callgrind.log)");
  StageSamples cg_samples;
  double ir = 0.0;
  if (!ReadStats(base + "_cg.csv", &cg_samples, &error)) Fail(error);
  if (!CallgrindTotal(out, &ir) || cg_samples.with_pose == 0) Fail(out + ": no total");
  return ir / static_cast<double>(cg_samples.with_pose);
}

// How each mode is run on one sequence.
struct ModeRun {
  std::string ppf_offline;  // the build that runs the modes
  std::string bag, preset;
  int threads = 2;
  bool callgrind = false;
};

// One table row: ppf_offline in `mode` (timed, then under callgrind if asked), its stats read
// back from `base`.csv; `read_rss_mb` is the read-only pass's peak RSS on the same bag.
ModeRow RunMode(const ModeRun& m, const std::string& sequence, const std::string& mode,
                const std::string& base, double read_rss_mb) {
  const std::vector<std::string> args = {m.ppf_offline,
                                         "--bag",
                                         m.bag,
                                         "--config",
                                         m.preset,
                                         "--config",
                                         m.bag + "/calibration.yaml",
                                         "--mode",
                                         mode,
                                         "--quiet"};
  std::vector<std::string> timed = args;
  for (const auto& a : {std::string("--threads"), std::to_string(m.threads), std::string("--out"),
                        base + ".tum", std::string("--stats"), base + ".csv"}) {
    timed.push_back(a);
  }
  std::cerr << "ppf_bench: " << sequence << ": " << mode << "...\n";
  const auto run = RunChild(timed, base + ".log");
  if (run.exit_code != 0) Fail(Quote(timed) + " failed (see " + base + ".log)");
  ModeRow row{sequence, mode, {}, run.max_rss_mb, read_rss_mb, -1.0};
  std::string error;
  if (!ReadStats(base + ".csv", &row.samples, &error)) Fail(error);
  if (m.callgrind) row.ir_per_scan = CallgrindIrPerScan(args, base, sequence + ": " + mode);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  ppf::tools::StudyOptions opts;
  opts.sequences = kDefaultSequences;
  opts.config_dir = PPF_DEFAULT_CONFIG_DIR;
  opts.workdir = "out/bench";
  bool callgrind = false;
  // The read-only pass always uses the ppf_offline installed with this command (the bag reader is
  // the same code in every build); --ppf-offline changes the one that runs the modes, e.g. an
  // older build for a before/after table.
  const std::string reader = SelfDir() + "/ppf_offline";
  std::string ppf_offline = reader;
  std::string peers_dir;
  std::string omp_wait_policy = "passive";
  auto own = [&](int argc_, char** argv_, int* i, std::string* error) {
    const std::string a = argv_[*i];
    if (a == "--callgrind") {
      callgrind = true;
      return 1;
    }
    if (a == "--ppf-offline") {
      if (*i + 1 >= argc_) {
        *error = "missing value after --ppf-offline";
        return -1;
      }
      ppf_offline = argv_[++*i];
      return 1;
    }
    if (a == "--omp-wait-policy") {
      if (*i + 1 >= argc_) {
        *error = "missing value after --omp-wait-policy";
        return -1;
      }
      omp_wait_policy = argv_[++*i];
      if (omp_wait_policy != "passive" && omp_wait_policy != "active" &&
          omp_wait_policy != "default") {
        *error = "--omp-wait-policy: passive, active or default";
        return -1;
      }
      return 1;
    }
    if (a == "--peers") {
      if (*i + 1 >= argc_) {
        *error = "missing value after --peers";
        return -1;
      }
      peers_dir = argv_[++*i];
      return 1;
    }
    return 0;
  };
  bool help = false;
  std::string error;
  if (!ppf::tools::ParseStudyCommandLine(argc, argv, &opts, &help, &error, own)) Fail(error);
  if (help) {
    PrintHelp();
    return 0;
  }
  if (opts.duration <= 0) opts.duration = opts.short_form ? kShortDuration : kDefaultDuration;
  const int threads = opts.threads >= 0 ? opts.threads : kDefaultThreads;
  // Inherited by every child: libgomp reads it when a child starts. Spinning idle workers wait
  // for descheduled ones on a loaded machine; an older --ppf-offline does not set it itself.
  if (omp_wait_policy != "default" && std::getenv("OMP_WAIT_POLICY") == nullptr) {
    setenv("OMP_WAIT_POLICY", omp_wait_policy == "active" ? "ACTIVE" : "PASSIVE", 1);
  }
  std::vector<ppf::tools::SequenceSpec> sequences;
  if (!ppf::tools::ParseSequenceList(opts.sequences, &sequences, &error)) Fail(error);
  const fs::path runs = fs::path(opts.workdir) / "runs";
  fs::create_directories(runs);

  // Which peers can run: one line for each that cannot, printed after our table.
  std::vector<std::string> peer_notes;
  std::vector<std::pair<const PeerSpec*, std::vector<std::string>>> peers;
  for (const auto& peer : kPeers) {
    if (peers_dir.empty()) {
      peer_notes.push_back(std::string("ppf_bench: peer ") + peer.label +
                           ": not run (no --peers DIR)");
      continue;
    }
    std::string why;
    auto cmd = FindPeerRunner(peers_dir, peer,
                              (runs / (std::string(peer.name) + "_probe.log")).string(), &why);
    if (cmd.empty()) {
      peer_notes.push_back(std::string("ppf_bench: peer ") + peer.label + ": " + why);
    } else {
      peers.emplace_back(&peer, cmd);
    }
  }
  std::vector<PeerRow> peer_rows;

  std::vector<ModeRow> rows;
  std::vector<std::string> names;
  for (const auto& seq : sequences) {
    std::string bag;
    try {
      bag = ppf::tools::EnsureSequence(seq, opts.duration, opts.workdir, std::cerr, "ppf_bench: ");
    } catch (const std::exception& e) {
      Fail(e.what());
    }
    names.push_back(seq.Name());
    const std::string preset = opts.config_dir + "/" + seq.lidar + ".yaml";
    if (!fs::exists(preset)) Fail(preset + ": no such preset");
    const std::string stem = (runs / (seq.scene + "_" + seq.lidar)).string();

    std::cerr << "ppf_bench: " << seq.Name() << ": read only...\n";
    const std::vector<std::string> read_args = {reader, "--bag", bag, "--read-only", "--quiet"};
    const auto read = RunChild(read_args, stem + "_read.log");
    if (read.exit_code != 0) Fail(Quote(read_args) + " failed (see " + stem + "_read.log)");

    for (const char* mode : {"knn", "ppf"}) {
      rows.push_back(RunMode({ppf_offline, bag, preset, threads, callgrind}, seq.Name(), mode,
                             stem + "_" + mode, read.max_rss_mb));
    }

    if (peers.empty()) continue;
    std::string why;
    const std::string sqlite_bag = EnsureSqliteSequence(seq, bag, opts.duration, &why);
    if (sqlite_bag.empty()) {
      peer_notes.push_back("ppf_bench: peers on " + seq.Name() +
                           ": not run (ppf_sim --storage sqlite3 failed: " + why + ")");
      continue;
    }
    std::vector<std::string> extrinsic;
    if (!ReadExtrinsic(bag + "/calibration.yaml", &extrinsic)) {
      peer_notes.push_back("ppf_bench: peers on " + seq.Name() + ": no T_imu_lidar in " + bag +
                           "/calibration.yaml, the runners' default extrinsic used");
    }
    for (const auto& [peer, cmd] : peers) {
      const std::string base = stem + "_" + peer->name;
      std::vector<std::string> args = cmd;
      for (const auto& a : {sqlite_bag, base + ".tum", std::string("--threads"),
                            std::to_string(threads), std::string("--times"), base + ".times"}) {
        args.push_back(a);
      }
      if (!extrinsic.empty()) {
        args.push_back("--extrinsic");
        args.insert(args.end(), extrinsic.begin(), extrinsic.end());
      }
      std::cerr << "ppf_bench: " << seq.Name() << ": " << peer->label << "...\n";
      fs::remove(base + ".times");
      const auto run = RunChild(args, base + ".log");
      std::vector<double> ms;
      std::string why;
      if (run.exit_code != 0) {
        peer_notes.push_back(std::string("ppf_bench: peer ") + peer->label + " on " + seq.Name() +
                             ": runner failed (exit " + std::to_string(run.exit_code) + ", see " +
                             base + ".log)");
      } else if (!ReadPeerTimes(base + ".times", &ms, &why)) {
        peer_notes.push_back(std::string("ppf_bench: peer ") + peer->label + " on " + seq.Name() +
                             ": " + why);
      } else {
        peer_rows.push_back({seq.Name(), peer->label, ms.size(), Median(ms)});
      }
    }
  }

  const std::string table = Table(rows);
  std::cout << "\nppf_bench: " << opts.duration << " s sequences, " << threads
            << " core threads; per scan with a pose: stage median/p95 ms; scans/s = scans /"
               " summed core time;\nRSS: peak of the ppf_offline process, read: of ppf_offline"
               " --read-only on the same bag, +MB: the difference"
            << (callgrind ? "; MIr/scan: callgrind, 1 thread, core only" : "") << "\n"
            << table;
  // Our table's check first (it concerns ours alone), then the peers: their outcome never
  // changes the exit code.
  const bool consistent = CheckTable(table, names, callgrind, &error);
  if (consistent) {
    std::cout << "ppf_bench: table complete and consistent (" << names.size()
              << " sequences x 2 modes)\n";
  } else {
    std::cout << "ppf_bench: table check failed: " << error << "\n";
  }
  if (!peer_rows.empty()) {
    std::cout << "\npeers, same bags (sqlite3 copy) and " << threads
              << " threads: median ms per scan inside the peer's registration call; ppf/knn ms:"
                 " our median total;\nppf/peer, knn/peer: ours over theirs (< 1: ours faster)\n"
              << PeerTable(peer_rows, rows);
  }
  for (const auto& n : peer_notes) std::cout << n << "\n";
  return consistent ? 0 : 1;
}
