#include "ppf_core/config.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "ppf_core/config_table.hpp"
#include "ppf_core/lio/so3.hpp"

namespace ppf {
namespace {

// extrinsic.T_imu_lidar: a translation and at most one of three rotation forms (a calibration
// tool writes whichever it has).
void ReadTransform(const YAML::Node& n, const std::string& key, Eigen::Isometry3d* out,
                   std::vector<std::string>* warnings) {
  if (!n.IsMap())
    throw ConfigError("key '" + key + "': expected a map, got " + ConfigTable::Show(n));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  int rotations = 0;
  for (const auto& kv : n) {
    const std::string k = kv.first.IsScalar() ? kv.first.Scalar() : std::string("?");
    const std::string path = key + "." + k;
    if (k == "translation") {
      const auto v = ConfigTable::AsList(kv.second, path, 3);
      T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    } else if (k == "rotation") {
      const auto v = ConfigTable::AsList(kv.second, path, 9);
      Eigen::Matrix3d R;
      R << v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8];
      T.linear() = R;  // ValidateConfig re-orthonormalizes rounded matrices
      ++rotations;
    } else if (k == "quaternion_wxyz") {
      const auto v = ConfigTable::AsList(kv.second, path, 4);
      const Eigen::Quaterniond q(v[0], v[1], v[2], v[3]);
      if (q.norm() < 1e-9) throw ConfigError("key '" + path + "': zero quaternion");
      T.linear() = q.normalized().toRotationMatrix();
      ++rotations;
    } else if (k == "rpy_deg") {
      const auto v = ConfigTable::AsList(kv.second, path, 3);
      const double d2r = 3.14159265358979323846 / 180.0;
      T.linear() = (Eigen::AngleAxisd(v[2] * d2r, Eigen::Vector3d::UnitZ()) *
                    Eigen::AngleAxisd(v[1] * d2r, Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(v[0] * d2r, Eigen::Vector3d::UnitX()))
                       .toRotationMatrix();
      ++rotations;
    } else {
      warnings->push_back("unknown key '" + path + "' ignored");
    }
  }
  if (rotations > 1) {
    throw ConfigError("key '" + key + "': give only one of rotation, quaternion_wxyz, rpy_deg");
  }
  *out = T;
}

std::string ShowTransform(const Eigen::Isometry3d& T) {
  std::ostringstream os;
  os.precision(17);
  os << "translation " << T.translation().transpose() << " rotation "
     << Eigen::Map<const Eigen::Matrix<double, 1, 9>>(
            Eigen::Matrix3d(T.linear().transpose()).data());
  return os.str();
}

}  // namespace

// The schema: every key a config file may hold, bound to its field of *c. The reference file
// config/reference.yaml lists the same keys in the same order with the struct's defaults.
ConfigTable CoreConfigTable(Config* c) {
  ConfigTable t;
  t.AddEnum("mode", &c->mode, {{"knn", Mode::kKnn}, {"ppf", Mode::kPpf}});
  t.AddCustom(
      "extrinsic.T_imu_lidar",
      [c](const YAML::Node& n, const std::string& k, std::vector<std::string>* w) {
        ReadTransform(n, k, &c->extrinsic.T_imu_lidar, w);
      },
      [c] { return ShowTransform(c->extrinsic.T_imu_lidar); });
  t.AddHint("extrinsic", "transforms are named T_<to>_<from>");

  t.Add("preprocess.min_range", &c->preprocess.min_range);
  t.Add("preprocess.max_range", &c->preprocess.max_range);
  t.Add("preprocess.point_stride", &c->preprocess.point_stride);
  t.Add("preprocess.scan_voxel_size", &c->preprocess.scan_voxel_size);

  t.Add("time.field", &c->time.field);
  t.Add("time.unit_scale", &c->time.unit_scale_s);
  t.AddEnum("time.reference", &c->time.reference,
            {{"auto", TimeReference::kAuto},
             {"relative", TimeReference::kRelative},
             {"absolute", TimeReference::kAbsolute}});
  t.AddEnum("time.stamp", &c->time.stamp,
            {{"auto", StampPosition::kAuto},
             {"start", StampPosition::kStart},
             {"end", StampPosition::kEnd}});
  t.AddEnum("time.no_time_policy", &c->time.no_time_policy,
            {{"azimuth", NoTimePolicy::kAzimuth}, {"no_deskew", NoTimePolicy::kNoDeskew}});
  t.Add("time.scan_period", &c->time.scan_period_s);
  t.Add("time.azimuth_clockwise", &c->time.azimuth_clockwise);

  t.Add("map.resolution", &c->map.resolution);
  t.AddCustom(
      "map.nearby",
      [c](const YAML::Node& n, const std::string& k, std::vector<std::string>*) {
        const long long v = ConfigTable::AsInt(n, k);
        if (v != 1 && v != 7 && v != 19 && v != 27) {
          throw ConfigError("key '" + k + "': must be 1, 7, 19 or 27");
        }
        c->map.nearby = static_cast<NearbyType>(v);  // the enum's values are the voxel counts
      },
      [c] { return std::to_string(static_cast<int>(c->map.nearby)); });
  t.Add("map.max_voxels", &c->map.max_voxels);
  t.Add("map.max_points_per_voxel", &c->map.max_points_per_voxel);
  t.Add("map.min_point_distance", &c->map.min_point_distance);
  t.Add("map.radius", &c->map.radius);

  t.AddEnum("imu.mode", &c->imu.mode,
            {{"auto", ImuMode::kAuto}, {"lio", ImuMode::kLio}, {"none", ImuMode::kNone}});
  t.Add("imu.auto_wait", &c->imu.auto_wait_s);
  t.Add("imu.init.duration", &c->imu.init.duration_s);
  t.Add("imu.init.min_samples", &c->imu.init.min_samples);
  t.Add("imu.init.max_acc_std", &c->imu.init.max_acc_std);
  t.Add("imu.init.max_gyro_std", &c->imu.init.max_gyro_std);
  t.Add("imu.init.max_gyro_bias", &c->imu.init.max_gyro_bias);
  t.Add("imu.init.max_gravity_error", &c->imu.init.max_gravity_error);
  t.Add("imu.init.moving_start", &c->imu.init.moving_start);
  t.Add("imu.init.moving_start_window", &c->imu.init.moving_start_window_s);
  t.Add("imu.init.moving_start_max_gravity_error", &c->imu.init.moving_start_max_gravity_error);
  t.Add("imu.init.acc_scale", &c->imu.init.acc_scale);
  t.Add("imu.init.gravity", &c->imu.init.gravity);
  t.Add("imu.noise.gyro", &c->imu.noise.gyro);
  t.Add("imu.noise.acc", &c->imu.noise.acc);
  t.Add("imu.noise.gyro_bias", &c->imu.noise.gyro_bias);
  t.Add("imu.noise.acc_bias", &c->imu.noise.acc_bias);
  t.Add("imu.noise.gravity_dir", &c->imu.noise.gravity_dir);
  t.Add("imu.noise.gyro_range", &c->imu.noise.gyro_range);
  t.Add("imu.max_gap", &c->imu.max_gap_s);
  t.Add("imu.max_gap_warn", &c->imu.max_gap_warn_s);
  t.Add("imu.max_gap_bridge", &c->imu.max_gap_bridge_s);
  t.Add("imu.loss_timeout", &c->imu.loss_timeout_s);
  t.Add("imu.loss_prior_pos_std", &c->imu.loss_prior_pos_std);
  t.Add("imu.loss_prior_rot_std", &c->imu.loss_prior_rot_std);
  t.Add("imu.gap_acc_std", &c->imu.gap_acc_std);
  t.Add("imu.gap_gyro_std", &c->imu.gap_gyro_std);
  // The flat spellings these keys had before imu: got its init: and noise: groups; files written
  // with them load unchanged (config/reference.yaml, "Former spellings").
  for (const char* k : {"duration", "min_samples", "max_acc_std", "max_gyro_std", "max_gyro_bias",
                        "max_gravity_error"}) {
    t.AddAlias(std::string("imu.init_") + k, std::string("imu.init.") + k);
  }
  for (const char* k : {"moving_start", "moving_start_window", "moving_start_max_gravity_error",
                        "acc_scale", "gravity"}) {
    t.AddAlias(std::string("imu.") + k, std::string("imu.init.") + k);
  }
  for (const char* k : {"gyro", "acc", "gyro_bias", "acc_bias", "gravity_dir"}) {
    t.AddAlias(std::string("imu.") + k + "_noise", std::string("imu.noise.") + k);
  }
  t.AddAlias("imu.gyro_range", "imu.noise.gyro_range");

  t.Add("lidar_only.good_fit", &c->lidar_only.good_fit);
  t.Add("lidar_only.good_fit_relative", &c->lidar_only.good_fit_relative);
  t.Add("lidar_only.min_fit", &c->lidar_only.min_fit);
  t.Add("lidar_only.fit_gate", &c->lidar_only.fit_gate);
  t.Add("lidar_only.coarse_iterations", &c->lidar_only.coarse_iterations);
  t.Add("lidar_only.coarse_max_residual", &c->lidar_only.coarse_max_residual);
  t.Add("lidar_only.coarse_points", &c->lidar_only.coarse_points);
  t.Add("lidar_only.offset_deg", &c->lidar_only.offset_deg);
  t.Add("lidar_only.prior_rot_std", &c->lidar_only.prior_rot_std);
  t.Add("lidar_only.prior_pos_std", &c->lidar_only.prior_pos_std);
  t.Add("lidar_only.redeskew_iterations", &c->lidar_only.redeskew_iterations);
  t.Add("lidar_only.redeskew_min_change", &c->lidar_only.redeskew_min_change);

  t.Add("consistency.check", &c->consistency.check);
  t.Add("consistency.fit_ratio", &c->consistency.fit_ratio);
  t.Add("consistency.fit_points", &c->consistency.fit_points);
  t.Add("consistency.max_step_pos", &c->consistency.max_step_pos);
  t.Add("consistency.min_step_sigmas", &c->consistency.min_step_sigmas);
  t.Add("consistency.min_gain", &c->consistency.min_gain);
  t.Add("consistency.turn_deg", &c->consistency.turn_deg);

  t.Add("iekf.max_iterations", &c->iekf.max_iterations);
  t.Add("iekf.convergence_rot", &c->iekf.convergence_rot_rad);
  t.Add("iekf.convergence_trans", &c->iekf.convergence_trans_m);
  t.Add("iekf.laser_point_std", &c->iekf.laser_point_std);
  t.Add("iekf.laser_angular_std", &c->iekf.laser_angular_std);
  t.Add("iekf.refined_gate", &c->iekf.refined_gate);
  t.Add("iekf.refined_gate_after", &c->iekf.refined_gate_after_s);
  t.Add("iekf.min_rows", &c->iekf.min_rows);
  t.Add("iekf.residual_max_range", &c->iekf.residual_max_range);
  t.Add("iekf.degeneracy_min_eig_translation", &c->iekf.degeneracy_min_eig_translation);
  t.Add("iekf.degeneracy_min_eig_rotation", &c->iekf.degeneracy_min_eig_rotation);

  t.Add("knn.k", &c->knn.k);
  t.Add("knn.max_neighbor_distance", &c->knn.max_neighbor_distance);
  t.Add("knn.plane_threshold", &c->knn.plane_threshold);
  t.Add("knn.min_plane_spread", &c->knn.min_plane_spread);
  t.Add("knn.max_residual", &c->knn.max_residual);
  t.Add("knn.search_again_distance", &c->knn.search_again_distance);

  t.Add("num_threads", &c->num_threads);

  // First in its section (the table applies keys in this order): it replaces the whole section
  // with PpfConfigForBeams(n), which the other ppf keys then override.
  t.AddCustom(
      "ppf.beams",
      [c](const YAML::Node& n, const std::string& k, std::vector<std::string>*) {
        const long long beams = ConfigTable::AsInt(n, k);
        if (beams < 0 || beams > 100000) throw ConfigError("key '" + k + "': out of range");
        c->ppf = PpfConfigForBeams(static_cast<int>(beams));
      },
      nullptr);
  PpfConfig* p = &c->ppf;
  t.Add("ppf.plane_least_inliers", &p->plane_least_inliers);
  t.Add("ppf.incremental_fitting", &p->incremental_fitting);
  t.Add("ppf.max_band_rms_ratio", &p->max_band_rms_ratio);
  t.Add("ppf.min_elevation_spread_deg", &p->min_elevation_spread_deg);
  t.Add("ppf.delta", &p->delta);
  t.Add("ppf.semi_band_factor", &p->semi_band_factor);
  t.Add("ppf.point_to_plane_thresh", &p->point_to_plane_thresh);
  t.Add("ppf.skeleton_normal_gate_deg", &p->skeleton_normal_gate_deg);
  t.Add("ppf.skeleton_rows_per_plane", &p->skeleton_rows_per_plane);
  t.Add("ppf.anchor_patches", &p->anchor_patches);
  t.Add("ppf.patch_window_fallback", &p->patch_window_fallback);
  t.Add("ppf.patch_size", &p->patch_size);
  t.Add("ppf.patch_max_points", &p->patch_max_points);
  t.Add("ppf.patch_radius", &p->patch_radius);
  t.Add("ppf.max_planes_per_scan", &p->max_planes_per_scan);
  t.Add("ppf.min_remaining_ratio", &p->min_remaining_ratio);
  t.Add("ppf.ransac_max_iterations", &p->ransac_max_iterations);
  t.Add("ppf.ransac_confidence", &p->ransac_confidence);
  t.Add("ppf.ransac_max_degenerate_samples", &p->ransac_max_degenerate_samples);
  t.Add("ppf.ransac_min_sample_area", &p->ransac_min_sample_area);
  t.Add("ppf.ransac_seed", &p->ransac_seed);
  t.Add("ppf.ipca_iterations_new", &p->ipca_iterations_new);
  t.Add("ppf.ipca_iterations_guess", &p->ipca_iterations_guess);
  t.Add("ppf.window_size", &p->window_size);
  t.Add("ppf.window_max_missed_scans", &p->window_max_missed_scans);
  t.Add("ppf.track_max_angle_deg", &p->track_max_angle_deg);
  t.Add("ppf.track_max_offset", &p->track_max_offset);
  t.Add("ppf.num_threads", &p->num_threads);
  return t;
}

namespace {

// Clamps a value that cannot work to a safe one and says so in a note naming the YAML key
// (config/reference.yaml), so a clamped value can be found in the file that set it.
class Fixer {
 public:
  explicit Fixer(std::vector<std::string>* notes) : notes_(notes) {}
  template <typename T, typename V>
  void operator()(bool bad, const std::string& what, T* field, V value) {
    if (!bad) return;
    std::ostringstream os;
    os << what << ": " << *field << " -> " << value;
    notes_->push_back(os.str());
    *field = value;
  }

 private:
  std::vector<std::string>* notes_;
};

void ValidatePreprocessMapAndTime(Config* c, Fixer& fix) {
  PreprocessConfig& pre = c->preprocess;
  fix(!(pre.min_range >= 0.0), "preprocess.min_range", &pre.min_range, 0.0);
  fix(!(pre.max_range > pre.min_range), "preprocess.max_range", &pre.max_range,
      pre.min_range + 100.0);
  fix(pre.point_stride < 1, "preprocess.point_stride", &pre.point_stride, 1);
  fix(!(pre.scan_voxel_size >= 0.0), "preprocess.scan_voxel_size", &pre.scan_voxel_size, 0.5);
  fix(pre.scan_voxel_size > 0.0 && pre.scan_voxel_size < 0.01, "preprocess.scan_voxel_size",
      &pre.scan_voxel_size, 0.01);
  fix(!(c->map.resolution >= 0.05), "map.resolution", &c->map.resolution, 0.05);
  fix(c->map.max_voxels < 1000, "map.max_voxels", &c->map.max_voxels, size_t{1000});
  fix(c->map.max_points_per_voxel < 1, "map.max_points_per_voxel", &c->map.max_points_per_voxel,
      size_t{1});
  fix(!(c->map.min_point_distance >= 0.0), "map.min_point_distance", &c->map.min_point_distance,
      0.0);
  fix(!(c->map.radius >= 0.0), "map.radius", &c->map.radius, 0.0);
  fix(!(c->time.scan_period_s > 0.0 && c->time.scan_period_s <= kMaxScanPeriodS),
      "time.scan_period", &c->time.scan_period_s, 0.1);
  fix(!(c->time.unit_scale_s >= 0.0), "time.unit_scale", &c->time.unit_scale_s, 0.0);
  fix(!(c->imu.auto_wait_s >= 0.0), "imu.auto_wait", &c->imu.auto_wait_s, 2.0);
}

void ValidateConsistency(Config* c, Fixer& fix) {
  ConsistencyOptions* co = &c->consistency;
  fix(!(co->fit_ratio >= 0.0 && co->fit_ratio <= 1.0), "consistency.fit_ratio", &co->fit_ratio, 0.7);
  fix(co->fit_points < 100, "consistency.fit_points", &co->fit_points, 100);
  fix(!(co->max_step_pos > 0.0), "consistency.max_step_pos", &co->max_step_pos, 0.1);
  fix(!(co->min_step_sigmas >= 0.0), "consistency.min_step_sigmas", &co->min_step_sigmas, 15.0);
  fix(!(co->min_gain >= 0.0 && co->min_gain <= 1.0), "consistency.min_gain", &co->min_gain, 0.1);
  fix(!(co->turn_deg >= 0.0 && co->turn_deg <= 45.0), "consistency.turn_deg", &co->turn_deg, 7.5);
}

void ValidateLidarOnly(Config* c, Fixer& fix) {
  LidarOnlyOptions* lo = &c->lidar_only;
  fix(!(lo->good_fit >= 0.0 && lo->good_fit <= 1.0), "lidar_only.good_fit", &lo->good_fit, 0.8);
  fix(!(lo->good_fit_relative >= 0.0 && lo->good_fit_relative <= 1.0),
      "lidar_only.good_fit_relative", &lo->good_fit_relative, 0.95);
  fix(!(lo->min_fit >= 0.0 && lo->min_fit <= 1.0), "lidar_only.min_fit", &lo->min_fit, 0.5);
  fix(!(lo->fit_gate > 0.0), "lidar_only.fit_gate", &lo->fit_gate, 0.1);
  fix(lo->coarse_iterations < 1 || lo->coarse_iterations > 50, "lidar_only.coarse_iterations",
      &lo->coarse_iterations, 10);
  fix(!(lo->coarse_max_residual > 0.0), "lidar_only.coarse_max_residual", &lo->coarse_max_residual,
      1.0);
  fix(lo->coarse_points < 100, "lidar_only.coarse_points", &lo->coarse_points, 100);
  fix(!(lo->offset_deg >= 0.0 && lo->offset_deg <= 90.0), "lidar_only.offset_deg", &lo->offset_deg,
      15.0);
  fix(!(lo->prior_rot_std > 0.0), "lidar_only.prior_rot_std", &lo->prior_rot_std, 0.05);
  fix(!(lo->prior_pos_std > 0.0), "lidar_only.prior_pos_std", &lo->prior_pos_std, 0.1);
  fix(lo->redeskew_iterations < 0 || lo->redeskew_iterations > 10, "lidar_only.redeskew_iterations",
      &lo->redeskew_iterations, 0);
  fix(!(lo->redeskew_min_change >= 0.0), "lidar_only.redeskew_min_change", &lo->redeskew_min_change,
      0.002);
}

void ValidateImu(Config* c, Fixer& fix) {
  fix(!(c->imu.init.duration_s >= 0.0), "imu.init.duration", &c->imu.init.duration_s, 1.0);
  fix(c->imu.init.min_samples < 2, "imu.init.min_samples", &c->imu.init.min_samples, 2);
  fix(!(c->imu.init.moving_start_window_s >= 0.3 && c->imu.init.moving_start_window_s <= 10.0),
      "imu.init.moving_start_window", &c->imu.init.moving_start_window_s, 1.5);
  fix(!(c->imu.init.moving_start_max_gravity_error > 0.0),
      "imu.init.moving_start_max_gravity_error", &c->imu.init.moving_start_max_gravity_error, 0.5);
  fix(!(c->imu.max_gap_s > 0.0), "imu.max_gap", &c->imu.max_gap_s, 0.5);
  fix(!(c->imu.max_gap_warn_s > 0.0), "imu.max_gap_warn", &c->imu.max_gap_warn_s, 0.1);
  fix(!(c->imu.max_gap_bridge_s >= 0.0), "imu.max_gap_bridge", &c->imu.max_gap_bridge_s, 0.0);
  fix(!(c->imu.loss_timeout_s > 0.0), "imu.loss_timeout", &c->imu.loss_timeout_s, 0.25);
  fix(!(c->imu.loss_prior_pos_std > 0.0), "imu.loss_prior_pos_std", &c->imu.loss_prior_pos_std,
      0.3);
  fix(!(c->imu.loss_prior_rot_std > 0.0), "imu.loss_prior_rot_std", &c->imu.loss_prior_rot_std,
      0.1);
  fix(!(c->imu.gap_acc_std >= 0.0), "imu.gap_acc_std", &c->imu.gap_acc_std, 1.0);
  fix(!(c->imu.gap_gyro_std >= 0.0), "imu.gap_gyro_std", &c->imu.gap_gyro_std, 0.05);
  fix(!(c->imu.noise.gyro >= 0.0), "imu.noise.gyro", &c->imu.noise.gyro, 0.01);
  fix(!(c->imu.noise.acc >= 0.0), "imu.noise.acc", &c->imu.noise.acc, 0.02);
  fix(!(c->imu.noise.gyro_bias >= 0.0), "imu.noise.gyro_bias", &c->imu.noise.gyro_bias, 1e-4);
  fix(!(c->imu.noise.acc_bias >= 0.0), "imu.noise.acc_bias", &c->imu.noise.acc_bias, 1e-3);
  fix(!(c->imu.noise.gravity_dir >= 0.0), "imu.noise.gravity_dir", &c->imu.noise.gravity_dir, 0.0);
  fix(!(c->imu.noise.gyro_range >= 0.0) || !std::isfinite(c->imu.noise.gyro_range),
      "imu.noise.gyro_range", &c->imu.noise.gyro_range, 0.0);
}

void ValidateIekfAndKnn(Config* c, Fixer& fix) {
  fix(c->iekf.max_iterations < 1, "iekf.max_iterations", &c->iekf.max_iterations, 1);
  fix(c->iekf.max_iterations > 30, "iekf.max_iterations", &c->iekf.max_iterations, 30);
  fix(!(c->iekf.laser_point_std > 0.0), "iekf.laser_point_std", &c->iekf.laser_point_std, 0.3);
  fix(!(c->iekf.laser_angular_std >= 0.0), "iekf.laser_angular_std", &c->iekf.laser_angular_std,
      0.05);
  fix(!(c->iekf.refined_gate >= 0.0), "iekf.refined_gate", &c->iekf.refined_gate, 0.1);
  fix(!(c->iekf.refined_gate_after_s >= 0.0), "iekf.refined_gate_after",
      &c->iekf.refined_gate_after_s, 3.0);
  fix(c->iekf.min_rows < 6, "iekf.min_rows", &c->iekf.min_rows, 6);
  fix(!(c->iekf.residual_max_range >= 0.0), "iekf.residual_max_range", &c->iekf.residual_max_range,
      0.0);
  fix(c->knn.k < 3, "knn.k", &c->knn.k, 3);
  fix(c->knn.k > 50, "knn.k", &c->knn.k, 50);
  fix(!(c->knn.plane_threshold > 0.0), "knn.plane_threshold", &c->knn.plane_threshold, 0.1);
  fix(!(c->knn.max_neighbor_distance > 0.0), "knn.max_neighbor_distance",
      &c->knn.max_neighbor_distance, 1.0);
  fix(!(c->knn.max_residual > 0.0), "knn.max_residual", &c->knn.max_residual, 0.5);
  fix(!(c->knn.search_again_distance >= 0.0), "knn.search_again_distance",
      &c->knn.search_again_distance, 0.0);
}

// A rotation that is not one (rounded digits in a YAML file) is re-orthonormalized; a broken one
// replaced by the identity.
void ValidateExtrinsic(Config* c, std::vector<std::string>* notes) {
  const Eigen::Matrix3d R = c->extrinsic.T_imu_lidar.linear();
  if (!c->extrinsic.T_imu_lidar.matrix().allFinite() ||
      (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() < 0) {
    notes->push_back("extrinsic.T_imu_lidar rotation is not a rotation: re-orthonormalized");
    if (c->extrinsic.T_imu_lidar.matrix().allFinite() && R.determinant() > 0) {
      c->extrinsic.T_imu_lidar.linear() = NormalizeRotation(R);
    } else {
      c->extrinsic.T_imu_lidar = Eigen::Isometry3d::Identity();
      notes->back() = "extrinsic.T_imu_lidar invalid: identity used";
    }
  }
}

}  // namespace

std::vector<std::string> ValidateConfig(Config* c) {
  std::vector<std::string> notes;
  Fixer fix(&notes);
  ValidatePreprocessMapAndTime(c, fix);
  ValidateLidarOnly(c, fix);
  ValidateConsistency(c, fix);
  ValidateImu(c, fix);
  ValidateIekfAndKnn(c, fix);
  for (const std::string& note : ValidatePpfConfig(&c->ppf)) notes.push_back(note);  // PPF
  ValidateExtrinsic(c, &notes);
  return notes;
}

ConfigLoadReport LoadConfigYamlString(const std::string& yaml, Config* config) {
  Config work = *config;  // all or nothing: a failed load leaves *config untouched
  ConfigLoadReport report = LoadWithTable(yaml, CoreConfigTable(&work));
  if (!report.ok) return report;
  for (const std::string& note : ValidateConfig(&work)) report.warnings.push_back(note);
  *config = work;
  return report;
}

ConfigLoadReport LoadConfigYaml(const std::string& path, Config* config) {
  ConfigLoadReport report;
  std::string text;
  if (!ReadConfigFile(path, &text, &report)) return report;
  report = LoadConfigYamlString(text, config);
  if (!report.ok) report.error = path + ": " + report.error;
  return report;
}

}  // namespace ppf
