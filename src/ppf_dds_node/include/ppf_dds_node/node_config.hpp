// ppf_node configuration. Every YAML key is optional; the defaults below are what runs without a
// file. The keys, their defaults and what each does: config/node.yaml, the node's reference file
// (test_node_units checks that it lists every key of the loader's table with the default here).
// Read by the core's one table-driven loader (ppf_core/config_table.hpp), so a node config fails
// and warns exactly like a core config.
#pragma once

#include <string>
#include <vector>

#include "ppf_core/config.hpp"
#include "ppf_dds_node/dds_common.hpp"

namespace ppf {
class ConfigTable;  // ppf_core/config_table.hpp (yaml-cpp stays out of this header)
}

namespace ppf::dds {

struct NodeConfig {
  ParticipantOptions participant{0, "", "", "ppf_node"};

  std::string points_topic = "/points";
  std::string imu_topic = "/imu";
  std::string odometry_topic = "/odometry";
  std::string skeleton_planes_topic = "/skeleton_planes";
  std::string tf_topic = "/tf";
  std::string path_topic = "/path";
  std::string registered_points_topic = "/registered_points";
  // The odometry at the IMU's rate: the last scan's posterior propagated with each IMU sample.
  std::string odometry_imu_rate_topic = "/odometry/imu";

  std::string odom_frame = "odom";
  std::string base_frame = "base_link";  // the IMU body frame: odometry is the IMU's pose

  // Best effort matches both best-effort and reliable drivers (a reliable reader would not match
  // a best-effort writer).
  Reliability sensor_reliability = Reliability::kBestEffort;
  int sensor_depth = 5;

  bool publish_tf = true;
  bool publish_path = true;
  int path_max_poses = 1000;  // /path keeps the last N poses (bounded message and memory)
  bool publish_skeleton_planes = true;
  bool publish_registered_points = false;
  bool publish_odometry_imu_rate = true;
  // Every scan with a trusted pose (status ok or degenerate, not re-localized after a long gap)
  // accumulated in the world (odom) frame, one point per map_voxel-sized voxel, written to
  // map_file at shutdown and on SIGUSR1: binary PCD (.pcd) or binary PLY (.ply), as ppf_offline
  // --map-out. "" = off.
  std::string map_file;
  double map_voxel = 0.1;  // m; as ppf_offline --map-voxel

  // Scans waiting for the core; when full the oldest is dropped (and counted).
  int scan_queue_capacity = 4;
  // IMU samples waiting for the core: ~4 min at 400 Hz; exceeding it is logged as an error.
  int imu_queue_capacity = 100000;
  // Larger clouds are refused in the listener (counted, logged): with the queue and the buffer
  // pool this bounds the memory input can take. 4M points is >10x a 128-beam LiDAR's scan.
  int max_cloud_points = 4000000;

  std::string core_config_file;
  // Layered after core_config_file: the robot's own calibration (T_imu_lidar), e.g. the
  // calibration.yaml that ppf_sim writes next to a sequence.
  std::string core_calibration_file;
  std::string core_mode;  // "", "knn" or "ppf" ("" = as in core_config_file)
  // OpenMP idle workers: "passive" (sleep), "active" (spin) or "" (leave the environment alone).
  // Spinning workers compete with the DDS and executor threads (and the core's own next
  // iteration) when CPUs are shared (ppf_latency_bench --omp-wait-policy compares the two).
  // Applied by re-executing ppf_node once with OMP_WAIT_POLICY set, unless
  // OMP_WAIT_POLICY is already in the environment (an explicit choice wins).
  std::string omp_wait_policy = "passive";
  std::string tum_file;

  double diagnostics_period_s = 5.0;
  double malformed_log_interval_s = 1.0;
  // A stream with a matched publisher and no sample for this long is reported as stalled
  // (status line, WARN, counted once data had flowed); <= 0 turns the watch off.
  double stall_warn_s = 5.0;
};

// The one report type of every config loader: the first error (naming the key) or the warnings.
using NodeConfigReport = ConfigLoadReport;

// The node's schema bound to *config: every key the loader reads (tests compare config/node.yaml
// with the defaults through it).
ConfigTable NodeConfigTable(NodeConfig* config);

// Parses YAML into *config (starting from what it holds), then clamps nonsense with a warning.
// All or nothing: a failed load leaves *config unchanged. A file in which no top-level key is a
// node section (typically a core preset) is refused. Never throws.
NodeConfigReport LoadNodeConfigString(const std::string& yaml, NodeConfig* config);
// As above, from a file; relative file names in it (dds.profiles_file, core.config_file,
// core.calibration_file) are made relative to the file's directory.
NodeConfigReport LoadNodeConfig(const std::string& path, NodeConfig* config);

}  // namespace ppf::dds
