// Logging is a callback in the config, so the core never writes to stdout/stderr itself: the DDS
// node forwards to its logger, tests capture messages, the offline runner prints them.
#pragma once

#include <functional>
#include <string>

namespace ppf {

enum class LogLevel { kDebug, kInfo, kWarn, kError };

using LogCallback = std::function<void(LogLevel, const std::string&)>;

inline const char* LogLevelName(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return "debug";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kWarn:
      return "warn";
    case LogLevel::kError:
      return "error";
  }
  return "?";
}

}  // namespace ppf
