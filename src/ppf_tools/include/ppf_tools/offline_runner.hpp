// Runs the core over a whole bag: shared by ppf_offline and the comparison benchmark so both
// measure exactly the same loop.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "ppf_core/lio_ppf.hpp"
#include "ppf_tools/bag_source.hpp"
#include "ppf_trajectory/evaluation.hpp"

namespace ppf::tools {

struct OfflineRun {
  std::vector<ScanResult> results;  // one per scan, in order
  Trajectory trajectory;            // poses of scans with pose_valid, in `frame`
  BagSourceStats source;
  double wall_s = 0.0;
  bool lidar_only = false;  // the core ran without IMU (imu.mode none, or a bag without IMU)
  uint64_t imu_dropped = 0;  // OfflineOptions::imu_gap_*
  uint64_t scans_dropped = 0;  // OfflineOptions::drop_scans_*
};

struct OfflineOptions {
  BagSourceOptions source;
  bool lidar_frame = false;  // trajectory of T_world_lidar instead of T_world_imu
  // Called after every processed batch: (scans done, scans in bag, core ms so far).
  std::function<void(size_t, uint64_t, double)> on_progress;
  std::function<void(const BagSourceStats&)> on_topics_resolved;
  std::function<void(const std::string&)> on_error;  // malformed message skipped
  // Called with each result (index in bag order from 0) before it is stored: e.g. to write one
  // scan's points and drop the others' so a long run does not keep every cloud.
  std::function<void(size_t, ScanResult*)> on_result;
  // Called once after the last scan was processed, with the core as it ends (its local map).
  std::function<void(const LioPpf&)> on_finish;
  // > 0: no IMU sample reaches the core from imu_gap_begin_s to imu_gap_begin_s +
  // imu_gap_length_s after the first message's stamp (a dropout, as the node's test peer's
  // --imu-gap makes one over DDS). Dropped samples count in OfflineRun::imu_dropped.
  double imu_gap_begin_s = 0.0;
  double imu_gap_length_s = 0.0;
  // Scans that never reach the core, as when a node starved of CPU drops them from its queue:
  // every drop_scans_every-th scan (counted from the first in the window; 2 drops half, 1 drops
  // every scan, a burst, and needs drop_scans_length_s > 0; 0 drops none) from
  // drop_scans_begin_s to drop_scans_begin_s + drop_scans_length_s after the first message, or
  // over the whole run if drop_scans_length_s is 0. Dropped scans count in
  // OfflineRun::scans_dropped and yield no result.
  int drop_scans_every = 0;
  double drop_scans_begin_s = 0.0;
  double drop_scans_length_s = 0.0;
  // > 0: the core processes its queued scans only once the IMU fed to it is this far ahead of
  // the oldest of them, as in ppf_node when its core is behind: the executor feeds every queued
  // IMU sample before the next scan, so IMU arrives seconds ahead of the scans waiting. 0: the
  // scans are processed as soon as the bag has given them (bag order).
  double imu_lead_s = 0.0;
};

// Throws ppf::bag::BagError if the bag cannot be read.
OfflineRun RunOffline(const std::string& bag_path, const Config& config,
                      const OfflineOptions& options = OfflineOptions());

}  // namespace ppf::tools
