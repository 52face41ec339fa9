// Per-process DDS domain ids for the cross-process tests.
#pragma once

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstdlib>
#include <map>
#include <mutex>
#include <string>

namespace ppf::test {

// Domain ids are taken from 1..100. Domain d's well-known ports start at 7400 + 250 d: above ~101
// they fall into Linux's ephemeral port range (32768-60999), where any process's outgoing socket
// can hold a participant's discovery port, so participants take higher ids than the loopback
// initial peers cover and never discover each other (ROS 2 documents 0-101 as the safe range on
// Linux). The e2e tests' "recorder never matched the node" failures (twice in ~8 CI runs) were
// consistent with that; with ids up to 200 half the runs were exposed.
//
// Within that range a hash of the pid alone let two test processes running at the same time (ctest
// -j2, or two checkouts tested on one machine) pick the same domain now and then, and each then
// saw the other's node. So a domain is claimed: an exclusive flock on
// <TMPDIR or /tmp>/ppf_dds_test_domain_<d>.lock, held until the process exits (the kernel drops
// it even after a crash). The search starts at the pid's hash and takes the next free id.
// The same salt gives the same domain for the whole process; different salts, different ones.
inline int TestDomainId(int salt = 0) {
  static std::mutex mutex;
  static std::map<int, int> claimed;  // salt -> domain
  std::lock_guard<std::mutex> lock(mutex);
  const auto it = claimed.find(salt);
  if (it != claimed.end()) return it->second;
  const char* tmp = std::getenv("TMPDIR");
  const std::string dir = tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
  const unsigned start =
      (static_cast<unsigned>(getpid()) * 7u + static_cast<unsigned>(salt)) % 100u;
  for (unsigned k = 0; k < 100u; ++k) {
    const int domain = 1 + static_cast<int>((start + k) % 100u);
    bool taken_here = false;
    for (const auto& [s, d] : claimed) taken_here = taken_here || d == domain;
    if (taken_here) continue;
    const std::string path = dir + "/ppf_dds_test_domain_" + std::to_string(domain) + ".lock";
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      claimed[salt] = domain;  // fd stays open: the claim lasts as long as the process
      return domain;
    }
    ::close(fd);
  }
  // Every id claimed (100 test processes at once) or no writable temp dir: the old hash.
  const int domain = 1 + static_cast<int>(start);
  claimed[salt] = domain;
  return domain;
}

}  // namespace ppf::test
