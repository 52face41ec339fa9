#include "ppf_core/config_table.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace ppf {
namespace {

// Shortest text that reads back to the same double: the reference-file test compares values
// through it, so 0.1 in a file and 0.1 in the struct must print alike, and 100 as "100".
std::string ShowDouble(double v) {
  char buf[40];
  if (v > -1e15 && v < 1e15 && v == std::floor(v)) {  // NaN fails the range test
    std::snprintf(buf, sizeof(buf), "%lld", static_cast<long long>(v));
    return buf;
  }
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

// The value at a dotted key; a null node if it is absent. Returns fresh handles on purpose:
// assigning one YAML::Node to another would overwrite the document's node instead.
YAML::Node Lookup(const YAML::Node& map, const std::string& key) {
  if (!map.IsMap()) return YAML::Node();
  const size_t dot = key.find('.');
  const YAML::Node child = map[key.substr(0, dot)];
  if (!child) return YAML::Node();
  return dot == std::string::npos ? child : Lookup(child, key.substr(dot + 1));
}

}  // namespace

std::string ConfigTable::Show(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a map";
  return "null";
}

std::string ConfigTable::AsScalar(const YAML::Node& n, const std::string& key,
                                  const char* expected) {
  if (!n.IsScalar()) {
    throw ConfigError("key '" + key + "': expected " + expected + ", got " + Show(n));
  }
  return n.Scalar();
}

double ConfigTable::AsDouble(const YAML::Node& n, const std::string& key) {
  AsScalar(n, key, "a number");
  try {
    return n.as<double>();
  } catch (const YAML::Exception&) {
    throw ConfigError("key '" + key + "': expected a number, got " + Show(n));
  }
}

long long ConfigTable::AsInt(const YAML::Node& n, const std::string& key) {
  AsScalar(n, key, "an integer");
  try {
    return n.as<long long>();
  } catch (const YAML::Exception&) {
    throw ConfigError("key '" + key + "': expected an integer, got " + Show(n));
  }
}

std::vector<double> ConfigTable::AsList(const YAML::Node& n, const std::string& key, size_t size) {
  if (!n.IsSequence() || n.size() != size) {
    throw ConfigError("key '" + key + "': expected a list of " + std::to_string(size) +
                      " numbers, got " + Show(n));
  }
  std::vector<double> v;
  for (size_t i = 0; i < size; ++i) v.push_back(AsDouble(n[i], key));
  return v;
}

void ConfigTable::Add(const std::string& key, double* field) {
  AddCustom(
      key,
      [field](const YAML::Node& n, const std::string& k, std::vector<std::string>*) {
        *field = AsDouble(n, k);
      },
      [field] { return ShowDouble(*field); });
}

void ConfigTable::Add(const std::string& key, int* field) {
  AddCustom(
      key,
      [field](const YAML::Node& n, const std::string& k, std::vector<std::string>*) {
        const long long v = AsInt(n, k);
        if (v < -1000000000LL || v > 1000000000LL)
          throw ConfigError("key '" + k + "': out of range");
        *field = static_cast<int>(v);
      },
      [field] { return std::to_string(*field); });
}

// Any unsigned field: a negative value is refused rather than wrapped (yaml-cpp would read "-1"
// as a huge count or seed).
namespace {

template <typename U>
ConfigTable::Setter UnsignedSetter(U* field) {
  return [field](const YAML::Node& n, const std::string& k, std::vector<std::string>*) {
    const std::string text = ConfigTable::AsScalar(n, k, "a non-negative integer");
    if (!text.empty() && text[0] == '-') {
      throw ConfigError("key '" + k + "': must not be negative");
    }
    try {
      *field = n.as<U>();
    } catch (const YAML::Exception&) {
      throw ConfigError("key '" + k + "': expected a non-negative integer, got " +
                        ConfigTable::Show(n));
    }
  };
}

}  // namespace

void ConfigTable::Add(const std::string& key, unsigned long* field) {
  AddCustom(key, UnsignedSetter(field), [field] { return std::to_string(*field); });
}

void ConfigTable::Add(const std::string& key, unsigned long long* field) {
  AddCustom(key, UnsignedSetter(field), [field] { return std::to_string(*field); });
}

void ConfigTable::Add(const std::string& key, bool* field) {
  AddCustom(
      key,
      [field](const YAML::Node& n, const std::string& k, std::vector<std::string>*) {
        AsScalar(n, k, "true/false");
        try {
          *field = n.as<bool>();
        } catch (const YAML::Exception&) {
          throw ConfigError("key '" + k + "': expected true/false, got " + Show(n));
        }
      },
      [field] { return std::string(*field ? "true" : "false"); });
}

void ConfigTable::Add(const std::string& key, std::string* field) {
  AddCustom(
      key,
      [field](const YAML::Node& n, const std::string& k, std::vector<std::string>*) {
        *field = AsScalar(n, k, "a string");
      },
      [field] { return "'" + *field + "'"; });
}

void ConfigTable::AddCustom(const std::string& key, Setter set, Shower show) {
  entries_.push_back({key, std::move(set), std::move(show)});
}

void ConfigTable::AddHint(const std::string& section, const std::string& hint) {
  hints_.emplace_back(section, hint);
}

void ConfigTable::AddAlias(const std::string& old_key, const std::string& key) {
  if (!IsKey(key)) {
    throw std::logic_error("alias '" + old_key + "' of unknown key '" + key + "'");
  }
  aliases_.emplace_back(old_key, key);
}

bool ConfigTable::IsAlias(const std::string& path) const {
  for (const auto& alias : aliases_) {
    if (alias.first == path) return true;
  }
  return false;
}

bool ConfigTable::IsKey(const std::string& path) const {
  for (const Entry& e : entries_) {
    if (e.key == path) return true;
  }
  return false;
}

bool ConfigTable::IsSection(const std::string& path) const {
  const std::string prefix = path + ".";
  for (const Entry& e : entries_) {
    if (e.key.compare(0, prefix.size(), prefix) == 0) return true;
  }
  return false;
}

// Walks the document once, in file order, before anything is set: sections must be maps, keys
// plain names, and unknown keys are warned about where they stand.
void ConfigTable::CheckKeys(const YAML::Node& map, const std::string& prefix,
                            std::vector<std::string>* warnings) const {
  for (const auto& kv : map) {
    // YAML allows a list or a map as a key ("? [a]: 1", a stray "? " typed before a key); ours are
    // all names, and reading such a key as one would throw inside yaml-cpp.
    if (!kv.first.IsScalar()) {
      throw ConfigError(
          "config key " +
          (prefix.empty() ? std::string("at the top level") : "in section '" + prefix + "'") +
          " is a list or a map; keys must be plain names");
    }
    const std::string path = prefix.empty() ? kv.first.Scalar() : prefix + "." + kv.first.Scalar();
    if (IsKey(path) || IsAlias(path)) continue;
    if (IsSection(path)) {
      if (kv.second.IsNull()) continue;  // "section:" with nothing under it: all defaults
      if (!kv.second.IsMap()) {
        throw ConfigError("key '" + path + "': expected a map, got " + Show(kv.second));
      }
      CheckKeys(kv.second, path, warnings);
      continue;
    }
    std::string warning = "unknown key '" + path + "' ignored";
    for (const auto& [section, hint] : hints_) {
      if (section == prefix) warning += " (" + hint + ")";
    }
    warnings->push_back(warning);
  }
}

void ConfigTable::Apply(const YAML::Node& root, std::vector<std::string>* warnings) const {
  if (root.IsNull()) return;  // an empty file: all defaults
  if (!root.IsMap()) throw ConfigError("top level: expected a map, got " + Show(root));
  CheckKeys(root, "", warnings);
  for (const Entry& e : entries_) {
    const YAML::Node value = Lookup(root, e.key);
    const bool given = value && !value.IsNull();
    for (const auto& [old_key, key] : aliases_) {
      if (key != e.key) continue;
      const YAML::Node old = Lookup(root, old_key);
      if (!old || old.IsNull()) continue;
      if (given) {
        warnings->push_back("key '" + old_key + "' ignored: its current spelling '" + key +
                            "' is also set");
      } else {
        warnings->push_back("key '" + old_key + "' read as '" + key + "' (its current spelling)");
        e.set(old, old_key, warnings);  // an error names the key as the file spells it
      }
    }
    if (given) e.set(value, e.key, warnings);
  }
}

std::vector<std::string> ConfigTable::Keys() const {
  std::vector<std::string> keys;
  for (const Entry& e : entries_) keys.push_back(e.key);
  return keys;
}

std::vector<std::string> ConfigTable::TopSections() const {
  std::vector<std::string> names;
  for (const Entry& e : entries_) {
    const std::string top = e.key.substr(0, e.key.find('.'));
    bool seen = false;
    for (const std::string& n : names) seen = seen || n == top;
    if (!seen) names.push_back(top);
  }
  return names;
}

std::string ConfigTable::ShowValue(const std::string& key) const {
  for (const Entry& e : entries_) {
    if (e.key == key) return e.show ? e.show() : std::string();
  }
  return "";
}

ConfigLoadReport LoadWithTable(const std::string& yaml, const ConfigTable& table) {
  ConfigLoadReport report;
  try {
    table.Apply(YAML::Load(yaml), &report.warnings);
  } catch (const ConfigError& e) {
    report.ok = false;
    report.error = e.what();
  } catch (const YAML::Exception& e) {
    report.ok = false;
    report.error = std::string("YAML syntax error: ") + e.what();
  } catch (const std::exception& e) {  // anything else yaml-cpp lets through: never a crash
    report.ok = false;
    report.error = e.what();
  }
  if (!report.ok) report.warnings.clear();
  return report;
}

bool ReadConfigFile(const std::string& path, std::string* text, ConfigLoadReport* report) {
  std::ifstream in(path);
  if (!in) {
    report->ok = false;
    report->error = "cannot read config file " + path;
    return false;
  }
  std::ostringstream os;
  os << in.rdbuf();
  *text = os.str();
  return true;
}

}  // namespace ppf
