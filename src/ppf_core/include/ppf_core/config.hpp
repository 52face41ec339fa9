// The core's configuration: the Config struct, its validation and its YAML loader.
//
// The YAML keys, their defaults and what each does are documented in ONE place,
// config/reference.yaml (every key, each value equal to the default here; test_config_yaml fails
// when the two differ, or when a key of the loader's table is missing there). The presets
// (config/vlp16.yaml, ...) hold only what differs from it. The comments below say why a default is
// what it is; the option structs of the stages (time_field.hpp, voxel_map.hpp, ...) do the same.
//
// Validation: ValidateConfig() is the one rule set. LoadConfigYaml() applies it so that a clamped
// value is reported with the file that set it; LioPpf applies it again for configs built in code
// (a config that passed once yields no notes, so nothing is reported twice). The stages trust
// the config they are given.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/lio/hypothesis_search.hpp"
#include "ppf_core/lio/iekf.hpp"
#include "ppf_core/lio/imu_init.hpp"
#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/knn_residual.hpp"
#include "ppf_core/log.hpp"
#include "ppf_core/ppf_config.hpp"
#include "ppf_core/lio/time_field.hpp"
#include "ppf_core/lio/voxel_map.hpp"

namespace ppf {

enum class Mode { kKnn, kPpf };

// Where the prediction comes from (lio_ppf.hpp, "LiDAR-only"). kLio: the IMU (static
// initialization first). kNone: no IMU; a constant-velocity model and several registration
// guesses (hypothesis_search.hpp); IMU samples are ignored. kAuto: kLio as soon as an IMU sample
// arrives; kNone if scans spanning imu_auto_wait_s (or the whole input, at flush) came without one.
enum class ImuMode { kAuto, kLio, kNone };

struct Config {
  Mode mode = Mode::kKnn;

  // LiDAR -> IMU extrinsic: p_imu = T_imu_lidar * p_lidar.
  Eigen::Isometry3d T_imu_lidar = Eigen::Isometry3d::Identity();

  // --- preprocess ------------------------------------------------------------------------------
  double min_range = 0.5;    // metres; closer points (the vehicle itself) are dropped
  double max_range = 150.0;  // metres
  int point_stride = 1;      // keep every n-th point (1 = all)
  TimeFieldOptions time;     // per-point time conventions (time_field.hpp)

  // --- downsample and map ------------------------------------------------------------------------
  double scan_voxel_size = 0.5;  // metres, voxel grid applied to the de-skewed scan
  VoxelMapOptions map;           // kNN map (voxel_map.hpp): 0.5 m voxels, LRU bound
  double map_radius = 150.0;     // voxels farther than this from the sensor are dropped; 0 = off

  // --- IMU -------------------------------------------------------------------------------------
  ImuMode imu_mode = ImuMode::kAuto;
  // Seconds of scans without any IMU sample after which kAuto decides "no IMU". Scans wait (are
  // not lost) meanwhile. Long enough for an IMU driver that starts a moment after the LiDAR's.
  double imu_auto_wait_s = 2.0;
  LidarOnlyOptions lidar_only;  // imu_mode none (hypothesis_search.hpp), YAML section lidar_only:
  ImuInitOptions init;         // static initialization (imu_init.hpp)
  ImuNoise noise;              // continuous-time noise densities (imu_propagation.hpp)
  double max_imu_gap_s = 0.5;  // longer gaps between IMU samples are bridged or re-anchored
  // IMU loss (lio_ppf.hpp): a scan whose end lies more than this beyond the last IMU sample,
  // while later scans show the stream has stalled (max_imu_gap_s), is registered LiDAR-only
  // (constant-velocity model seeded from the filter's velocity and turn rate, the guesses of
  // hypothesis_search.hpp), keeping map, gravity and biases; LIO resumes, re-anchored, when IMU
  // samples are back. Scans closer to the last sample are propagated with it held (extrapolated):
  // a held acceleration and turn rate are only right for a moment, and on the simulated drives
  // the LiDAR-only registration was the more accurate from a quarter second on (the report of
  // issue 16 has the comparison). Shorter values gain nothing: the scan interval is 0.1 s.
  double imu_loss_timeout_s = 0.25;
  // The fine update's prior about the coarse pose for those scans (as lidar_only.prior_*_std).
  // Looser than LiDAR-only's own: the map the fallback registers against was built with the
  // IMU and the coarse alignment starts from the filter's motion, so the scan's own residuals
  // are worth more than the guess; a tight prior held the pose off the map by centimetres.
  double imu_loss_prior_pos_std = 0.3;  // m
  double imu_loss_prior_rot_std = 0.1;  // rad
  // A gap between IMU samples up to this long, without scans that needed the LiDAR-only
  // fallback meanwhile (both streams silent), is bridged: state and map are kept, the IMU is
  // integrated across the gap from the samples on either side (as if it had been constant), and
  // the uncertainty is widened by gap_acc_std / gap_gyro_std for the unmeasured motion, so the
  // next scan re-registers against the map (ScanResult::imu_gap_s says so). Extrapolation errors
  // grow with the square of the gap and registration (0.5 m residual gates) only recovers small
  // ones: measured on the urban HDL-64 replay at 5-7 m/s with the link cut, 2.0 s gaps ended
  // 4-8 cm off after the gap, 2.4 s gaps 6 cm and 0.64 m (height), 2.9 s gaps 2.5-3.1 m. After a
  // longer gap the first scan is registered LiDAR-only and LIO re-anchors (no reset). 0 = never
  // bridge by integration.
  double max_imu_gap_bridge_s = 2.5;
  double gap_acc_std = 1.0;    // m/s^2, unmeasured acceleration assumed during a bridged gap
  double gap_gyro_std = 0.05;  // rad/s, unmeasured turn rate assumed during a bridged gap

  // --- registration ----------------------------------------------------------------------------
  IekfOptions iekf;  // max 4 iterations, degeneracy thresholds (iekf.hpp)
  KnnOptions knn;    // 5 neighbours, planes valid within 0.1 m (knn_residual.hpp)
  // Plane pre-fitting and skeleton tracking (Mode::kPpf), YAML section `ppf:`; why each default
  // is what it is: ppf_config.hpp (PpfConfigForBeams() for 16/32/64/128 beams).
  PpfConfig ppf;

  int num_threads = 0;  // OpenMP threads for de-skew and kNN residuals (0 = OpenMP default)
  // Fill ScanResult::deskewed_points_lidar (the node's registered_points output). Set by the
  // caller that publishes them, not read from YAML.
  bool output_deskewed_points = false;
  LogCallback log;  // receives all messages; nullptr = silent
};

// Clamps nonsensical values to safe ones; returns one note per fix (empty if valid). Never throws.
std::vector<std::string> ValidateConfig(Config* config);

// The outcome of loading a config file (core or ppf_node): the first hard error, naming the key,
// or ok with the warnings (unknown keys, clamped values).
struct ConfigLoadReport {
  bool ok = true;
  std::string error;                  // first hard error (wrong type, unreadable file)
  std::vector<std::string> warnings;  // unknown keys, clamped values
};

// Parses YAML into *config, starting from what *config holds (defaults, or an earlier file: a
// calibration file is layered after a preset this way), then validates (ValidateConfig). All or
// nothing: a failed load leaves *config unchanged. Never throws.
ConfigLoadReport LoadConfigYamlString(const std::string& yaml, Config* config);
ConfigLoadReport LoadConfigYaml(const std::string& path, Config* config);

}  // namespace ppf
