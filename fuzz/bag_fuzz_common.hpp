// Shared body of the bag reader fuzz targets: the input bytes become a storage file on disk (the
// readers take paths, as rosbag2 bags are files) and are read the way ppf_offline and
// ppf_replay read a bag: info, every message, a topic filter, a seek.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "ppf_bag/bag.hpp"

namespace ppf::fuzz {

// One file per process, rewritten for every input; under /dev/shm when available so the
// fuzzer is not bound by disk writes.
inline const std::string& ScratchFile(const char* suffix) {
  static const std::string path = [suffix] {
    const char* dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    return std::string(dir) + "/ppf_fuzz_" + std::to_string(getpid()) + suffix;
  }();
  return path;
}

inline void ReadWholeBag(const uint8_t* data, size_t size, const char* suffix) {
  const std::string& path = ScratchFile(suffix);
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr || std::fwrite(data, 1, size, f) != size || std::fclose(f) != 0) {
    std::perror(path.c_str());
    std::abort();  // an environment problem, not a finding: stop instead of fuzzing nothing
  }
  try {
    ppf::bag::Reader reader(path);
    const ppf::bag::BagInfo& info = reader.Info();
    ppf::bag::Message m;
    // Bounded: a tiny input may legitimately describe many messages (sqlite rows, chunks).
    uint64_t n = 0;
    while (n < 10000 && reader.Next(m)) ++n;
    if (!info.topics.empty()) {
      reader.SetTopicFilter({info.topics.front().info.name});
      for (int i = 0; i < 100 && reader.Next(m); ++i) {
        if (m.topic != info.topics.front().info.name) {
          std::fprintf(stderr, "topic filter let '%s' through\n", m.topic.c_str());
          std::abort();
        }
      }
    }
    reader.Seek(info.start_ns / 2 + info.end_ns / 2);
    for (int i = 0; i < 100 && reader.Next(m); ++i) {
    }
  } catch (const ppf::bag::BagError&) {
    // The documented way to refuse a corrupt bag. Any other exception escapes and is a finding.
  }
  unlink(path.c_str());
}

}  // namespace ppf::fuzz
