// Dataset importers: real recordings to the same rosbag2 layout the simulator writes.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "ppf_sim/bag_output.hpp"
#include "ppf_sim/cloud_buffer.hpp"

namespace ppf::sim {

struct ImportSummary {
  int clouds = 0;
  int imu_samples = 0;
  uint64_t points = 0;
  std::vector<std::string> notes;  // what was assumed, printed by the tools
};

// ---- KITTI raw --------------------------------------------------------------------------
// DIR/velodyne_points/data/*.bin (float32 x y z reflectance) + timestamps.txt
// (+ timestamps_start.txt / timestamps_end.txt), DIR/oxts/data/*.txt (30 fields) +
// oxts/timestamps.txt. KITTI scans carry no per-point time: it is computed from the azimuth of
// each point for a 10 Hz clockwise sweep that starts and ends behind the sensor, and `ring` is
// the nearest HDL-64E beam of the point's elevation (an estimate).
struct KittiOptions {
  bool imu_body_axes = true;  // true: ax ay az / wx wy wz (IMU body); false: af al au / wf wl wu
  double scan_period = 0.1;
  std::string lidar_frame = "velodyne";
  std::string imu_frame = "imu";
};
ImportSummary ImportKittiRaw(const std::string& raw_dir, const std::string& out_dir,
                             const BagOutputOptions& bag, const KittiOptions& opt);

// "2011-09-26 13:02:25.964389445" (taken as UTC) -> ns since the epoch; throws if malformed.
int64_t ParseKittiTimestamp(const std::string& line);
// Per-point time (s after the scan start) of a point at azimuth atan2(y, x).
double AzimuthTime(double x, double y, double period);

// ---- PCD directory ----------------------------------------------------------------------
// Every *.pcd in DIR in name order, fields kept exactly as in the file. The header stamp (scan
// start) comes from, in this order: --stamps FILE (one time per scan, s or ns: the first column
// of each line, so a TUM trajectory with one row per scan serves), --rate HZ (scan i at i/HZ s), a
// per-point absolute time field (F64 `timestamp`/`time`/`t` > 1e9 s: the earliest point), or the
// file name (19-digit ns, "sec.frac", or "YYYY-MM-DD-HH-MM-SS-mmm" read as UTC).
struct PcdOptions {
  std::string stamps_file;  // optional
  double rate_hz = 0.0;     // > 0 and no stamps_file: scan i at i / rate_hz seconds
  std::string imu_csv;      // optional: t,wx,wy,wz,ax,ay,az (t in s, or ns if > 1e14)
  double scan_period = 0.1; // bag time of a cloud = stamp + period (scan end)
  std::string lidar_frame = "lidar";
  std::string imu_frame = "imu";
};
ImportSummary ImportPcdDirectory(const std::string& dir, const std::string& out_dir,
                                 const BagOutputOptions& bag, const PcdOptions& opt);

// Reads one PCD file (ascii, binary, binary_compressed) into PointCloud2 layout.
CloudBuffer LoadPcd(const std::string& path);
// Time from a file name as above; false if the name has no recognizable time.
bool StampFromFileName(const std::string& name, int64_t* ns);

}  // namespace ppf::sim
