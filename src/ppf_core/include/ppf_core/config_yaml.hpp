// Config from YAML. Every key is optional: a missing key keeps the default documented in
// lio_ppf.hpp. Unknown keys are warned about (typos must not pass silently); a key with the wrong
// type (e.g. a list where a number is expected) makes loading fail with a message naming the key.
// Nothing here throws out of the functions.
//
// Layout (all sections optional; see config/*.yaml for commented presets):
//   mode: knn | ppf
//   extrinsic: { T_imu_lidar: { translation: [x, y, z],
//                               rotation: [r00 .. r22] (row-major) | quaternion_wxyz: [w, x, y, z]
//                               | rpy_deg: [roll, pitch, yaw] } }
//   preprocess: { min_range, max_range, point_stride, scan_voxel_size }
//   time: { field, unit_scale, reference: auto|relative|absolute, stamp: auto|start|end,
//           no_time_policy: azimuth|no_deskew, scan_period, azimuth_clockwise }
//   map: { resolution, nearby: 7|19|27, max_voxels, max_points_per_voxel, min_point_distance,
//          radius }
//   imu: { init_duration, init_min_samples, init_max_acc_std, init_max_gyro_std, acc_scale,
//          gravity, gyro_noise, acc_noise, gyro_bias_noise, acc_bias_noise, max_gap }
//   iekf: { max_iterations, convergence_rot, convergence_trans, laser_point_std,
//           laser_angular_std, refined_gate, refined_gate_after, residual_max_range,
//           min_rows,
//           degeneracy_min_eig_translation, degeneracy_min_eig_rotation }
//   knn: { k, max_neighbor_distance, plane_threshold, min_plane_spread, max_residual }
//   num_threads: 0
//   ppf: { ... }   (owned by the plane pre-fitting config; not interpreted here, not warned)
#pragma once

#include <string>
#include <vector>

#include "ppf_core/lio_ppf.hpp"

namespace ppf {

struct ConfigLoadReport {
  bool ok = true;
  std::string error;                  // first hard error (wrong type, unreadable file)
  std::vector<std::string> warnings;  // unknown keys, clamped values
};

// Parses YAML text into *config (starting from whatever *config holds, normally defaults).
ConfigLoadReport LoadConfigYamlString(const std::string& yaml, Config* config);
ConfigLoadReport LoadConfigYaml(const std::string& path, Config* config);

}  // namespace ppf
