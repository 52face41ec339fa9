#include "ppf_sim/scan_generator.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "ppf_sim/rng.hpp"

namespace ppf::sim {

namespace {

struct Sample {
  float x, y, z;
  float intensity;
  float reflectivity;  // 0..1
  float range;         // measured, m; 0 = no return
};

template <typename T>
void Put(uint8_t* dst, uint32_t offset, T v) {
  std::memcpy(dst + offset, &v, sizeof(T));
}

// What the sensor reports for a beam with direction d_l (LiDAR frame) that hit the scene:
// false when the echo is lost (too weak for its range, random dropout, noisy range out of the
// model's limits). Every random draw is keyed by the ray, so the order of calls does not matter.
bool MeasureReturn(const Hit& hit, const Ray& ray, const Eigen::Vector3d& d_l,
                   const LidarModel& model, const ScanOptions& opt, Sample* s) {
  const double cos_i = std::abs(hit.n.dot(ray.d));
  // Weak echoes (dark, grazing) are lost before max range: the detectable range scales
  // with the fourth root of the returned energy relative to a 50 % Lambertian target.
  const double echo = std::max(hit.reflectivity * cos_i, 1e-6);
  const double reach = model.max_range * std::min(1.0, std::pow(echo / 0.5, 0.25));
  if (hit.t > reach) return false;
  if (KeyedUniform(ray.key, 1) < opt.dropout) return false;
  const double range = hit.t + opt.range_noise * KeyedNormal(ray.key, 2);
  if (range < model.min_range || range > model.max_range) return false;
  s->x = static_cast<float>(range * d_l.x());
  s->y = static_cast<float>(range * d_l.y());
  s->z = static_cast<float>(range * d_l.z());
  s->range = static_cast<float>(range);
  s->reflectivity = hit.reflectivity;
  const double jitter = 1.0 + 0.05 * KeyedNormal(ray.key, 3);
  if (model.layout == PointLayout::kVelodyne) {
    // Velodyne's calibrated intensity: 0..255, integer-valued, mostly reflectivity.
    s->intensity = static_cast<float>(std::clamp(
        std::round(255.0 * hit.reflectivity * (0.35 + 0.65 * cos_i) * jitter), 0.0, 255.0));
  } else {
    // Ouster's signal: photon counts falling with range squared.
    s->intensity = static_cast<float>(std::clamp(
        3.0e5 * hit.reflectivity * cos_i * jitter / std::max(range * range, 1.0), 0.0, 65535.0));
  }
  return true;
}

// Velodyne driver layout: an unorganized cloud of the valid returns only, column by column,
// with the per-point time field the options ask for. cloud->stamp_ns is the scan start on entry.
void PackVelodyne(const std::vector<Sample>& samples, int nc, int nr, double period,
                  const ScanOptions& opt, CloudBuffer* cloud) {
  using TF = ScanOptions::TimeField;
  cloud->fields = {{"x", 0, kFloat32, 1},
                   {"y", 4, kFloat32, 1},
                   {"z", 8, kFloat32, 1},
                   {"intensity", 16, kFloat32, 1},
                   {"ring", 20, kUint16, 1}};
  if (opt.time_field == TF::kDriverDefault) cloud->fields.push_back({"time", 24, kFloat32, 1});
  if (opt.time_field == TF::kAbsoluteF64) cloud->fields.push_back({"timestamp", 24, kFloat64, 1});
  const int64_t start_ns = cloud->stamp_ns;
  const double time_offset = opt.stamp_at_end ? -period : 0.0;
  if (opt.stamp_at_end) cloud->stamp_ns += static_cast<int64_t>(std::llround(period * 1e9));
  cloud->point_step = 32;
  size_t valid = 0;
  for (const Sample& s : samples) valid += s.range > 0.0f;
  cloud->height = 1;
  cloud->width = static_cast<uint32_t>(valid);
  cloud->row_step = cloud->width * cloud->point_step;
  cloud->is_dense = true;
  cloud->data.assign(static_cast<size_t>(cloud->row_step), 0);
  uint8_t* dst = cloud->data.data();
  for (int c = 0; c < nc; ++c) {
    const float t_rel = static_cast<float>(c * period / nc + time_offset);
    // Absolute time in seconds: integer seconds plus fraction, to keep double precision.
    const int64_t abs_ns = start_ns + static_cast<int64_t>(std::llround(c * period / nc * 1e9));
    const double t_abs = static_cast<double>(abs_ns / 1000000000LL) +
                         static_cast<double>(abs_ns % 1000000000LL) * 1e-9;
    for (int r = 0; r < nr; ++r) {
      const Sample& s = samples[static_cast<size_t>(c) * nr + r];
      if (!(s.range > 0.0f)) continue;
      Put(dst, 0, s.x);
      Put(dst, 4, s.y);
      Put(dst, 8, s.z);
      Put(dst, 16, s.intensity);
      Put(dst, 20, static_cast<uint16_t>(r));
      if (opt.time_field == TF::kDriverDefault) Put(dst, 24, t_rel);
      if (opt.time_field == TF::kAbsoluteF64) Put(dst, 24, t_abs);
      dst += cloud->point_step;
    }
  }
}

// Ouster driver layout: an organized ring-major image with every beam, misses as zero points,
// per-point `t` in ns after the header stamp and a keyed ambient level.
void PackOuster(const std::vector<Sample>& samples, int nc, int nr, double period, int k,
                const ScanOptions& opt, CloudBuffer* cloud) {
  cloud->fields = {{"x", 0, kFloat32, 1},          {"y", 4, kFloat32, 1},
                   {"z", 8, kFloat32, 1},          {"intensity", 16, kFloat32, 1},
                   {"t", 20, kUint32, 1},          {"reflectivity", 24, kUint16, 1},
                   {"ring", 26, kUint16, 1},       {"ambient", 28, kUint16, 1},
                   {"range", 32, kUint32, 1}};
  cloud->point_step = 48;
  cloud->height = static_cast<uint32_t>(nr);
  cloud->width = static_cast<uint32_t>(nc);
  cloud->row_step = cloud->width * cloud->point_step;
  cloud->is_dense = false;
  cloud->data.assign(static_cast<size_t>(cloud->row_step) * cloud->height, 0);
  for (int r = 0; r < nr; ++r) {
    for (int c = 0; c < nc; ++c) {
      const Sample& s = samples[static_cast<size_t>(c) * nr + r];
      uint8_t* dst = cloud->data.data() + (static_cast<size_t>(r) * nc + c) * cloud->point_step;
      const uint32_t t_ns = static_cast<uint32_t>(std::llround(c * period / nc * 1e9));
      Put(dst, 0, s.x);
      Put(dst, 4, s.y);
      Put(dst, 8, s.z);
      Put(dst, 16, s.intensity);
      Put(dst, 20, t_ns);
      Put(dst, 24, static_cast<uint16_t>(std::lround(s.reflectivity * 255.0f)));
      Put(dst, 26, static_cast<uint16_t>(r));
      const uint64_t key = HashKey(opt.seed, static_cast<uint64_t>(k), c, r);
      Put(dst, 28, static_cast<uint16_t>(40 + 30 * KeyedUniform(key, 4)));
      Put(dst, 32, static_cast<uint32_t>(std::lround(s.range * 1000.0f)));
    }
  }
}

}  // namespace

Eigen::Isometry3d DefaultImuLidarExtrinsic() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const double d2r = M_PI / 180.0;
  T.linear() = EulerToRotation({1.0 * d2r, -1.5 * d2r, 2.0 * d2r});
  T.translation() = Eigen::Vector3d(0.2, 0.05, 0.15);
  return T;
}

ScanGenerator::ScanGenerator(const Scene& scene, const Trajectory& traj, LidarModel model,
                             ScanOptions opt)
    : scene_(scene), traj_(traj), model_(std::move(model)), opt_(std::move(opt)) {
  if (opt_.max_range > 0.0) model_.max_range = opt_.max_range;
  for (double e : model_.elevation_deg) {
    cos_el_.push_back(std::cos(e * M_PI / 180.0));
    sin_el_.push_back(std::sin(e * M_PI / 180.0));
  }
}

double ScanGenerator::ColumnAzimuth(int c) const {
  return M_PI - 2.0 * M_PI * c / model_.columns;
}

int ScanGenerator::NumScans(double duration) const {
  return static_cast<int>(std::floor(duration * model_.rate_hz + 1e-9));
}

CloudBuffer ScanGenerator::Generate(int k) const {
  const int nc = model_.columns;
  const int nr = static_cast<int>(model_.elevation_deg.size());
  const double period = 1.0 / model_.rate_hz;
  const double t_scan = k * period;
  std::vector<Sample> samples(static_cast<size_t>(nc) * nr);

  // One column of beams fires at once from the pose at its own time (motion distortion).
#pragma omp parallel for schedule(dynamic, 16)
  for (int c = 0; c < nc; ++c) {
    const double t_rel = c * period / nc;
    const Eigen::Isometry3d T_world_lidar = traj_.Pose(t_scan + t_rel) * opt_.T_imu_lidar;
    const Eigen::Matrix3d R = T_world_lidar.linear();
    const double az = ColumnAzimuth(c);
    const double ca = std::cos(az), sa = std::sin(az);
    Ray ray;
    ray.o = T_world_lidar.translation();
    ray.tmin = 0.05;
    ray.tmax = model_.max_range;
    for (int r = 0; r < nr; ++r) {
      Sample& s = samples[static_cast<size_t>(c) * nr + r];
      s = Sample{0, 0, 0, 0, 0, 0};
      const Eigen::Vector3d d_l(cos_el_[r] * ca, cos_el_[r] * sa, sin_el_[r]);
      ray.d = R * d_l;
      ray.key = HashKey(opt_.seed, static_cast<uint64_t>(k), static_cast<uint64_t>(c),
                        static_cast<uint64_t>(r));
      Hit hit;
      if (!scene_.Intersect(ray, &hit)) continue;
      // A lost echo leaves the sample zero (range 0 = no return): every rejection in
      // MeasureReturn comes before its first write.
      MeasureReturn(hit, ray, d_l, model_, opt_, &s);
    }
  }

  CloudBuffer cloud;
  cloud.stamp_ns = opt_.start_ns + static_cast<int64_t>(std::llround(t_scan * 1e9));
  cloud.frame_id = opt_.frame_id;
  if (model_.layout == PointLayout::kVelodyne) {
    PackVelodyne(samples, nc, nr, period, opt_, &cloud);
  } else {
    PackOuster(samples, nc, nr, period, k, opt_, &cloud);
  }
  return cloud;
}

}  // namespace ppf::sim
