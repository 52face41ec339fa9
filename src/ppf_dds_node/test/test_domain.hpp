// Per-process DDS domain ids for the cross-process tests.
#pragma once

#include <unistd.h>

namespace ppf::test {

// Domain id unique to this test process, in 1..100. Domain d's well-known ports start at
// 7400 + 250 d: above ~101 they fall into Linux's ephemeral port range (32768-60999), where any
// process's outgoing socket can hold a participant's discovery port, so participants take higher
// ids than the loopback initial peers cover and never discover each other (ROS 2 documents 0-101
// as the safe range on Linux). The e2e tests' "recorder never matched the node" failures (twice in
// ~8 CI runs) are consistent with that; with ids up to 200 half the runs were exposed.
inline int TestDomainId(int salt = 0) {
  return 1 + static_cast<int>((static_cast<unsigned>(getpid()) * 7u + static_cast<unsigned>(salt)) %
                              100u);
}

}  // namespace ppf::test
