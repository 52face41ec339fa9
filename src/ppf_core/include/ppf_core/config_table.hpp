// The one YAML config loader: a table of dotted keys ("map.resolution"), each bound to one field
// of a config struct. The core's Config (config.hpp) and ppf_node's NodeConfig are both read by
// it, so every config file behaves alike:
//   - every key is optional; a missing key or "key:" without a value keeps the field's value;
//   - an unknown key is a warning naming it (a typo must not pass silently, nor stop a robot);
//   - a wrong type, a value outside an enum, a section that is not a map, or a key that is itself
//     a list or a map is an error naming the key; the load then changes nothing;
//   - a key's former spelling (AddAlias) is still read, with a warning naming the current one, so
//     that files written before a rename keep loading to the same values.
// Keys are applied in the order they were added to the table, not in the order of the file: a key
// that selects defaults for its section (ppf.beams) is added first and the others override it.
//
// This header includes yaml-cpp: include it from loader .cpp files only; config.hpp stays free of
// it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "ppf_core/config.hpp"  // ConfigLoadReport

namespace ppf {

// Thrown by the table and by custom setters; Load() turns it into ConfigLoadReport::error. The
// message names the key ("key 'map.nearby': must be 1, 7, 19 or 27").
struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class ConfigTable {
 public:
  // A custom key: reads its value (never null) into the bound struct; may add warnings.
  using Setter = std::function<void(const YAML::Node& value, const std::string& key,
                                    std::vector<std::string>* warnings)>;
  // Prints the bound value, so that two configs can be compared key by key (ShowValue()); empty
  // for a key that selects values rather than holding one (ppf.beams).
  using Shower = std::function<std::string()>;

  void Add(const std::string& key, double* field);
  void Add(const std::string& key, int* field);
  // Unsigned (size_t, uint64_t): both C++ spellings, whichever the platform's typedefs use.
  void Add(const std::string& key, unsigned long* field);
  void Add(const std::string& key, unsigned long long* field);
  void Add(const std::string& key, bool* field);
  void Add(const std::string& key, std::string* field);
  // An enum written as one of `names`; an unlisted name is an error listing the allowed ones.
  template <typename E>
  void AddEnum(const std::string& key, E* field, std::vector<std::pair<std::string, E>> names);
  void AddCustom(const std::string& key, Setter set, Shower show);
  // Appended to the warning about an unknown key inside `section` (e.g. how keys there are named).
  void AddHint(const std::string& section, const std::string& hint);
  // `old_key` is a former spelling of the table's key `key`: its value is read into the same
  // field, at `key`'s place in the table order, with a warning naming `key`. When a file gives
  // both, `key` wins and the old one is reported as ignored. Keys() does not list aliases.
  void AddAlias(const std::string& old_key, const std::string& key);

  // Applies a parsed document (a map, or null for "all defaults") to the bound fields. Throws
  // ConfigError; appends a warning per unknown key. The caller keeps its struct's previous value
  // on a throw (the loaders bind the table to a copy).
  void Apply(const YAML::Node& root, std::vector<std::string>* warnings) const;

  std::vector<std::string> Keys() const;                // in table order
  std::vector<std::string> TopSections() const;         // first components of the keys, in order
  std::string ShowValue(const std::string& key) const;  // "" for unknown keys and for selectors

  // Helpers for custom setters: the value as a number / list of `size` numbers / scalar text, or
  // a ConfigError naming `key` (`expected` says what was expected).
  static double AsDouble(const YAML::Node& n, const std::string& key);
  static long long AsInt(const YAML::Node& n, const std::string& key);
  static std::vector<double> AsList(const YAML::Node& n, const std::string& key, size_t size);
  static std::string AsScalar(const YAML::Node& n, const std::string& key, const char* expected);
  static std::string Show(const YAML::Node& n);  // "'text'", "a list", "a map" or "null"

 private:
  struct Entry {
    std::string key;
    Setter set;
    Shower show;
  };
  void CheckKeys(const YAML::Node& map, const std::string& prefix,
                 std::vector<std::string>* warnings) const;
  bool IsKey(const std::string& path) const;
  bool IsAlias(const std::string& path) const;
  bool IsSection(const std::string& path) const;

  std::vector<Entry> entries_;
  std::vector<std::pair<std::string, std::string>> hints_;
  std::vector<std::pair<std::string, std::string>> aliases_;  // (old key, current key)
};

// Loads YAML text with `table` (bound to *work, a copy of the caller's config): the report
// carries the first error or the warnings. Never throws.
ConfigLoadReport LoadWithTable(const std::string& yaml, const ConfigTable& table);
// The core's schema (config.cpp), bound to *config: what LoadConfigYaml reads. Tests compare
// config/reference.yaml with the defaults through it.
ConfigTable CoreConfigTable(Config* config);

// Reads a file into *text; false with report->error naming the file if it cannot be read.
bool ReadConfigFile(const std::string& path, std::string* text, ConfigLoadReport* report);

template <typename E>
void ConfigTable::AddEnum(const std::string& key, E* field,
                          std::vector<std::pair<std::string, E>> names) {
  AddCustom(
      key,
      [field, names](const YAML::Node& n, const std::string& k, std::vector<std::string>*) {
        const std::string s = AsScalar(n, k, "a name");
        std::string allowed;
        for (const auto& [name, value] : names) {
          if (name == s) {
            *field = value;
            return;
          }
          allowed += (allowed.empty() ? "" : "|") + (name.empty() ? "\"\"" : name);
        }
        throw ConfigError("key '" + k + "': '" + s + "' is not one of " + allowed);
      },
      [field, names] {
        for (const auto& [name, value] : names) {
          if (value == *field) return name;
        }
        return std::string("?");
      });
}

}  // namespace ppf
