#include "ppf_dds_node/synthetic_scene.hpp"

#include <cmath>
#include <cstring>
#include <limits>

#include "ppf_bridge/convert.hpp"
#include "ppf_msgs_cdr/time.hpp"

namespace ppf::dds {

namespace {

// Room 24 x 14 x 4.5 m, sensor 1.8 m above the floor, off-centre so no axis is symmetric, and
// two pillars that break the remaining ambiguity.
double CastRay(double dx, double dy, double dz) {
  double best = std::numeric_limits<double>::infinity();
  auto plane = [&](double dir, double pos) {
    if (std::abs(dir) < 1e-9) return;
    const double t = pos / dir;
    if (t > 0 && t < best) best = t;
  };
  plane(dx, 9.0);
  plane(dx, -15.0);
  plane(dy, 6.0);
  plane(dy, -8.0);
  plane(dz, -1.8);
  plane(dz, 2.7);
  // Pillars: axis-aligned boxes (x0, x1, y0, y1), floor to ceiling.
  const double boxes[2][4] = {{3.0, 4.0, 1.5, 2.5}, {-6.0, -4.5, -3.5, -2.5}};
  for (const auto& b : boxes) {
    double tmin = 0.0, tmax = best;
    bool hit = true;
    const double o[2] = {0.0, 0.0};
    const double d[2] = {dx, dy};
    for (int k = 0; k < 2 && hit; ++k) {
      const double lo = b[2 * k], hi = b[2 * k + 1];
      if (std::abs(d[k]) < 1e-12) {
        if (o[k] < lo || o[k] > hi) hit = false;
        continue;
      }
      double t0 = (lo - o[k]) / d[k], t1 = (hi - o[k]) / d[k];
      if (t0 > t1) std::swap(t0, t1);
      tmin = std::max(tmin, t0);
      tmax = std::min(tmax, t1);
      if (tmin > tmax) hit = false;
    }
    if (hit && tmin > 0 && tmin < best) best = tmin;
  }
  return best;
}

}  // namespace

sensor_msgs::msg::PointCloud2 MakeRoomScan(const SyntheticLidar& lidar, int64_t stamp_ns) {
  sensor_msgs::msg::PointCloud2 msg;
  msg.header().stamp(msgs::TimeFromNanoseconds(stamp_ns));
  msg.header().frame_id("lidar");
  struct F {
    const char* name;
    uint32_t offset;
    uint8_t type;
  };
  const F fields[] = {{"x", 0, 7},          {"y", 4, 7},  {"z", 8, 7},
                      {"intensity", 12, 7}, {"t", 16, 7}, {"ring", 20, 4}};
  for (const F& f : fields) {
    sensor_msgs::msg::PointField pf;
    pf.name(f.name);
    pf.offset(f.offset);
    pf.datatype(f.type);
    pf.count(1);
    msg.fields().push_back(pf);
  }
  constexpr uint32_t kStep = 24;
  const uint32_t n = static_cast<uint32_t>(lidar.rings * lidar.columns);
  msg.height(1);
  msg.width(n);
  msg.point_step(kStep);
  msg.row_step(kStep * n);
  msg.is_bigendian(false);
  msg.is_dense(true);
  std::vector<uint8_t>& data = msg.data();
  data.resize(static_cast<size_t>(n) * kStep);
  size_t i = 0;
  for (int c = 0; c < lidar.columns; ++c) {
    // Clockwise from above, as a Velodyne.
    const double az = -2.0 * M_PI * c / lidar.columns;
    const float t = static_cast<float>(lidar.scan_period_s * c / lidar.columns);
    for (int r = 0; r < lidar.rings; ++r) {
      const double el =
          (lidar.min_elevation_deg +
           (lidar.max_elevation_deg - lidar.min_elevation_deg) * r / std::max(1, lidar.rings - 1)) *
          M_PI / 180.0;
      const double dx = std::cos(el) * std::cos(az), dy = std::cos(el) * std::sin(az),
                   dz = std::sin(el);
      const double range = CastRay(dx, dy, dz);
      const float p[5] = {static_cast<float>(range * dx), static_cast<float>(range * dy),
                          static_cast<float>(range * dz), static_cast<float>(10 + r), t};
      const uint16_t ring = static_cast<uint16_t>(r);
      uint8_t* out = data.data() + i * kStep;
      std::memcpy(out, p, sizeof(p));
      std::memcpy(out + 20, &ring, 2);
      ++i;
    }
  }
  return msg;
}

sensor_msgs::msg::Imu MakeRestingImu(int64_t stamp_ns, uint64_t seq) {
  sensor_msgs::msg::Imu msg;
  msg.header().stamp(msgs::TimeFromNanoseconds(stamp_ns));
  msg.header().frame_id("imu");
  // Tiny deterministic jitter: real IMUs are never exactly constant.
  const double j = 1e-4 * static_cast<double>(static_cast<int64_t>(seq % 7) - 3);
  msg.angular_velocity().x(j);
  msg.angular_velocity().y(-j);
  msg.angular_velocity().z(0.5 * j);
  msg.linear_acceleration().x(j);
  msg.linear_acceleration().y(0.0);
  msg.linear_acceleration().z(9.81 + j);
  msg.orientation().w(1.0);
  return msg;
}

}  // namespace ppf::dds
