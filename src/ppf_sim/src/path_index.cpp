// Stations along the path: where roadside objects are proposed.
#include <cmath>

#include "world_detail.hpp"

namespace ppf::sim::detail {

std::vector<Station> Stations(const std::vector<PathSample>& path, double step) {
  std::vector<Station> out;
  double acc = step;  // emit the first point
  for (size_t i = 1; i < path.size(); ++i) {
    const PathSample& a = path[i - 1];
    const PathSample& b = path[i];
    const double len = std::hypot(b.x - a.x, b.y - a.y);
    if (len < 1e-9) continue;
    double pos = 0.0;
    while (acc + (len - pos) >= step) {
      pos += step - acc;
      acc = 0.0;
      const double f = pos / len;
      out.push_back({a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.yaw + f * (b.yaw - a.yaw)});
    }
    acc += len - pos;
  }
  if (out.empty() && !path.empty()) out.push_back({path[0].x, path[0].y, path[0].yaw});
  return out;
}

}  // namespace ppf::sim::detail
