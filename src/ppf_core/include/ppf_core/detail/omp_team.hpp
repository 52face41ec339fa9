// Whether a loop worth a parallel region may open one: not from inside another region. The kPpf
// pre-fit runs on one thread of a team while the other searches the kNN map (LioPpf's
// SplitScan); a region opened there would run on that one thread and still pay for a team of its
// own at every call (hundreds a scan), so the loops that would open one run serially instead.
// Every such loop gives the same result on any number of threads.
#pragma once

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ppf {
namespace detail {

inline bool MayOpenTeam() {
#ifdef _OPENMP
  return omp_in_parallel() == 0;
#else
  return false;
#endif
}

}  // namespace detail
}  // namespace ppf
