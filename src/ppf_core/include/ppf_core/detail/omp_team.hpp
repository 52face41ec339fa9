// Whether a loop worth a parallel region may open one: not from inside another region. The
// pre-fit's loops (RANSAC's batch scoring, inlier counts, sandwich labels) choose between their
// parallel and serial forms with a plain if: a `parallel for` whose if clause is false is still a
// region entry, hundreds a scan, and inside another team each builds a nested team of one. Every
// such loop gives the same result on any number of threads.
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
