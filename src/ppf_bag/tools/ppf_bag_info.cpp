// ppf_bag_info PATH: summary of a bag directory or a single .db3/.mcap/.bag (ROS 1) file, laid
// out like `ros2 bag info`.
#include <cstdio>
#include <ctime>
#include <string>

#include "ppf_bag/bag.hpp"

namespace {

std::string FormatTime(int64_t ns) {
  const std::time_t secs = static_cast<std::time_t>(ns / 1000000000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char date[64];
  std::strftime(date, sizeof(date), "%b %e %Y %H:%M:%S", &tm);
  char buf[128];
  std::snprintf(buf, sizeof(buf), "%s.%09lld UTC (%lld.%09lld)", date,
                static_cast<long long>(ns % 1000000000), static_cast<long long>(ns / 1000000000),
                static_cast<long long>(ns % 1000000000));
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s BAG_DIR|FILE.db3|FILE.mcap|FILE.bag\n", argv[0]);
    return 2;
  }
  try {
    const ppf::bag::BagInfo info = ppf::bag::ReadInfo(argv[1]);
    std::printf("Files:             %s\n", argv[1]);
    std::printf("Storage id:        %s\n", ppf::bag::StorageIdentifier(info.storage));
    std::printf("Duration:          %.9fs\n", static_cast<double>(info.duration_ns()) * 1e-9);
    std::printf("Start:             %s\n", FormatTime(info.start_ns).c_str());
    std::printf("End:               %s\n", FormatTime(info.end_ns).c_str());
    std::printf("Messages:          %llu\n", static_cast<unsigned long long>(info.message_count));
    std::printf("Topic information: ");
    if (info.topics.empty()) std::printf("\n");
    bool first = true;
    for (const auto& t : info.topics) {
      std::printf("%sTopic: %s | Type: %s | Count: %llu | Serialization Format: %s\n",
                  first ? "" : "                   ", t.info.name.c_str(), t.info.type.c_str(),
                  static_cast<unsigned long long>(t.message_count),
                  t.info.serialization_format.c_str());
      first = false;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ppf_bag_info: %s\n", e.what());
    return 1;
  }
}
