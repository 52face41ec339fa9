// builtin_interfaces/Time <-> seconds and nanoseconds. Every stamp that enters or leaves a message
// goes through here, so the time base (nanoseconds since the epoch, floor division for negative
// times as rclcpp does) is decided in one place.
#pragma once

#include <cstdint>

#include "builtin_interfaces/msg/Time.h"

namespace ppf::msgs {

double ToSeconds(const builtin_interfaces::msg::Time& t);
int64_t ToNanoseconds(const builtin_interfaces::msg::Time& t);
builtin_interfaces::msg::Time TimeFromNanoseconds(int64_t ns);
builtin_interfaces::msg::Time TimeFromSeconds(double s);

}  // namespace ppf::msgs
