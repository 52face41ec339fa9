#include "ppf_dds_node/logging.hpp"

#include <cstdio>
#include <ctime>

namespace ppf::dds {

namespace {
std::mutex g_log_mutex;

const char* LevelName(Level level) {
  switch (level) {
    case Level::kDebug:
      return "DEBUG";
    case Level::kInfo:
      return "INFO";
    case Level::kWarn:
      return "WARN";
    case Level::kError:
      return "ERROR";
  }
  return "?";
}
}  // namespace

void Log(Level level, const std::string& message) {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const int ms = static_cast<int>(
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%H:%M:%S", &tm);
  std::lock_guard<std::mutex> lock(g_log_mutex);
  std::fprintf(stderr, "[%s.%03d] [%s] %s\n", stamp, ms, LevelName(level), message.c_str());
}

void RateLimitedLog::Log(Level level, const std::string& message) {
  const auto now = std::chrono::steady_clock::now();
  uint64_t suppressed = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (logged_once_ && std::chrono::duration<double>(now - last_).count() < interval_s_) {
      ++suppressed_;
      suppressed_level_ = level;
      suppressed_message_ = message;
      return;
    }
    logged_once_ = true;
    last_ = now;
    suppressed = suppressed_;
    suppressed_ = 0;
  }
  ppf::dds::Log(level, suppressed == 0 ? message
                                       : message + " (+" + std::to_string(suppressed) +
                                             " similar since the last line)");
}

void RateLimitedLog::Flush() {
  uint64_t suppressed = 0;
  Level level;
  std::string message;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (suppressed_ == 0) return;
    suppressed = suppressed_;
    suppressed_ = 0;
    level = suppressed_level_;
    message.swap(suppressed_message_);
    last_ = std::chrono::steady_clock::now();
  }
  ppf::dds::Log(
      level, "(+" + std::to_string(suppressed) + " similar since the last line) last: " + message);
}

}  // namespace ppf::dds
