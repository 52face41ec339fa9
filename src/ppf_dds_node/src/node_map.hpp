// NodeMap: the map the node saves (outputs.map_file). The executor thread only hands each trusted
// scan's points over (a copy, queued under a short lock that no Fast DDS call is made under); the
// map's own thread accumulates them into the voxel grid and writes the file. So neither the grid's
// growth nor a save, however large the map or slow the disk, holds up odometry (docs/decisions.md,
// "The node's map on its own thread").
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>

#include "ppf_core/lio_ppf.hpp"
#include "ppf_dds_node/node_config.hpp"
#include "ppf_trajectory/map_export.hpp"

namespace ppf::dds {

class NodeMap {
 public:
  // Starts the map thread when config.map_file is set (the loader checked its extension).
  explicit NodeMap(const NodeConfig& config);
  ~NodeMap();
  NodeMap(const NodeMap&) = delete;
  NodeMap& operator=(const NodeMap&) = delete;

  bool enabled() const { return thread_.joinable(); }

  // Executor thread: queues the scan's de-skewed points (Config::output_deskewed_points) if its
  // pose is trusted: status kOk or kDegenerate with pose_valid, not relocalized (the core's own
  // map does not take such a scan either), as ppf_offline's map.
  void Add(const ScanResult& r);
  // Any thread, returns at once: the map thread writes the file with what it has so far.
  void RequestSave();
  // After the last Add: the map thread takes in what is queued, writes the file and ends.
  // Returns once it has (the write's duration).
  void Finish();

  // Saves written and failed; scans not mapped because the map thread fell behind by more than
  // its backlog (a stalled disk). Read after Finish().
  uint64_t saves() const { return saves_; }
  uint64_t save_errors() const { return save_errors_; }
  uint64_t scans_skipped() const { return skipped_; }

 private:
  struct Scan {
    std::vector<Eigen::Vector3f> points_lidar;
    Eigen::Isometry3d T_world_lidar;
  };

  void Run();
  void Save(const char* why);

  const std::string file_;
  MapFormat format_ = MapFormat::kPcdBinary;
  MapAccumulator grid_;  // the map thread's only

  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Scan> queue_;   // guarded by mutex_
  bool finishing_ = false;    // guarded by mutex_
  std::atomic<bool> save_requested_{false};
  std::atomic<uint64_t> saves_{0}, save_errors_{0}, skipped_{0};
  std::thread thread_;
};

}  // namespace ppf::dds
