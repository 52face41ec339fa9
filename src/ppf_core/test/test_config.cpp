// YAML config: missing keys keep defaults, unknown keys warn, wrong types fail with the key name,
// every preset in config/ loads cleanly, reference.yaml holds every key with its default, and
// basic.yaml holds a few of them, documented as there.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "ppf_core/config.hpp"
#include "ppf_core/config_table.hpp"

namespace ppf {
namespace {

TEST(ConfigYaml, EmptyDocumentKeepsAllDefaults) {
  Config c;
  const ConfigLoadReport r = LoadConfigYamlString("", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.warnings.empty());
  const Config d;
  EXPECT_EQ(c.mode, d.mode);
  EXPECT_EQ(c.preprocess.scan_voxel_size, d.preprocess.scan_voxel_size);
  EXPECT_EQ(c.iekf.max_iterations, 4);
  EXPECT_EQ(c.knn.k, 5);
  EXPECT_EQ(c.knn.plane_threshold, 0.1);
  EXPECT_EQ(c.map.resolution, 0.5);
  EXPECT_TRUE(c.extrinsic.T_imu_lidar.isApprox(Eigen::Isometry3d::Identity()));
}

TEST(ConfigYaml, PartialSectionsOverrideOnlyTheirKeys) {
  Config c;
  const ConfigLoadReport r = LoadConfigYamlString(R"(
mode: ppf
preprocess:
  scan_voxel_size: 0.3
time:
  field: t
  stamp: end
  no_time_policy: no_deskew
map:
  nearby: 27
iekf: {max_iterations: 3}
extrinsic:
  T_imu_lidar:
    translation: [0.1, 0.2, 0.3]
    rpy_deg: [0, 0, 90]
ppf:
  plane_least_inliers: 400
)", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();
  EXPECT_EQ(c.mode, Mode::kPpf);
  EXPECT_EQ(c.preprocess.scan_voxel_size, 0.3);
  EXPECT_EQ(c.preprocess.min_range,
            Config().preprocess.min_range);  // untouched key of a present section
  EXPECT_EQ(c.time.field, "t");
  EXPECT_EQ(c.time.stamp, StampPosition::kEnd);
  EXPECT_EQ(c.time.no_time_policy, NoTimePolicy::kNoDeskew);
  EXPECT_EQ(c.map.nearby, NearbyType::kNearby27);
  EXPECT_EQ(c.iekf.max_iterations, 3);
  EXPECT_TRUE(c.extrinsic.T_imu_lidar.translation().isApprox(Eigen::Vector3d(0.1, 0.2, 0.3)));
  // 90 deg yaw: lidar x axis is imu y axis.
  EXPECT_TRUE((c.extrinsic.T_imu_lidar.linear() * Eigen::Vector3d::UnitX())
                  .isApprox(Eigen::Vector3d::UnitY()));
}

TEST(ConfigYaml, UnknownKeysAreWarnedNotFatal) {
  Config c;
  const ConfigLoadReport r = LoadConfigYamlString(R"(
preprocess:
  scan_voxel_sise: 0.3
bogus_section: 1
extrinsic:
  T_lidar_imu: {translation: [1, 2, 3]}
)", &c);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.warnings.size(), 3u);
  EXPECT_NE(r.warnings[0].find("preprocess.scan_voxel_sise"), std::string::npos);
  EXPECT_EQ(c.preprocess.scan_voxel_size, 0.5);
}

TEST(ConfigYaml, WrongTypesFailWithTheKeyName) {
  const struct {
    const char* yaml;
    const char* key;
  } cases[] = {
      {"preprocess:\n  max_range: [1, 2]\n", "preprocess.max_range"},
      {"preprocess:\n  max_range: far\n", "preprocess.max_range"},
      {"iekf:\n  max_iterations: 2.5\n", "iekf.max_iterations"},
      {"map: 3\n", "map"},
      {"mode: fast\n", "mode"},
      {"time:\n  azimuth_clockwise: maybe\n", "time.azimuth_clockwise"},
      {"map:\n  nearby: 8\n", "map.nearby"},
      {"map:\n  max_voxels: -5\n", "map.max_voxels"},
      {"extrinsic:\n  T_imu_lidar:\n    translation: [1, 2]\n", "extrinsic.T_imu_lidar.translation"},
      {"extrinsic:\n  T_imu_lidar:\n    quaternion_wxyz: [0, 0, 0, 0]\n",
       "extrinsic.T_imu_lidar.quaternion_wxyz"},
  };
  for (const auto& tc : cases) {
    Config c;
    c.preprocess.max_range = 77.0;
    const ConfigLoadReport r = LoadConfigYamlString(tc.yaml, &c);
    EXPECT_FALSE(r.ok) << tc.yaml;
    EXPECT_NE(r.error.find(tc.key), std::string::npos) << r.error;
    EXPECT_EQ(c.preprocess.max_range, 77.0);  // a failed load changes nothing
  }
}

TEST(ConfigYaml, SyntaxErrorsAndMissingFilesAreErrors) {
  Config c;
  EXPECT_FALSE(LoadConfigYamlString("map: [1, 2\n", &c).ok);
  EXPECT_FALSE(LoadConfigYamlString("- 1\n- 2\n", &c).ok);  // top level must be a map
  const ConfigLoadReport r = LoadConfigYaml("/nonexistent/ppf.yaml", &c);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("/nonexistent/ppf.yaml"), std::string::npos);
}

TEST(ConfigYaml, NonsensicalValuesAreClampedWithAWarning) {
  Config c;
  const ConfigLoadReport r = LoadConfigYamlString(R"(
preprocess: {scan_voxel_size: 0.0001}
map: {resolution: 0}
iekf: {max_iterations: 0}
knn: {k: 1}
time: {scan_period: 1e300}
)", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.warnings.size(), 5u);
  EXPECT_EQ(c.time.scan_period_s, 0.1);
  EXPECT_GE(c.preprocess.scan_voxel_size, 0.01);
  EXPECT_GE(c.map.resolution, 0.05);
  EXPECT_GE(c.iekf.max_iterations, 1);
  EXPECT_GE(c.knn.k, 3);
}

TEST(ConfigYaml, FuzzedDocumentsNeverThrow) {
  // Mutations of a valid document: every outcome is ok or a clean error, never an exception.
  const std::string base =
      "mode: knn\npreprocess: {min_range: 0.5, max_range: 100}\nmap: {nearby: 19}\n"
      "imu: {init: {acc_scale: 0}}\nextrinsic: {T_imu_lidar: {translation: [0, 0, 0]}}\n";
  const std::string alphabet = "{}[]:,- \n\t\"'#&*!|>%@`abc019.e";
  std::mt19937 rng(99);
  for (int iter = 0; iter < 2000; ++iter) {
    std::string doc = base;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      const size_t at = rng() % doc.size();
      doc[at] = alphabet[rng() % alphabet.size()];
    }
    Config c;
    ConfigLoadReport r;
    EXPECT_NO_THROW(r = LoadConfigYamlString(doc, &c)) << doc;
    if (!r.ok) {
      EXPECT_FALSE(r.error.empty());
    }
  }
}

// Files written before imu: got its init: and noise: groups use the flat keys; they load to the
// same values, each with a warning naming the current key.
TEST(ConfigYaml, FormerFlatImuKeysLoadAsTheirCurrentSpelling) {
  Config old_spelling, new_spelling, defaults;
  const ConfigLoadReport r_old = LoadConfigYamlString(R"(
imu:
  init_duration: 2.5
  init_min_samples: 40
  init_max_acc_std: 0.4
  init_max_gyro_std: 0.06
  init_max_gyro_bias: 0.07
  init_max_gravity_error: 0.35
  moving_start: false
  moving_start_window: 2.0
  moving_start_max_gravity_error: 0.6
  acc_scale: 1.0
  gravity: 9.81
  gyro_noise: 0.02
  acc_noise: 0.03
  gyro_bias_noise: 0.0002
  acc_bias_noise: 0.002
  gravity_dir_noise: 0.001
  gyro_range: 8.7
)", &old_spelling);
  const ConfigLoadReport r_new = LoadConfigYamlString(R"(
imu:
  init:
    duration: 2.5
    min_samples: 40
    max_acc_std: 0.4
    max_gyro_std: 0.06
    max_gyro_bias: 0.07
    max_gravity_error: 0.35
    moving_start: false
    moving_start_window: 2.0
    moving_start_max_gravity_error: 0.6
    acc_scale: 1.0
    gravity: 9.81
  noise:
    gyro: 0.02
    acc: 0.03
    gyro_bias: 0.0002
    acc_bias: 0.002
    gravity_dir: 0.001
    gyro_range: 8.7
)", &new_spelling);
  ASSERT_TRUE(r_old.ok) << r_old.error;
  ASSERT_TRUE(r_new.ok) << r_new.error;
  EXPECT_TRUE(r_new.warnings.empty()) << r_new.warnings.front();
  ASSERT_EQ(r_old.warnings.size(), 17u);
  EXPECT_EQ(r_old.warnings.front(),
            "key 'imu.init_duration' read as 'imu.init.duration' (its current spelling)");
  EXPECT_EQ(r_old.warnings.back(),
            "key 'imu.gyro_range' read as 'imu.noise.gyro_range' (its current spelling)");
  const ConfigTable got = CoreConfigTable(&old_spelling), want = CoreConfigTable(&new_spelling),
                    def = CoreConfigTable(&defaults);
  int changed = 0;
  for (const std::string& key : want.Keys()) {
    EXPECT_EQ(got.ShowValue(key), want.ShowValue(key)) << key;
    changed += want.ShowValue(key) != def.ShowValue(key);
  }
  EXPECT_EQ(changed, 17);  // every key above moved off its default: none was silently dropped
}

TEST(ConfigYaml, CurrentSpellingWinsOverAFormerOneAndErrorsNameTheKeyAsWritten) {
  Config c;
  ConfigLoadReport r = LoadConfigYamlString(
      "imu:\n  gyro_noise: 0.5\n  noise:\n    gyro: 0.02\n", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(c.imu.noise.gyro, 0.02);
  EXPECT_EQ(r.warnings, std::vector<std::string>{
                            "key 'imu.gyro_noise' ignored: its current spelling 'imu.noise.gyro' "
                            "is also set"});
  r = LoadConfigYamlString("imu:\n  init_min_samples: many\n", &c);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error, "key 'imu.init_min_samples': expected an integer, got 'many'");
}

TEST(ConfigYaml, NullValueKeepsDefault) {
  Config c;
  const ConfigLoadReport r = LoadConfigYamlString("preprocess:\n  max_range:\n", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(c.preprocess.max_range, Config().preprocess.max_range);
}

TEST(ConfigYaml, PresetsLoadWithoutWarnings) {
  for (const char* name : {"vlp16", "hdl32", "hdl64", "os1_64", "os1_128", "kitti_raw"}) {
    const std::string path = std::string(PPF_CONFIG_DIR) + "/" + name + ".yaml";
    if (!std::ifstream(path)) GTEST_SKIP() << "presets not found at " << PPF_CONFIG_DIR;
    Config c;
    const ConfigLoadReport r = LoadConfigYaml(path, &c);
    EXPECT_TRUE(r.ok) << name << ": " << r.error;
    EXPECT_TRUE(r.warnings.empty()) << name << ": " << r.warnings.front();
  }
  Config k;
  ASSERT_TRUE(LoadConfigYaml(std::string(PPF_CONFIG_DIR) + "/kitti_raw.yaml", &k).ok);
  EXPECT_NEAR(k.extrinsic.T_imu_lidar.translation().x(), 0.81, 0.01);
  EXPECT_EQ(k.imu.init.acc_scale, 1.0);
}

// --- the reference file: config/reference.yaml lists every key with the struct's default ---------

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

// Keys of the loader's table that `yaml` lacks, leaves without a value, or sets to something
// other than the default, as "key: reason" lines (empty = the text is a faithful reference).
std::vector<std::string> DiffFromDefaults(const std::string& yaml) {
  std::vector<std::string> diffs;
  Config loaded, defaults;
  const ConfigLoadReport r = LoadConfigYamlString(yaml, &loaded);
  if (!r.ok) return {"load failed: " + r.error};
  for (const std::string& w : r.warnings) diffs.push_back("warning: " + w);
  const YAML::Node root = YAML::Load(yaml);
  const ConfigTable got = CoreConfigTable(&loaded), want = CoreConfigTable(&defaults);
  for (const std::string& key : want.Keys()) {
    YAML::Node node = YAML::Clone(root);
    bool present = true;
    for (size_t begin = 0; present;) {
      const size_t dot = key.find('.', begin);
      const std::string part = key.substr(begin, dot == std::string::npos ? dot : dot - begin);
      present = node.IsMap() && node[part];
      if (present) node.reset(node[part]);
      if (dot == std::string::npos) break;
      begin = dot + 1;
    }
    if (!present) {
      diffs.push_back(key + ": missing");
    } else if (!want.ShowValue(key).empty() && node.IsNull()) {
      diffs.push_back(key + ": no value");  // a null value keeps the default: it proves nothing
    } else if (got.ShowValue(key) != want.ShowValue(key)) {
      diffs.push_back(key + ": " + got.ShowValue(key) + " in the file, " + want.ShowValue(key) +
                      " in the struct");
    }
  }
  return diffs;
}

TEST(ReferenceFile, HoldsEveryKeyWithTheStructDefault) {
  const std::string text = ReadText(std::string(PPF_CONFIG_DIR) + "/reference.yaml");
  ASSERT_FALSE(text.empty()) << "config/reference.yaml not found at " << PPF_CONFIG_DIR;
  const std::vector<std::string> diffs = DiffFromDefaults(text);
  std::string all;
  for (const std::string& d : diffs) all += "\n  " + d;
  EXPECT_TRUE(diffs.empty()) << "config/reference.yaml and ppf::Config disagree:" << all;
  Config c;
  EXPECT_GT(CoreConfigTable(&c).Keys().size(), 70u);  // the whole schema, not an empty table
}

// The check above must catch the two ways the reference goes stale.
TEST(ReferenceFile, ACheckThatCatchesAChangedDefaultOrAMissingKey) {
  const std::string text = ReadText(std::string(PPF_CONFIG_DIR) + "/reference.yaml");
  ASSERT_FALSE(text.empty());
  std::string changed = text;
  const size_t at = changed.find("  k: 5 ");
  ASSERT_NE(at, std::string::npos);
  changed.replace(at, 7, "  k: 6 ");  // as if the struct's default had moved to 6
  EXPECT_EQ(DiffFromDefaults(changed),
            std::vector<std::string>{"knn.k: 6 in the file, 5 in the struct"});
  std::string missing = text;
  const size_t line = missing.find("  min_plane_spread:");
  ASSERT_NE(line, std::string::npos);
  missing.erase(line, missing.find('\n', line) + 1 - line);  // a field added without its key
  EXPECT_EQ(DiffFromDefaults(missing), std::vector<std::string>{"knn.min_plane_spread: missing"});
}

// "Fully commented": every key of the table carries a comment on its line or on the line above.
TEST(ReferenceFile, EveryKeyIsCommented) {
  std::istringstream in(ReadText(std::string(PPF_CONFIG_DIR) + "/reference.yaml"));
  Config c;
  const std::vector<std::string> keys = CoreConfigTable(&c).Keys();
  std::vector<std::pair<size_t, std::string>> path;  // (indent, name) of the enclosing sections
  std::string line, previous;
  size_t found = 0;
  while (std::getline(in, line)) {
    const size_t indent = line.find_first_not_of(' ');
    const size_t colon = line.find(':');
    if (indent != std::string::npos && line[indent] != '#' && line[indent] != '-' &&
        colon != std::string::npos && line.find_first_of(" [", indent) > colon) {
      while (!path.empty() && path.back().first >= indent) path.pop_back();
      path.emplace_back(indent, line.substr(indent, colon - indent));
      std::string key;
      for (const auto& [i, name] : path) key += (key.empty() ? "" : ".") + name;
      if (std::find(keys.begin(), keys.end(), key) != keys.end()) {
        ++found;
        const size_t prev = previous.find_first_not_of(' ');
        EXPECT_TRUE(line.find('#') != std::string::npos ||
                    (prev != std::string::npos && previous[prev] == '#'))
            << key << " has no comment in config/reference.yaml";
      }
    }
    if (indent != std::string::npos) previous = line;
  }
  EXPECT_EQ(found, keys.size());
}

// The presets are deltas over the reference: loaded, they differ from the defaults in exactly
// these values (the values the full 94-line presets had before they became deltas).
TEST(ReferenceFile, PresetsDifferOnlyInTheirSensorKeys) {
  const std::map<std::string, std::vector<std::string>> expected = {
      {"vlp16", {"preprocess.max_range: 100", "map.resolution: 1"}},
      {"hdl32", {"preprocess.max_range: 100", "ppf.plane_least_inliers: 150"}},
      {"hdl64", {"preprocess.max_range: 120", "ppf.plane_least_inliers: 400"}},
      {"os1_64", {"preprocess.max_range: 120", "ppf.plane_least_inliers: 400"}},
      {"os1_128", {"preprocess.max_range: 120", "ppf.plane_least_inliers: 600"}},
      {"kitti_raw",
       {"extrinsic.T_imu_lidar", "preprocess.max_range: 120", "time.stamp: start",
        "imu.init.acc_scale: 1", "ppf.plane_least_inliers: 400"}},
  };
  for (const auto& [name, want] : expected) {
    Config preset, defaults;
    const ConfigLoadReport r =
        LoadConfigYaml(std::string(PPF_CONFIG_DIR) + "/" + name + ".yaml", &preset);
    ASSERT_TRUE(r.ok) << name << ": " << r.error;
    const ConfigTable got = CoreConfigTable(&preset), def = CoreConfigTable(&defaults);
    std::vector<std::string> diffs;
    for (const std::string& key : def.Keys()) {
      if (got.ShowValue(key) == def.ShowValue(key)) continue;
      // The extrinsic's printout is long; that it differs is what matters here.
      diffs.push_back(key == "extrinsic.T_imu_lidar" ? key : key + ": " + got.ShowValue(key));
    }
    EXPECT_EQ(diffs, want) << name;
  }
}


// --- the basic file: config/basic.yaml, the few keys a user sets, documented as in the reference --

// What a key's comment says it is: the first clause of its comment (the one on its line, or else
// the first line of the comment block right above it), up to the first ';', ',', ':' or ". ".
// In both files that clause is the unit ("m", "rad/s/sqrt(Hz)") or the choices ("auto | lio |
// none"), so equal clauses mean the same documented meaning.
std::string FirstClause(const std::string& comment) {
  const size_t begin = comment.find_first_not_of("# ");
  if (begin == std::string::npos) return "";
  size_t end = comment.find_first_of(";,:", begin);
  const size_t period = comment.find(". ", begin);
  if (period < end) end = period;
  std::string clause = comment.substr(begin, end == std::string::npos ? end : end - begin);
  while (!clause.empty() && (clause.back() == ' ' || clause.back() == '.')) clause.pop_back();
  return clause;
}

// The keys of the loader's table that `text` sets, each with FirstClause of its comment; any other
// key path (not a section of the table, nor inside a key such as extrinsic.T_imu_lidar) goes to
// *unknown.
std::map<std::string, std::string> DocumentedKeys(const std::string& text,
                                                  std::vector<std::string>* unknown) {
  Config c;
  const std::vector<std::string> keys = CoreConfigTable(&c).Keys();
  const auto starts_with = [](const std::string& s, const std::string& prefix) {
    return s.compare(0, prefix.size(), prefix) == 0;
  };
  std::map<std::string, std::string> found;
  std::istringstream in(text);
  std::vector<std::pair<size_t, std::string>> path;  // (indent, name) of the enclosing sections
  std::vector<std::string> block;                     // comment lines right above this line
  std::string line;
  while (std::getline(in, line)) {
    const size_t indent = line.find_first_not_of(' ');
    if (indent == std::string::npos) {
      block.clear();
      continue;
    }
    if (line[indent] == '#') {
      block.push_back(line.substr(indent));
      continue;
    }
    const size_t colon = line.find(':');
    if (line[indent] != '-' && colon != std::string::npos &&
        line.find_first_of(" [", indent) > colon) {
      while (!path.empty() && path.back().first >= indent) path.pop_back();
      path.emplace_back(indent, line.substr(indent, colon - indent));
      std::string key;
      for (const auto& [i, name] : path) key += (key.empty() ? "" : ".") + name;
      const size_t hash = line.find('#', colon);
      if (std::find(keys.begin(), keys.end(), key) != keys.end()) {
        found[key] = FirstClause(hash != std::string::npos ? line.substr(hash)
                                 : block.empty()           ? std::string()
                                                           : block.front());
      } else if (std::none_of(keys.begin(), keys.end(), [&](const std::string& k) {
                   return starts_with(key, k + ".") || starts_with(k, key + ".");
                 })) {
        unknown->push_back(key);
      }
    }
    block.clear();
  }
  return found;
}

// "key: reason" lines for every key of `basic` that the reference does not hold or documents with
// another unit or choices (empty = a faithful subset of the reference).
std::vector<std::string> BasicFileProblems(const std::string& basic, const std::string& reference) {
  std::vector<std::string> problems, unknown;
  const std::map<std::string, std::string> ref = DocumentedKeys(reference, &unknown);
  for (const std::string& key : unknown) problems.push_back(key + ": unknown in reference.yaml");
  unknown.clear();
  for (const auto& [key, meaning] : DocumentedKeys(basic, &unknown)) {
    const auto it = ref.find(key);
    if (it == ref.end()) {
      problems.push_back(key + ": not in reference.yaml");
    } else if (meaning != it->second) {
      problems.push_back(key + ": '" + meaning + "' here, '" + it->second + "' in reference.yaml");
    }
  }
  for (const std::string& key : unknown) problems.push_back(key + ": not a key of the loader");
  return problems;
}

TEST(BasicFile, LoadsWithoutWarningsToTheDefaults) {
  const std::string path = std::string(PPF_CONFIG_DIR) + "/basic.yaml";
  ASSERT_FALSE(ReadText(path).empty()) << "config/basic.yaml not found at " << PPF_CONFIG_DIR;
  Config basic, defaults;
  const ConfigLoadReport r = LoadConfigYaml(path, &basic);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();
  const ConfigTable got = CoreConfigTable(&basic), want = CoreConfigTable(&defaults);
  for (const std::string& key : want.Keys()) {
    EXPECT_EQ(got.ShowValue(key), want.ShowValue(key)) << key;
  }
}

TEST(BasicFile, HoldsAFewReferenceKeysEachWithTheReferenceMeaning) {
  const std::string basic = ReadText(std::string(PPF_CONFIG_DIR) + "/basic.yaml");
  const std::string reference = ReadText(std::string(PPF_CONFIG_DIR) + "/reference.yaml");
  ASSERT_FALSE(basic.empty());
  ASSERT_FALSE(reference.empty());
  std::vector<std::string> unknown;
  const std::map<std::string, std::string> keys = DocumentedKeys(basic, &unknown);
  EXPECT_GE(keys.size(), 8u);
  EXPECT_LE(keys.size(), 15u);  // the basic file, not a second reference
  for (const auto& [key, meaning] : keys) EXPECT_FALSE(meaning.empty()) << key << " undocumented";
  for (const char* key : {"mode", "extrinsic.T_imu_lidar", "time.field", "imu.mode",
                          "preprocess.scan_voxel_size", "map.resolution", "map.radius",
                          "imu.noise.gyro", "imu.noise.acc", "ppf.beams"}) {
    EXPECT_EQ(keys.count(key), 1u) << key;
  }
  std::string all;
  const std::vector<std::string> problems = BasicFileProblems(basic, reference);
  for (const std::string& p : problems) all += "\n  " + p;
  EXPECT_TRUE(problems.empty()) << "config/basic.yaml and config/reference.yaml disagree:" << all;
}

// The check above must catch a key documented with another unit and a key the loader lacks.
TEST(BasicFile, ACheckThatCatchesAnotherUnitOrAnUnknownKey) {
  const std::string basic = ReadText(std::string(PPF_CONFIG_DIR) + "/basic.yaml");
  const std::string reference = ReadText(std::string(PPF_CONFIG_DIR) + "/reference.yaml");
  ASSERT_FALSE(basic.empty());
  std::string changed = basic;
  const size_t at = changed.find("radius: 150.0           # m;");
  ASSERT_NE(at, std::string::npos);
  changed.replace(changed.find("# m;", at), 4, "# s;");
  changed += "map_radius: 150.0  # m\n";
  EXPECT_EQ(BasicFileProblems(changed, reference),
            (std::vector<std::string>{"map.radius: 's' here, 'm' in reference.yaml",
                                      "map_radius: not a key of the loader"}));
}

}  // namespace
}  // namespace ppf
