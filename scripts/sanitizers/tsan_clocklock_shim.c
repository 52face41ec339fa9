// Preloaded into the TSan test runs by scripts/sanitize.sh. Debian's Fast DDS 2.9 takes its
// timed mutexes with pthread_mutex_clocklock (glibc 2.34+, used by libstdc++ 12 for steady_clock
// deadlines), which the TSan runtimes of clang 14 and gcc 12 do not intercept: TSan would never
// see those locks taken, and would report their unlocks, and races on everything they protect.
// This definition takes precedence over glibc's and forwards to pthread_mutex_timedlock, which
// TSan does intercept, with the deadline moved to CLOCK_REALTIME.
#define _GNU_SOURCE
#include <pthread.h>
#include <time.h>

int pthread_mutex_clocklock(pthread_mutex_t* mutex, clockid_t clock,
                            const struct timespec* abstime) {
  struct timespec now_clock, now_real, deadline;
  clock_gettime(clock, &now_clock);
  clock_gettime(CLOCK_REALTIME, &now_real);
  long long left_ns = (abstime->tv_sec - now_clock.tv_sec) * 1000000000LL +
                      (abstime->tv_nsec - now_clock.tv_nsec);
  if (left_ns < 0) left_ns = 0;
  long long at_ns = now_real.tv_sec * 1000000000LL + now_real.tv_nsec + left_ns;
  deadline.tv_sec = at_ns / 1000000000LL;
  deadline.tv_nsec = at_ns % 1000000000LL;
  return pthread_mutex_timedlock(mutex, &deadline);
}
