#include "ppf_dds_node/node_config.hpp"

#include <fstream>
#include <functional>
#include <map>
#include <sstream>

#include <yaml-cpp/yaml.h>

namespace ppf::dds {

namespace {

// Reads `node[key]` into *out if present. A wrong type is a hard error naming the key; a missing
// key keeps the default.
template <typename T>
bool Read(const YAML::Node& section, const std::string& path, const std::string& key, T* out,
          NodeConfigReport* report) {
  const YAML::Node v = section[key];
  if (!v) return true;
  try {
    *out = v.as<T>();
  } catch (const YAML::Exception&) {
    report->ok = false;
    report->error = "config key '" + path + "." + key + "' has the wrong type";
    return false;
  }
  return true;
}

// YAML lets a key be a list or a map ("? [a]: 1", or a stray "? " typed before a key); ours are
// all names, and as<std::string>() would throw on such a key. Returns false and reports it.
bool KeyName(const YAML::Node& key, const std::string& path, std::string* name,
             NodeConfigReport* report) {
  if (!key.IsScalar()) {
    report->ok = false;
    report->error = "config key " +
                    (path.empty() ? std::string("at the top level")
                                  : "in section '" + path.substr(0, path.size() - 1) + "'") +
                    " is a list or a map; keys must be plain names";
    return false;
  }
  *name = key.Scalar();
  return true;
}

void WarnUnknown(const YAML::Node& section, const std::string& path,
                 const std::vector<std::string>& known, NodeConfigReport* report) {
  if (!section.IsMap()) return;
  for (const auto& kv : section) {
    std::string key;
    if (!KeyName(kv.first, path, &key, report)) continue;
    bool found = false;
    for (const auto& k : known) found = found || k == key;
    if (!found) report->warnings.push_back("unknown config key '" + path + key + "' ignored");
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

NodeConfigReport LoadNodeConfigString(const std::string& yaml, NodeConfig* c) {
  NodeConfigReport r;
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception& e) {
    r.ok = false;
    r.error = std::string("invalid YAML: ") + e.what();
    return r;
  }
  if (root.IsNull()) return r;  // empty file: all defaults
  if (!root.IsMap()) {
    r.ok = false;
    r.error = "node config must be a YAML map";
    return r;
  }
  const std::vector<std::string> sections = {
      "dds", "topics", "frames", "qos", "outputs", "queues", "core", "trajectory", "diagnostics"};
  // A file in which no key is ours is the wrong file (typically a core preset such as
  // config/vlp16.yaml): starting anyway would run on defaults, Fast DDS's transport included,
  // with nothing but a list of warnings to show for it.
  if (root.size() > 0) {
    std::string keys;
    bool any_known = false;
    for (const auto& kv : root) {
      std::string key;
      if (!KeyName(kv.first, "", &key, &r)) return r;
      for (const auto& k : sections) any_known = any_known || k == key;
      if (keys.size() < 60) keys += (keys.empty() ? "" : ", ") + key;
    }
    if (!any_known) {
      r.ok = false;
      r.error =
          "not a ppf_node config: none of its keys (" + keys +
          ") is a node key (dds, topics, frames, qos, outputs, queues, core, trajectory, "
          "diagnostics). A core preset (config/<lidar>.yaml) goes in core.config_file of a node "
          "config, e.g. config/node_hdl32.yaml";
      return r;
    }
  }
  WarnUnknown(root, "", sections, &r);
  auto section = [&](const char* name, const std::vector<std::string>& known) {
    YAML::Node s = root[name];
    if (s && !s.IsMap()) {
      r.ok = false;
      r.error = std::string("config section '") + name + "' must be a map";
      return YAML::Node();
    }
    if (s) WarnUnknown(s, std::string(name) + ".", known, &r);
    return s ? s : YAML::Node();
  };

  YAML::Node dds =
      section("dds", {"domain_id", "profiles_file", "profile_name", "participant_name"});
  if (dds) {
    Read(dds, "dds", "domain_id", &c->participant.domain_id, &r);
    Read(dds, "dds", "profiles_file", &c->participant.profiles_file, &r);
    Read(dds, "dds", "profile_name", &c->participant.profile_name, &r);
    Read(dds, "dds", "participant_name", &c->participant.participant_name, &r);
  }
  YAML::Node topics = section("topics", {"points", "imu", "odometry", "skeleton_planes", "tf",
                                         "path", "registered_points"});
  if (topics) {
    Read(topics, "topics", "points", &c->points_topic, &r);
    Read(topics, "topics", "imu", &c->imu_topic, &r);
    Read(topics, "topics", "odometry", &c->odometry_topic, &r);
    Read(topics, "topics", "skeleton_planes", &c->skeleton_planes_topic, &r);
    Read(topics, "topics", "tf", &c->tf_topic, &r);
    Read(topics, "topics", "path", &c->path_topic, &r);
    Read(topics, "topics", "registered_points", &c->registered_points_topic, &r);
  }
  YAML::Node frames = section("frames", {"odom_frame", "base_frame"});
  if (frames) {
    Read(frames, "frames", "odom_frame", &c->odom_frame, &r);
    Read(frames, "frames", "base_frame", &c->base_frame, &r);
  }
  YAML::Node qos = section("qos", {"sensor_reliability", "sensor_depth"});
  if (qos) {
    std::string rel;
    if (Read(qos, "qos", "sensor_reliability", &rel, &r) && !rel.empty()) {
      if (rel == "best_effort") {
        c->sensor_reliability = Reliability::kBestEffort;
      } else if (rel == "reliable") {
        c->sensor_reliability = Reliability::kReliable;
      } else {
        r.ok = false;
        r.error = "qos.sensor_reliability must be best_effort or reliable, not '" + rel + "'";
      }
    }
    Read(qos, "qos", "sensor_depth", &c->sensor_depth, &r);
  }
  YAML::Node outputs =
      section("outputs", {"tf", "path", "path_max_poses", "skeleton_planes", "registered_points"});
  if (outputs) {
    Read(outputs, "outputs", "tf", &c->publish_tf, &r);
    Read(outputs, "outputs", "path", &c->publish_path, &r);
    Read(outputs, "outputs", "path_max_poses", &c->path_max_poses, &r);
    Read(outputs, "outputs", "skeleton_planes", &c->publish_skeleton_planes, &r);
    Read(outputs, "outputs", "registered_points", &c->publish_registered_points, &r);
  }
  YAML::Node queues = section("queues", {"scan_capacity", "imu_capacity", "max_cloud_points"});
  if (queues) {
    Read(queues, "queues", "scan_capacity", &c->scan_queue_capacity, &r);
    Read(queues, "queues", "imu_capacity", &c->imu_queue_capacity, &r);
    Read(queues, "queues", "max_cloud_points", &c->max_cloud_points, &r);
  }
  YAML::Node core = section("core", {"config_file", "calibration_file", "mode", "omp_wait_policy"});
  if (core) {
    Read(core, "core", "config_file", &c->core_config_file, &r);
    Read(core, "core", "calibration_file", &c->core_calibration_file, &r);
    Read(core, "core", "mode", &c->core_mode, &r);
    Read(core, "core", "omp_wait_policy", &c->omp_wait_policy, &r);
    if (!c->omp_wait_policy.empty() && c->omp_wait_policy != "passive" &&
        c->omp_wait_policy != "active") {
      r.ok = false;
      r.error =
          "core.omp_wait_policy must be passive, active or \"\", not '" + c->omp_wait_policy + "'";
    }
    if (!c->core_mode.empty() && c->core_mode != "knn" && c->core_mode != "ppf") {
      r.ok = false;
      r.error = "core.mode must be knn or ppf, not '" + c->core_mode + "'";
    }
  }
  YAML::Node traj = section("trajectory", {"tum_file"});
  if (traj) Read(traj, "trajectory", "tum_file", &c->tum_file, &r);
  YAML::Node diag = section("diagnostics", {"period_s", "malformed_log_interval_s"});
  if (diag) {
    Read(diag, "diagnostics", "period_s", &c->diagnostics_period_s, &r);
    Read(diag, "diagnostics", "malformed_log_interval_s", &c->malformed_log_interval_s, &r);
  }

  auto clamp_min = [&r](int* v, int lo, const char* key) {
    if (*v < lo) {
      r.warnings.push_back(std::string(key) + " = " + std::to_string(*v) + " raised to " +
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
    r.warnings.push_back("diagnostics.period_s must be > 0: using 5");
    c->diagnostics_period_s = 5.0;
  }
  if (!(c->malformed_log_interval_s >= 0.0)) c->malformed_log_interval_s = 1.0;
  if (c->participant.domain_id < 0 || c->participant.domain_id > 232) {
    r.ok = false;
    r.error = "dds.domain_id must be in 0..232";
  }
  return r;
}

NodeConfigReport LoadNodeConfig(const std::string& path, NodeConfig* config) {
  std::ifstream in(path);
  if (!in) {
    NodeConfigReport r;
    r.ok = false;
    r.error = "cannot read node config '" + path + "'";
    return r;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  NodeConfigReport r = LoadNodeConfigString(ss.str(), config);
  const std::string dir = Dirname(path);
  ResolveRelative(dir, &config->participant.profiles_file);
  ResolveRelative(dir, &config->core_config_file);
  ResolveRelative(dir, &config->core_calibration_file);
  return r;
}

}  // namespace ppf::dds
