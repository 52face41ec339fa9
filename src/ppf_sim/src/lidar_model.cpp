#include "ppf_sim/lidar_model.hpp"

#include <stdexcept>

namespace ppf::sim {

namespace {

std::vector<double> Uniform(int n, double lo, double hi) {
  std::vector<double> e(n);
  for (int i = 0; i < n; ++i) e[i] = lo + (hi - lo) * i / (n - 1);
  return e;
}

}  // namespace

std::vector<std::string> LidarModelNames() {
  return {"vlp16", "hdl32", "hdl64", "os1_64", "os1_128"};
}

LidarModel GetLidarModel(const std::string& name) {
  LidarModel m;
  m.name = name;
  if (name == "vlp16") {
    // VLP-16: -15..+15 deg in 2 deg steps, 0.2 deg at 10 Hz, 100 m.
    m.elevation_deg = Uniform(16, -15.0, 15.0);
    m.columns = 1800;
    m.max_range = 100.0;
    m.min_range = 0.4;
    m.layout = PointLayout::kVelodyne;
  } else if (name == "hdl32") {
    // HDL-32E: -30.67..+10.67 deg, 1.33 deg steps, 0.16 deg at 10 Hz, 100 m.
    m.elevation_deg = Uniform(32, -30.67, 10.67);
    m.columns = 2250;
    m.max_range = 100.0;
    m.min_range = 1.0;
    m.layout = PointLayout::kVelodyne;
  } else if (name == "hdl64") {
    // HDL-64E (S2/S3 as on KITTI): lower block of 32 lasers from -24.9 to about -8.9 deg
    // (~0.5 deg apart), upper block of 32 from about -8.3 to +2.0 deg (~1/3 deg apart);
    // 0.1728 deg at 10 Hz gives ~2083 firings, ~120k returns per scan outdoors.
    std::vector<double> lower = Uniform(32, -24.9, -8.87);
    std::vector<double> upper = Uniform(32, -8.33, 2.0);
    m.elevation_deg = lower;
    m.elevation_deg.insert(m.elevation_deg.end(), upper.begin(), upper.end());
    m.columns = 2083;
    m.max_range = 120.0;
    m.min_range = 0.9;
    m.layout = PointLayout::kVelodyne;
  } else if (name == "os1_64" || name == "os1_128") {
    // OS1 (gen 2): uniform beams over +-22.5 deg, 1024 columns at 10 Hz, 120 m.
    const int n = name == "os1_64" ? 64 : 128;
    m.elevation_deg = Uniform(n, 22.5, -22.5);  // ring 0 = top beam
    m.columns = 1024;
    m.max_range = 120.0;
    m.min_range = 0.3;
    m.layout = PointLayout::kOuster;
  } else {
    throw std::invalid_argument("unknown lidar model '" + name +
                                "' (vlp16, hdl32, hdl64, os1_64, os1_128)");
  }
  return m;
}

}  // namespace ppf::sim
