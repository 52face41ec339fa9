#include <algorithm>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "ppf_sim/importers.hpp"
#include "ppf_sim/lidar_model.hpp"
#include "ppf_sim/trajectory.hpp"
#include "ppf_trajectory/trajectory_io.hpp"

namespace ppf::sim {

namespace fs = std::filesystem;

int64_t ParseKittiTimestamp(const std::string& line) {
  int y, mo, d, h, mi;
  char frac[32] = {0};
  int sec;
  if (std::sscanf(line.c_str(), "%d-%d-%d %d:%d:%d.%31[0-9]", &y, &mo, &d, &h, &mi, &sec, frac) < 6)
    throw std::runtime_error("malformed KITTI timestamp '" + line + "'");
  std::tm tm{};
  tm.tm_year = y - 1900;
  tm.tm_mon = mo - 1;
  tm.tm_mday = d;
  tm.tm_hour = h;
  tm.tm_min = mi;
  tm.tm_sec = sec;
  std::string f = frac;
  f.resize(9, '0');
  return static_cast<int64_t>(timegm(&tm)) * 1000000000LL + std::stoll(f);
}

double AzimuthTime(double x, double y, double period) {
  // Clockwise from behind: azimuth +pi at t = 0 down to -pi at t = period.
  const double az = std::atan2(y, x);
  return (M_PI - az) / (2.0 * M_PI) * period;
}

namespace {

std::vector<int64_t> ReadStamps(const fs::path& file) {
  std::vector<int64_t> out;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    out.push_back(ParseKittiTimestamp(line));
  }
  return out;
}

std::vector<fs::path> SortedFiles(const fs::path& dir, const std::string& ext) {
  std::vector<fs::path> files;
  if (!fs::is_directory(dir)) return files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ext) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

template <typename T>
void Put(uint8_t* dst, uint32_t offset, T v) {
  std::memcpy(dst + offset, &v, sizeof(T));
}

// One OXTS record: its stamp, the IMU sample and the pose fields.
struct OxtsSample {
  int64_t t;
  double w[3], a[3];
  double lat, lon, alt, roll, pitch, yaw;
};

// The scans' header stamps (sweep start): timestamps_start.txt if it matches the scans, else
// timestamps.txt (the sensor facing forward, half a sweep later) less half a period.
std::vector<int64_t> ReadScanStarts(const fs::path& velo, size_t scans, int64_t period_ns,
                                    ImportSummary* sum) {
  std::vector<int64_t> start;
  const std::vector<int64_t> mid = ReadStamps(velo / "timestamps.txt");
  if (fs::exists(velo / "timestamps_start.txt")) start = ReadStamps(velo / "timestamps_start.txt");
  if (start.size() == scans) {
    sum->notes.push_back("header stamp = timestamps_start.txt (scan start)");
    return start;
  }
  if (mid.size() == scans) {
    start.clear();
    for (int64_t t : mid) start.push_back(t - period_ns / 2);
    sum->notes.push_back("no timestamps_start.txt: header stamp = timestamps.txt - period/2");
    return start;
  }
  throw std::runtime_error("velodyne timestamps do not match the " + std::to_string(scans) +
                           " scans");
}

// oxts/data/*.txt (30 whitespace-separated values each) with oxts/timestamps.txt; empty when the
// drive has no oxts folder.
std::vector<OxtsSample> ReadOxts(const fs::path& root, const KittiOptions& opt,
                                 ImportSummary* sum) {
  std::vector<OxtsSample> imu;
  const auto oxts = SortedFiles(root / "oxts" / "data", ".txt");
  if (oxts.empty()) {
    sum->notes.push_back("no oxts/data: bag has no IMU messages");
    return imu;
  }
  const std::vector<int64_t> ot = ReadStamps(root / "oxts" / "timestamps.txt");
  if (ot.size() != oxts.size())
    throw std::runtime_error("oxts/timestamps.txt does not match oxts/data");
  for (size_t i = 0; i < oxts.size(); ++i) {
    std::ifstream in(oxts[i]);
    std::vector<double> v;
    double x;
    while (in >> x) v.push_back(x);
    if (v.size() < 23) throw std::runtime_error(oxts[i].string() + ": expected 30 OXTS values");
    OxtsSample s;
    s.t = ot[i];
    s.lat = v[0];
    s.lon = v[1];
    s.alt = v[2];
    s.roll = v[3];
    s.pitch = v[4];
    s.yaw = v[5];
    // Field order: lat lon alt roll pitch yaw vn ve vf vl vu ax ay az af al au wx wy wz wf wl wu
    const int a0 = opt.imu_body_axes ? 11 : 14, w0 = opt.imu_body_axes ? 17 : 20;
    for (int k = 0; k < 3; ++k) {
      s.a[k] = v[a0 + k];
      s.w[k] = v[w0 + k];
    }
    imu.push_back(s);
  }
  sum->notes.push_back(opt.imu_body_axes ? "IMU from OXTS ax ay az / wx wy wz (body axes)"
                                         : "IMU from OXTS af al au / wf wl wu (leveled axes)");
  return imu;
}

// One velodyne_points/data/*.bin scan (x y z reflectance floats) as a PointCloud2 with the
// fields our drivers' clouds have: ring estimated as the nearest HDL-64E beam, time from azimuth.
CloudBuffer ReadKittiScan(const fs::path& file, int64_t stamp_ns, const LidarModel& hdl,
                          const KittiOptions& opt) {
  std::ifstream in(file, std::ios::binary);
  std::vector<float> raw((fs::file_size(file)) / sizeof(float));
  in.read(reinterpret_cast<char*>(raw.data()), static_cast<std::streamsize>(raw.size() * 4));
  if (raw.size() % 4 != 0) throw std::runtime_error(file.string() + ": size not 16*n bytes");
  const size_t n = raw.size() / 4;
  CloudBuffer c;
  c.stamp_ns = stamp_ns;
  c.frame_id = opt.lidar_frame;
  c.fields = {{"x", 0, kFloat32, 1},          {"y", 4, kFloat32, 1},    {"z", 8, kFloat32, 1},
              {"intensity", 16, kFloat32, 1}, {"ring", 20, kUint16, 1}, {"time", 24, kFloat32, 1}};
  c.point_step = 32;
  c.height = 1;
  c.width = static_cast<uint32_t>(n);
  c.row_step = c.width * c.point_step;
  c.data.assign(static_cast<size_t>(c.row_step), 0);
  for (size_t p = 0; p < n; ++p) {
    const float x = raw[4 * p], y = raw[4 * p + 1], z = raw[4 * p + 2];
    const double el = std::atan2(z, std::hypot(x, y)) * 180.0 / M_PI;
    uint16_t ring = 0;
    double best = 1e9;
    for (size_t r = 0; r < hdl.elevation_deg.size(); ++r) {
      const double d = std::abs(hdl.elevation_deg[r] - el);
      if (d < best) {
        best = d;
        ring = static_cast<uint16_t>(r);
      }
    }
    uint8_t* dst = c.data.data() + p * c.point_step;
    Put(dst, 0, x);
    Put(dst, 4, y);
    Put(dst, 8, z);
    Put(dst, 16, raw[4 * p + 3]);
    Put(dst, 20, ring);
    Put(dst, 24, static_cast<float>(AzimuthTime(x, y, opt.scan_period)));
  }
  return c;
}

// Ground truth from the OXTS poses, as the KITTI devkit converts them (Mercator scale of the
// first fix), but kept gravity-aligned: origin at the first fix, axes east-north-up, rotation
// R = Rz(yaw) Ry(pitch) Rx(roll) of the OXTS (IMU) frame.
void WriteOxtsGroundTruth(const std::vector<OxtsSample>& imu, const fs::path& out_dir,
                          ImportSummary* sum) {
  TumWriter gt((out_dir / "groundtruth.tum").string(),
               "timestamp tx ty tz qx qy qz qw: T_world_imu from OXTS (IMU frame in a local "
               "east-north-up frame at the first fix)");
  const double er = 6378137.0;
  const double scale = std::cos(imu[0].lat * M_PI / 180.0);
  auto mercator = [&](const OxtsSample& s) {
    return Eigen::Vector3d(scale * er * s.lon * M_PI / 180.0,
                           scale * er * std::log(std::tan((90.0 + s.lat) * M_PI / 360.0)), s.alt);
  };
  const Eigen::Vector3d origin = mercator(imu[0]);
  for (const OxtsSample& s : imu) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = EulerToRotation({s.roll, s.pitch, s.yaw});
    T.translation() = mercator(s) - origin;
    gt.Write(s.t, T);
  }
  sum->notes.push_back("groundtruth.tum written from the OXTS poses (ENU at the first fix)");
}

// KITTI's calib_imu_to_velo.txt (in the drive's folder or the date folder above it) holds
// T_velo_imu; writes T_imu_lidar to calibration.yaml. Nothing when neither file parses.
void WriteKittiCalibration(const fs::path& root, const fs::path& out_dir, ImportSummary* sum) {
  for (const fs::path& cand :
       {root / "calib_imu_to_velo.txt", root.parent_path() / "calib_imu_to_velo.txt"}) {
    std::ifstream in(cand);
    if (!in) continue;
    std::string line;
    double R[9] = {0}, T[3] = {0};
    bool hasR = false, hasT = false;
    while (std::getline(in, line)) {
      std::istringstream ss(line.substr(line.find(':') + 1));
      if (line.rfind("R:", 0) == 0)
        hasR = static_cast<bool>(ss >> R[0] >> R[1] >> R[2] >> R[3] >> R[4] >> R[5] >> R[6] >>
                                 R[7] >> R[8]);
      if (line.rfind("T:", 0) == 0) hasT = static_cast<bool>(ss >> T[0] >> T[1] >> T[2]);
    }
    if (!hasR || !hasT) continue;
    Eigen::Isometry3d T_velo_imu = Eigen::Isometry3d::Identity();
    T_velo_imu.linear() << R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8];
    T_velo_imu.translation() << T[0], T[1], T[2];
    const Eigen::Isometry3d T_imu_lidar = T_velo_imu.inverse();
    const Eigen::Quaterniond q(T_imu_lidar.linear());
    std::ofstream cal(out_dir / "calibration.yaml");
    cal.precision(12);
    cal << "# From " << cand.string() << " (T_velo_imu), inverted.\n"
        << "# Transforms are named T_<to>_<from>: p_to = T_to_from * p_from.\n"
        << "extrinsic:\n  T_imu_lidar:\n    translation: [" << T_imu_lidar.translation().x() << ", "
        << T_imu_lidar.translation().y() << ", " << T_imu_lidar.translation().z()
        << "]\n    quaternion_wxyz: [" << q.w() << ", " << q.x() << ", " << q.y() << ", " << q.z()
        << "]\n";
    sum->notes.push_back("calibration.yaml written from " + cand.string());
    return;
  }
}

}  // namespace

// A KITTI raw drive as a bag: the clouds with their IMU samples interleaved by time, then the
// ground truth and the calibration beside it.
ImportSummary ImportKittiRaw(const std::string& raw_dir, const std::string& out_dir,
                             const BagOutputOptions& bag_opt, const KittiOptions& opt) {
  ImportSummary sum;
  const fs::path root(raw_dir);
  const fs::path velo = root / "velodyne_points";
  const auto scans = SortedFiles(velo / "data", ".bin");
  if (scans.empty()) throw std::runtime_error("no velodyne_points/data/*.bin under " + raw_dir);
  const int64_t period_ns = static_cast<int64_t>(std::llround(opt.scan_period * 1e9));
  const std::vector<int64_t> start = ReadScanStarts(velo, scans.size(), period_ns, &sum);
  std::vector<int64_t> end;
  if (fs::exists(velo / "timestamps_end.txt")) end = ReadStamps(velo / "timestamps_end.txt");
  sum.notes.push_back(
      "KITTI has no per-point time: `time` = (pi - atan2(y, x)) / 2pi * period (clockwise "
      "sweep starting behind the sensor); `ring` = nearest HDL-64E beam (estimate); intensity = "
      "KITTI reflectance (0..1)");
  const std::vector<OxtsSample> imu = ReadOxts(root, opt, &sum);

  const LidarModel hdl = GetLidarModel("hdl64");
  BagOutput bag(out_dir, bag_opt);
  size_t next_imu = 0;
  auto flush_imu = [&](int64_t until) {
    sum.imu_samples += WriteImuUntil(bag, imu, &next_imu, until, opt.imu_frame);
  };
  for (size_t i = 0; i < scans.size(); ++i) {
    const CloudBuffer c = ReadKittiScan(scans[i], start[i], hdl, opt);
    const int64_t bag_time = end.size() == scans.size() ? end[i] : start[i] + period_ns;
    flush_imu(bag_time);
    bag.WriteCloud(c, bag_time);
    ++sum.clouds;
    sum.points += c.width;
  }
  flush_imu(INT64_MAX);
  bag.Close();

  if (!imu.empty()) WriteOxtsGroundTruth(imu, fs::path(out_dir), &sum);
  WriteKittiCalibration(root, fs::path(out_dir), &sum);
  return sum;
}

}  // namespace ppf::sim
