// Node log lines go to stderr with a wall-clock time; machine-readable lines (READY, SUMMARY) go
// to stdout so tests and scripts can parse them without the log noise.
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace ppf::dds {

enum class Level { kDebug, kInfo, kWarn, kError };

void Log(Level level, const std::string& message);

// At most one line per `interval_s` for a recurring condition; the suppressed count is appended
// to the next line so nothing is hidden, only batched.
class RateLimitedLog {
 public:
  explicit RateLimitedLog(double interval_s) : interval_s_(interval_s) {}
  void Log(Level level, const std::string& message);
  // Lines suppressed since the last one and not yet reported (no later line carried the count)
  // are reported now: "(+N similar since the last line) last: <latest message>". Called
  // periodically and at shutdown, so the count of a burst's tail is not lost with the burst.
  void Flush();

 private:
  std::mutex mutex_;
  double interval_s_;
  bool logged_once_ = false;
  std::chrono::steady_clock::time_point last_;
  uint64_t suppressed_ = 0;
  Level suppressed_level_ = Level::kInfo;
  std::string suppressed_message_;  // the latest suppressed one
};

}  // namespace ppf::dds
