// Trajectory files: TUM ("stamp tx ty tz qx qy qz qw" per line) and KITTI (row-major 3x4 per
// line). Every tool that writes a TUM file (ppf_offline, ppf_node's tum_file, ppf_sim's and the
// KITTI importer's groundtruth.tum, the studies) writes it through TumWriter, so one text form
// exists: the stamp in seconds with 9 decimals (exact when given in nanoseconds), every other
// number "%.9f" (nanometres, 1e-9 of a unit quaternion), the quaternion normalized with qw >= 0
// (one sign per rotation, so a reader diffing two files sees no spurious flips).
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ppf {

struct StampedPose {
  double stamp_s = 0.0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // T_world_body
};
using Trajectory = std::vector<StampedPose>;

// TUM: "stamp tx ty tz qx qy qz qw" per line, '#' comments. Returns false and sets *error on
// a malformed line (line number included).
bool ReadTum(const std::string& path, Trajectory* traj, std::string* error);
bool ParseTum(const std::string& text, Trajectory* traj, std::string* error);

// One TUM line, without the newline. The nanosecond form prints the stamp exactly (a double
// holds a 2023 epoch stamp only to ~0.2 us).
std::string FormatTumLine(const StampedPose& pose);
std::string FormatTumLine(int64_t stamp_ns, const Eigen::Isometry3d& T_world_body);

// Streams a TUM file pose by pose (ground truth at every IMU sample need not be held in memory).
class TumWriter {
 public:
  // Truncates `path`. A non-empty `comment` becomes the first line, prefixed by "# "; without one
  // the file holds exactly one line per pose (ppf_node's tum_file: readers count lines).
  explicit TumWriter(const std::string& path, const std::string& comment = "");
  bool ok() const { return static_cast<bool>(out_); }
  void Write(const StampedPose& pose);
  void Write(int64_t stamp_ns, const Eigen::Isometry3d& T_world_body);
  // Flushes and closes; false if the file could not be opened or a write failed.
  bool Close();

 private:
  std::ofstream out_;
};

// The whole trajectory with the column header "# timestamp tx ty tz qx qy qz qw".
bool WriteTum(const std::string& path, const Trajectory& traj);

// KITTI: 12 numbers per line (row-major 3x4). No stamps in the format: stamp = line index.
bool ReadKitti(const std::string& path, Trajectory* traj, std::string* error);
bool ParseKitti(const std::string& text, Trajectory* traj, std::string* error);
bool WriteKitti(const std::string& path, const Trajectory& traj);

}  // namespace ppf
