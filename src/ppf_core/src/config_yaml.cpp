#include "ppf_core/config_yaml.hpp"

#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

#include "ppf_core/ppf_config.hpp"
#include "ppf_core/so3.hpp"

namespace ppf {
namespace {

// Thrown inside this file only, caught by the loaders.
struct TypeError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string Show(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a map";
  return "null";
}

double AsDouble(const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) throw TypeError("key '" + key + "': expected a number, got " + Show(n));
  try {
    return n.as<double>();
  } catch (const YAML::Exception&) {
    throw TypeError("key '" + key + "': expected a number, got " + Show(n));
  }
}

long long AsInt(const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) throw TypeError("key '" + key + "': expected an integer, got " + Show(n));
  try {
    return n.as<long long>();
  } catch (const YAML::Exception&) {
    throw TypeError("key '" + key + "': expected an integer, got " + Show(n));
  }
}

bool AsBool(const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) throw TypeError("key '" + key + "': expected true/false, got " + Show(n));
  try {
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    throw TypeError("key '" + key + "': expected true/false, got " + Show(n));
  }
}

std::string AsString(const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) throw TypeError("key '" + key + "': expected a string, got " + Show(n));
  return n.Scalar();
}

std::vector<double> AsList(const YAML::Node& n, const std::string& key, size_t size) {
  if (!n.IsSequence() || n.size() != size) {
    throw TypeError("key '" + key + "': expected a list of " + std::to_string(size) +
                    " numbers, got " + Show(n));
  }
  std::vector<double> v;
  for (size_t i = 0; i < size; ++i) v.push_back(AsDouble(n[i], key));
  return v;
}

template <typename E>
E AsEnum(const YAML::Node& n, const std::string& key, const std::map<std::string, E>& values) {
  const std::string s = AsString(n, key);
  const auto it = values.find(s);
  if (it == values.end()) {
    std::string allowed;
    for (const auto& [name, v] : values) allowed += (allowed.empty() ? "" : "|") + name;
    throw TypeError("key '" + key + "': '" + s + "' is not one of " + allowed);
  }
  return it->second;
}

using Setter = std::function<void(const YAML::Node&, const std::string&)>;
using Table = std::map<std::string, Setter>;

Setter Num(double* f) {
  return [f](const YAML::Node& n, const std::string& k) { *f = AsDouble(n, k); };
}
Setter Int(int* f) {
  return [f](const YAML::Node& n, const std::string& k) {
    const long long v = AsInt(n, k);
    if (v < -1000000000LL || v > 1000000000LL) throw TypeError("key '" + k + "': out of range");
    *f = static_cast<int>(v);
  };
}
Setter Size(size_t* f) {
  return [f](const YAML::Node& n, const std::string& k) {
    const long long v = AsInt(n, k);
    if (v < 0) throw TypeError("key '" + k + "': must not be negative");
    *f = static_cast<size_t>(v);
  };
}
Setter Bool(bool* f) {
  return [f](const YAML::Node& n, const std::string& k) { *f = AsBool(n, k); };
}

void ApplyTable(const YAML::Node& section, const std::string& prefix, const Table& table,
                ConfigLoadReport* report) {
  if (!section.IsMap()) {
    throw TypeError("key '" + prefix + "': expected a map, got " + Show(section));
  }
  for (const auto& kv : section) {
    const std::string key = kv.first.Scalar();
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    const auto it = table.find(key);
    if (it == table.end()) {
      report->warnings.push_back("unknown key '" + path + "' ignored");
      continue;
    }
    if (kv.second.IsNull()) continue;  // "key:" with no value keeps the default
    it->second(kv.second, path);
  }
}

Eigen::Isometry3d ParseTransform(const YAML::Node& n, const std::string& key,
                                 ConfigLoadReport* report) {
  if (!n.IsMap()) throw TypeError("key '" + key + "': expected a map, got " + Show(n));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  int rotations = 0;
  for (const auto& kv : n) {
    const std::string k = kv.first.Scalar();
    const std::string path = key + "." + k;
    if (k == "translation") {
      const auto v = AsList(kv.second, path, 3);
      T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    } else if (k == "rotation") {
      const auto v = AsList(kv.second, path, 9);
      Eigen::Matrix3d R;
      R << v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8];
      T.linear() = R;  // ValidateConfig re-orthonormalizes rounded matrices
      ++rotations;
    } else if (k == "quaternion_wxyz") {
      const auto v = AsList(kv.second, path, 4);
      const Eigen::Quaterniond q(v[0], v[1], v[2], v[3]);
      if (q.norm() < 1e-9) throw TypeError("key '" + path + "': zero quaternion");
      T.linear() = q.normalized().toRotationMatrix();
      ++rotations;
    } else if (k == "rpy_deg") {
      const auto v = AsList(kv.second, path, 3);
      const double d2r = 3.14159265358979323846 / 180.0;
      T.linear() = (Eigen::AngleAxisd(v[2] * d2r, Eigen::Vector3d::UnitZ()) *
                    Eigen::AngleAxisd(v[1] * d2r, Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(v[0] * d2r, Eigen::Vector3d::UnitX()))
                       .toRotationMatrix();
      ++rotations;
    } else {
      report->warnings.push_back("unknown key '" + path + "' ignored");
    }
  }
  if (rotations > 1)
    throw TypeError("key '" + key +
                    "': give only one of rotation, "
                    "quaternion_wxyz, rpy_deg");
  return T;
}

void Apply(const YAML::Node& root, Config* c, ConfigLoadReport* report) {
  if (root.IsNull()) return;  // empty file: all defaults
  if (!root.IsMap()) throw TypeError("top level: expected a map, got " + Show(root));

  const Table preprocess = {{"min_range", Num(&c->min_range)},
                            {"max_range", Num(&c->max_range)},
                            {"point_stride", Int(&c->point_stride)},
                            {"scan_voxel_size", Num(&c->scan_voxel_size)}};
  const Table time = {
      {"field",
       [c](const YAML::Node& n, const std::string& k) { c->time.field_name = AsString(n, k); }},
      {"unit_scale", Num(&c->time.unit_scale_s)},
      {"reference",
       [c](const YAML::Node& n, const std::string& k) {
         c->time.reference = AsEnum<TimeReference>(n, k,
                                                   {{"auto", TimeReference::kAuto},
                                                    {"relative", TimeReference::kRelative},
                                                    {"absolute", TimeReference::kAbsolute}});
       }},
      {"stamp",
       [c](const YAML::Node& n, const std::string& k) {
         c->time.stamp_position = AsEnum<StampPosition>(n, k,
                                                        {{"auto", StampPosition::kAuto},
                                                         {"start", StampPosition::kStart},
                                                         {"end", StampPosition::kEnd}});
       }},
      {"no_time_policy",
       [c](const YAML::Node& n, const std::string& k) {
         c->time.no_time_policy = AsEnum<NoTimePolicy>(
             n, k, {{"azimuth", NoTimePolicy::kAzimuth}, {"no_deskew", NoTimePolicy::kNoDeskew}});
       }},
      {"scan_period", Num(&c->time.scan_period_s)},
      {"azimuth_clockwise", Bool(&c->time.azimuth_clockwise)}};
  const Table map = {{"resolution", Num(&c->map.resolution)},
                     {"nearby",
                      [c](const YAML::Node& n, const std::string& k) {
                        const long long v = AsInt(n, k);
                        if (v == 1)
                          c->map.nearby = NearbyType::kCenter;
                        else if (v == 7)
                          c->map.nearby = NearbyType::kNearby7;
                        else if (v == 19)
                          c->map.nearby = NearbyType::kNearby19;
                        else if (v == 27)
                          c->map.nearby = NearbyType::kNearby27;
                        else
                          throw TypeError("key '" + k + "': must be 1, 7, 19 or 27");
                      }},
                     {"max_voxels", Size(&c->map.max_voxels)},
                     {"max_points_per_voxel", Size(&c->map.max_points_per_voxel)},
                     {"min_point_distance", Num(&c->map.min_point_distance)},
                     {"radius", Num(&c->map_radius)}};
  const Table imu = {{"init_duration", Num(&c->init.duration_s)},
                     {"init_min_samples", Int(&c->init.min_samples)},
                     {"init_max_acc_std", Num(&c->init.max_acc_std)},
                     {"init_max_gyro_std", Num(&c->init.max_gyro_std)},
                     {"init_max_gyro_bias", Num(&c->init.max_gyro_bias)},
                     {"init_max_gravity_error", Num(&c->init.max_gravity_error)},
                     {"acc_scale", Num(&c->init.acc_scale)},
                     {"gravity", Num(&c->init.gravity)},
                     {"gyro_noise", Num(&c->noise.gyro)},
                     {"acc_noise", Num(&c->noise.acc)},
                     {"gyro_bias_noise", Num(&c->noise.gyro_bias)},
                     {"acc_bias_noise", Num(&c->noise.acc_bias)},
                     {"gravity_dir_noise", Num(&c->noise.gravity_dir)},
                     {"max_gap", Num(&c->max_imu_gap_s)},
                     {"max_gap_bridge", Num(&c->max_imu_gap_bridge_s)},
                     {"gap_acc_std", Num(&c->gap_acc_std)},
                     {"gap_gyro_std", Num(&c->gap_gyro_std)}};
  const Table iekf = {
      {"max_iterations", Int(&c->iekf.max_iterations)},
      {"convergence_rot", Num(&c->iekf.convergence_rot_rad)},
      {"convergence_trans", Num(&c->iekf.convergence_trans_m)},
      {"laser_point_std", Num(&c->iekf.laser_point_std)},
      {"laser_angular_std", Num(&c->iekf.laser_angular_std)},
      {"refined_gate", Num(&c->iekf.refined_gate)},
      {"refined_gate_after", Num(&c->iekf.refined_gate_after_s)},
      {"residual_max_range", Num(&c->iekf.residual_max_range)},
      {"min_rows", Int(&c->iekf.min_rows)},
      {"degeneracy_min_eig_translation", Num(&c->iekf.degeneracy_min_eig_translation)},
      {"degeneracy_min_eig_rotation", Num(&c->iekf.degeneracy_min_eig_rotation)}};
  const Table knn = {{"k", Int(&c->knn.k)},
                     {"max_neighbor_distance", Num(&c->knn.max_neighbor_distance)},
                     {"plane_threshold", Num(&c->knn.plane_threshold)},
                     {"min_plane_spread", Num(&c->knn.min_plane_spread)},
                     {"max_residual", Num(&c->knn.max_residual)}};

  const Table top = {
      {"mode",
       [c](const YAML::Node& n, const std::string& k) {
         c->mode = AsEnum<Mode>(n, k, {{"knn", Mode::kKnn}, {"ppf", Mode::kPpf}});
       }},
      {"extrinsic",
       [c, report](const YAML::Node& n, const std::string& k) {
         if (!n.IsMap()) throw TypeError("key '" + k + "': expected a map, got " + Show(n));
         for (const auto& kv : n) {
           const std::string name = kv.first.Scalar();
           if (name == "T_imu_lidar") {
             c->T_imu_lidar = ParseTransform(kv.second, k + "." + name, report);
           } else {
             report->warnings.push_back("unknown key '" + k + "." + name +
                                        "' ignored (transforms are named T_<to>_<from>)");
           }
         }
       }},
      {"preprocess",
       [&](const YAML::Node& n, const std::string& k) { ApplyTable(n, k, preprocess, report); }},
      {"time", [&](const YAML::Node& n, const std::string& k) { ApplyTable(n, k, time, report); }},
      {"map", [&](const YAML::Node& n, const std::string& k) { ApplyTable(n, k, map, report); }},
      {"imu", [&](const YAML::Node& n, const std::string& k) { ApplyTable(n, k, imu, report); }},
      {"iekf", [&](const YAML::Node& n, const std::string& k) { ApplyTable(n, k, iekf, report); }},
      {"knn", [&](const YAML::Node& n, const std::string& k) { ApplyTable(n, k, knn, report); }},
      {"num_threads", Int(&c->num_threads)},
      // Plane pre-fitting parameters are read by the PPF config loader (ppf_config.hpp).
      {"ppf",
       [c, report](const YAML::Node& n, const std::string&) {
         const PpfConfigLoadReport r = LoadPpfConfig(n, &c->ppf);
         for (const std::string& w : r.warnings) report->warnings.push_back(w);
         if (!r.ok) throw TypeError(r.error);
       }},
  };
  ApplyTable(root, "", top, report);
}

}  // namespace

ConfigLoadReport LoadConfigYamlString(const std::string& yaml, Config* config) {
  ConfigLoadReport report;
  Config work = *config;  // all or nothing: a failed load leaves *config untouched
  try {
    Apply(YAML::Load(yaml), &work, &report);
  } catch (const TypeError& e) {
    report.ok = false;
    report.error = e.what();
    return report;
  } catch (const YAML::Exception& e) {
    report.ok = false;
    report.error = std::string("YAML syntax error: ") + e.what();
    return report;
  } catch (const std::exception& e) {
    report.ok = false;
    report.error = e.what();
    return report;
  }
  for (const std::string& note : ValidateConfig(&work)) report.warnings.push_back(note);
  *config = work;
  return report;
}

ConfigLoadReport LoadConfigYaml(const std::string& path, Config* config) {
  std::ifstream in(path);
  if (!in) {
    ConfigLoadReport report;
    report.ok = false;
    report.error = "cannot read config file " + path;
    return report;
  }
  std::ostringstream os;
  os << in.rdbuf();
  ConfigLoadReport report = LoadConfigYamlString(os.str(), config);
  if (!report.ok) report.error = path + ": " + report.error;
  return report;
}

}  // namespace ppf
