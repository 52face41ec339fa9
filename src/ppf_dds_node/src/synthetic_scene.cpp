#include "ppf_dds_node/synthetic_scene.hpp"

#include <cmath>
#include <cstring>
#include <limits>

#include "ppf_bridge/convert.hpp"
#include "ppf_msgs_cdr/time.hpp"
#include "ppf_sim/scene.hpp"

namespace ppf::dds {

namespace {

// Room 24 x 14 x 4.5 m, sensor 1.8 m above the floor, off-centre so no axis is symmetric, and
// two pillars that break the remaining ambiguity; in the sensor frame, built from the
// simulator's primitives and cast with its scene. The walls overlap by 1 cm at the edges so
// that a ray into a corner always hits one.
const sim::Scene& Room() {
  static const sim::Scene scene = [] {
    const double x0 = -15.0, x1 = 9.0, y0 = -8.0, y1 = 6.0, z0 = -1.8, z1 = 2.7, e = 0.01;
    const Eigen::Vector3d c(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * (z0 + z1));
    const double hx = 0.5 * (x1 - x0) + e, hy = 0.5 * (y1 - y0) + e, hz = 0.5 * (z1 - z0) + e;
    const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                          Z = Eigen::Vector3d::UnitZ();
    sim::Scene s;
    for (const double x : {x0, x1}) s.Add(sim::MakeQuad({x, c.y(), c.z()}, Y, hy, Z, hz, 0.3f));
    for (const double y : {y0, y1}) s.Add(sim::MakeQuad({c.x(), y, c.z()}, X, hx, Z, hz, 0.3f));
    for (const double z : {z0, z1}) s.Add(sim::MakeQuad({c.x(), c.y(), z}, X, hx, Y, hy, 0.3f));
    s.Add(sim::MakeBox(3.5, 2.0, 0.0, 0.5, 0.5, z0, z1, 0.3f));
    s.Add(sim::MakeBox(-5.25, -3.0, 0.0, 0.75, 0.5, z0, z1, 0.3f));
    s.Build();
    return s;
  }();
  return scene;
}

double CastRay(double dx, double dy, double dz) {
  sim::Ray ray;
  ray.d = Eigen::Vector3d(dx, dy, dz);
  sim::Hit hit;
  return Room().Intersect(ray, &hit) ? hit.t : std::numeric_limits<double>::infinity();
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
