// The command line both importers share: --help, the required input directory and --out BAG, the
// bag options (--storage, --compression, --points-topic, --imu-topic), the summary printed after
// the import, and errors reported as "<tool>: error: ..." with exit code 2.
#pragma once

#include <cstdio>
#include <functional>
#include <set>
#include <stdexcept>
#include <string>

#include "cli_args.hpp"
#include "ppf_sim/bag_output.hpp"
#include "ppf_sim/importers.hpp"

namespace ppf::sim {

// `import` gets the parsed arguments, the value of --<input_key> and of --out, and the bag
// options; it reads its own options from the arguments.
using ImportFn = std::function<ImportSummary(const CliArgs& args, const std::string& input,
                                             const std::string& out, const BagOutputOptions& bag)>;

inline int RunImporter(int argc, char** argv, const char* tool, const char* help,
                       const std::string& input_key, std::set<std::string> keys,
                       const ImportFn& import) {
  try {
    keys.insert({input_key, "out", "storage", "compression", "points-topic", "imu-topic"});
    const CliArgs args(argc, argv, keys, {"help"});
    if (args.Has("help")) {
      std::fputs(help, stdout);
      return 0;
    }
    if (!args.Has(input_key) || !args.Has("out"))
      throw std::invalid_argument("--" + input_key +
                                  " DIR and --out BAG are required (see --help)");
    BagOutputOptions bag;
    bag.storage = args.Str("storage", "mcap");
    bag.compression = args.Str("compression", "none");
    bag.points_topic = args.Str("points-topic", "/points");
    bag.imu_topic = args.Str("imu-topic", "/imu");
    const std::string out = args.Str("out", "");
    const ImportSummary s = import(args, args.Str(input_key, ""), out, bag);
    for (const auto& n : s.notes) std::printf("note: %s\n", n.c_str());
    std::printf("%d clouds (%.0f points/scan), %d IMU samples -> %s\n", s.clouds,
                s.clouds ? static_cast<double>(s.points) / s.clouds : 0.0, s.imu_samples,
                out.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", tool, e.what());
    return 2;
  }
}

}  // namespace ppf::sim
