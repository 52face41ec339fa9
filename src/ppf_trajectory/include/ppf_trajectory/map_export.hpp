// Map files: registered scans accumulated in the world frame, one point per voxel, written as a
// binary PCD (what PCL's reader and CloudCompare load) or a PLY (binary little-endian or ASCII).
// Eigen only, like the trajectory files beside it: ppf_offline (through ppf_tools) and ppf_node
// both write maps, and neither the writer nor the grid needs the estimator.
//
// The core keeps no intensity for its registered points, so the fourth field, "intensity", is the
// number of registered points that fell into the voxel (1 for every point of the local map).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ppf {

struct MapPoint {
  float x = 0.f, y = 0.f, z = 0.f;
  float intensity = 0.f;  // points averaged into this one (see the file comment)
};

// Voxel grid of running means: memory grows with the occupied voxels, not with the points added,
// so a long run costs what the mapped volume costs.
class MapAccumulator {
 public:
  explicit MapAccumulator(double voxel_size);

  double voxel_size() const { return voxel_size_; }
  // A world point; non-finite points and points beyond the grid's reach (about 2e9 voxels from
  // the origin) are counted in rejected() and left out.
  void Add(const Eigen::Vector3d& p_world);
  // The points of one scan, LiDAR frame, placed with T_world_lidar.
  void AddScan(const std::vector<Eigen::Vector3f>& points_lidar,
               const Eigen::Isometry3d& T_world_lidar);

  size_t voxels() const { return cells_.size(); }
  uint64_t points_added() const { return added_; }
  uint64_t scans_added() const { return scans_; }
  uint64_t rejected() const { return rejected_; }
  // One point per voxel, its points' mean, in the order the voxels were first occupied.
  std::vector<MapPoint> Points() const;

 private:
  struct Key {
    int32_t x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const;
  };
  struct Cell {
    double sx = 0, sy = 0, sz = 0;
    uint32_t n = 0;
  };
  double voxel_size_;
  double inv_;
  std::unordered_map<Key, uint32_t, KeyHash> index_;
  std::vector<Cell> cells_;
  uint64_t added_ = 0, scans_ = 0, rejected_ = 0;
};

// Points as they are (the local map): intensity 1 each.
std::vector<MapPoint> ToMapPoints(const std::vector<Eigen::Vector3f>& points);

enum class MapFormat { kPcdBinary, kPlyBinary, kPlyAscii };

// From the file name: .pcd -> binary PCD; .ply -> binary PLY, or ASCII PLY if ply_ascii. False
// for any other extension.
bool MapFormatForFile(const std::string& path, bool ply_ascii, MapFormat* format);

// The exact header bytes written before the points.
std::string PcdHeader(size_t points);
std::string PlyHeader(size_t points, bool binary);

// Writes path + ".tmp" and renames it over path, so a reader never sees a half-written map (the
// node saves while running). False with *error set if it cannot.
bool WriteMapFile(const std::string& path, const std::vector<MapPoint>& points, MapFormat format,
                  std::string* error);

}  // namespace ppf
