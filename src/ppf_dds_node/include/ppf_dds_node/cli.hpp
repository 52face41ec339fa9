// Small command-line helpers shared by ppf_replay, ppf_record and the benchmark.
#pragma once

#include <signal.h>

#include <atomic>
#include <cstdlib>
#include <string>
#include <vector>

namespace ppf::dds {

// Options common to every tool that joins the DDS graph.
struct DdsCliOptions {
  int domain_id = 0;
  std::string profiles_file;
  std::string profile_name;
  // --fastdds-defaults: no XML at all (otherwise the project's SHM+UDP profile is the default,
  // see ChooseToolTransport).
  bool fastdds_defaults = false;
};

// Consumes --domain/--profiles/--profile/--fastdds-defaults at argv[*i]; returns true if it did.
inline bool ParseDdsOption(int argc, char** argv, int* i, DdsCliOptions* o) {
  const std::string a = argv[*i];
  if (a == "--fastdds-defaults") {
    o->fastdds_defaults = true;
    return true;
  }
  if (*i + 1 >= argc) return false;
  if (a == "--domain") {
    o->domain_id = std::atoi(argv[++*i]);
  } else if (a == "--profiles") {
    o->profiles_file = argv[++*i];
  } else if (a == "--profile") {
    o->profile_name = argv[++*i];
  } else {
    return false;
  }
  return true;
}

// Reads values following argv[*i] until the next "--option".
inline std::vector<std::string> TakeList(int argc, char** argv, int* i) {
  std::vector<std::string> out;
  while (*i + 1 < argc && std::string(argv[*i + 1]).rfind("--", 0) != 0) out.push_back(argv[++*i]);
  return out;
}

namespace detail {
inline std::atomic<bool> stop_requested{false};
}  // namespace detail

// After StopOnSignals(), SIGINT and SIGTERM only set a flag (StopRequested()) that the tool's
// loops poll, so it can wind down (acknowledgements, bag close, counts) instead of dying mid-way.
inline void StopOnSignals() {
  signal(SIGINT, [](int) { detail::stop_requested = true; });
  signal(SIGTERM, [](int) { detail::stop_requested = true; });
}
inline bool StopRequested() { return detail::stop_requested; }

}  // namespace ppf::dds
