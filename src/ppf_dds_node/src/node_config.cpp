#include "ppf_dds_node/node_config.hpp"

#include <cmath>

#include "ppf_core/config_table.hpp"
#include "ppf_trajectory/map_export.hpp"

namespace ppf::dds {
namespace {

// Every top-level section of the node config; a file with none of them is not a node config.
std::vector<std::string> NodeSections() {
  NodeConfig scratch;
  return NodeConfigTable(&scratch).TopSections();
}

// A file in which no key is ours is the wrong file (typically a core preset such as
// config/vlp16.yaml): starting anyway would run on defaults, Fast DDS's transport included, with
// nothing but a list of warnings to show for it. Returns "" or the error.
std::string NotANodeConfig(const std::string& yaml) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception&) {
    return "";  // the loader reports the syntax error
  }
  if (!root.IsMap() || root.size() == 0) return "";
  const std::vector<std::string> sections = NodeSections();
  std::string keys, all;
  for (const auto& kv : root) {
    if (!kv.first.IsScalar()) return "";  // the loader refuses such a key with its own reason
    for (const std::string& s : sections) {
      if (s == kv.first.Scalar()) return "";
    }
    if (keys.size() < 60) keys += (keys.empty() ? "" : ", ") + kv.first.Scalar();
  }
  for (const std::string& s : sections) all += (all.empty() ? "" : ", ") + s;
  return "not a ppf_node config: none of its keys (" + keys + ") is a node key (" + all +
         "). A core preset (config/<lidar>.yaml) goes in core.config_file of a node config, e.g. "
         "config/node_hdl32.yaml";
}

bool MapFileExtensionOk(const std::string& file) {
  MapFormat format;
  return MapFormatForFile(file, false, &format);
}

// Values no file can mean: clamped with a warning naming the key, or an error.
void ValidateNodeConfig(NodeConfig* c, NodeConfigReport* r) {
  auto clamp_min = [r](int* v, int lo, const char* key) {
    if (*v < lo) {
      r->warnings.push_back(std::string(key) + " = " + std::to_string(*v) + " raised to " +
                            std::to_string(lo));
      *v = lo;
    }
  };
  clamp_min(&c->sensor_depth, 1, "qos.sensor_depth");
  clamp_min(&c->path_max_poses, 1, "outputs.path_max_poses");
  clamp_min(&c->scan_queue_capacity, 1, "queues.scan_capacity");
  clamp_min(&c->imu_queue_capacity, 100, "queues.imu_capacity");
  clamp_min(&c->max_cloud_points, 1, "queues.max_cloud_points");
  if (!(c->diagnostics_period_s > 0.0)) {
    r->warnings.push_back("diagnostics.period_s must be > 0: using 5");
    c->diagnostics_period_s = 5.0;
  }
  if (!(c->malformed_log_interval_s >= 0.0)) c->malformed_log_interval_s = 1.0;
  if (std::isnan(c->stall_warn_s)) {
    r->warnings.push_back("diagnostics.stall_warn_s is not a number: using 5");
    c->stall_warn_s = 5.0;
  }
  // As ppf_offline --map-voxel: finer would cost memory for nothing the core resolves, coarser
  // is no map.
  if (!(c->map_voxel >= 0.01 && c->map_voxel <= 100.0)) {
    r->warnings.push_back("outputs.map_voxel must be in 0.01..100 m: using 0.1");
    c->map_voxel = 0.1;
  }
  if (!c->map_file.empty() && !MapFileExtensionOk(c->map_file)) {
    r->ok = false;
    r->error = "outputs.map_file '" + c->map_file + "' must end in .pcd or .ply";
  }
  if (c->participant.domain_id < 0 || c->participant.domain_id > 232) {
    r->ok = false;
    r->error = "dds.domain_id must be in 0..232";
  }
}

std::string Dirname(const std::string& path) {
  const size_t slash = path.rfind('/');
  return slash == std::string::npos ? "." : path.substr(0, slash);
}

// Relative file names in the config are relative to the config file, so presets work from any
// working directory.
void ResolveRelative(const std::string& base_dir, std::string* file) {
  if (file->empty() || (*file)[0] == '/' || base_dir.empty()) return;
  *file = base_dir + "/" + *file;
}

}  // namespace

ConfigTable NodeConfigTable(NodeConfig* c) {
  ConfigTable t;
  t.Add("dds.domain_id", &c->participant.domain_id);
  t.Add("dds.profiles_file", &c->participant.profiles_file);
  t.Add("dds.profile_name", &c->participant.profile_name);
  t.Add("dds.participant_name", &c->participant.participant_name);
  t.Add("topics.points", &c->points_topic);
  t.Add("topics.imu", &c->imu_topic);
  t.Add("topics.odometry", &c->odometry_topic);
  t.Add("topics.skeleton_planes", &c->skeleton_planes_topic);
  t.Add("topics.tf", &c->tf_topic);
  t.Add("topics.path", &c->path_topic);
  t.Add("topics.registered_points", &c->registered_points_topic);
  t.Add("topics.odometry_imu_rate", &c->odometry_imu_rate_topic);
  t.Add("frames.odom_frame", &c->odom_frame);
  t.Add("frames.base_frame", &c->base_frame);
  t.AddEnum("qos.sensor_reliability", &c->sensor_reliability,
            {{"best_effort", Reliability::kBestEffort}, {"reliable", Reliability::kReliable}});
  t.Add("qos.sensor_depth", &c->sensor_depth);
  t.Add("outputs.tf", &c->publish_tf);
  t.Add("outputs.path", &c->publish_path);
  t.Add("outputs.path_max_poses", &c->path_max_poses);
  t.Add("outputs.skeleton_planes", &c->publish_skeleton_planes);
  t.Add("outputs.registered_points", &c->publish_registered_points);
  t.Add("outputs.odometry_imu_rate", &c->publish_odometry_imu_rate);
  t.Add("outputs.map_file", &c->map_file);
  t.Add("outputs.map_voxel", &c->map_voxel);
  t.Add("queues.scan_capacity", &c->scan_queue_capacity);
  t.Add("queues.imu_capacity", &c->imu_queue_capacity);
  t.Add("queues.max_cloud_points", &c->max_cloud_points);
  t.Add("core.config_file", &c->core_config_file);
  t.Add("core.calibration_file", &c->core_calibration_file);
  // Names, not enums: "" means "leave it" (the core file's mode, the environment's policy).
  t.AddEnum<std::string>("core.mode", &c->core_mode, {{"", ""}, {"knn", "knn"}, {"ppf", "ppf"}});
  t.AddEnum<std::string>("core.omp_wait_policy", &c->omp_wait_policy,
                         {{"passive", "passive"}, {"active", "active"}, {"", ""}});
  t.Add("trajectory.tum_file", &c->tum_file);
  t.Add("diagnostics.period_s", &c->diagnostics_period_s);
  t.Add("diagnostics.malformed_log_interval_s", &c->malformed_log_interval_s);
  t.Add("diagnostics.stall_warn_s", &c->stall_warn_s);
  return t;
}

NodeConfigReport LoadNodeConfigString(const std::string& yaml, NodeConfig* config) {
  NodeConfigReport r;
  r.error = NotANodeConfig(yaml);
  if (!r.error.empty()) {
    r.ok = false;
    return r;
  }
  NodeConfig work = *config;  // all or nothing
  r = LoadWithTable(yaml, NodeConfigTable(&work));
  if (!r.ok) return r;
  ValidateNodeConfig(&work, &r);
  if (r.ok) *config = work;
  return r;
}

NodeConfigReport LoadNodeConfig(const std::string& path, NodeConfig* config) {
  NodeConfigReport r;
  std::string text;
  if (!ReadConfigFile(path, &text, &r)) return r;
  r = LoadNodeConfigString(text, config);
  if (!r.ok) return r;
  const std::string dir = Dirname(path);
  ResolveRelative(dir, &config->participant.profiles_file);
  ResolveRelative(dir, &config->core_config_file);
  ResolveRelative(dir, &config->core_calibration_file);
  return r;
}

}  // namespace ppf::dds
