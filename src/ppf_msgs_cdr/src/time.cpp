#include "ppf_msgs_cdr/time.hpp"

#include <cmath>

namespace ppf::msgs {

double ToSeconds(const builtin_interfaces::msg::Time& t) {
  return static_cast<double>(t.sec()) + 1e-9 * static_cast<double>(t.nanosec());
}

int64_t ToNanoseconds(const builtin_interfaces::msg::Time& t) {
  return static_cast<int64_t>(t.sec()) * 1000000000LL + static_cast<int64_t>(t.nanosec());
}

builtin_interfaces::msg::Time TimeFromNanoseconds(int64_t ns) {
  // Floor division so that negative times keep 0 <= nanosec < 1e9, as rclcpp does.
  int64_t sec = ns / 1000000000LL;
  int64_t rem = ns % 1000000000LL;
  if (rem < 0) {
    rem += 1000000000LL;
    sec -= 1;
  }
  builtin_interfaces::msg::Time t;
  t.sec(static_cast<int32_t>(sec));
  t.nanosec(static_cast<uint32_t>(rem));
  return t;
}

builtin_interfaces::msg::Time TimeFromSeconds(double s) {
  return TimeFromNanoseconds(static_cast<int64_t>(std::llround(s * 1e9)));
}

}  // namespace ppf::msgs
