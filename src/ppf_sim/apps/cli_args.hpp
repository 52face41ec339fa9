// Minimal "--key value" / "--flag" command-line parsing shared by the three tools.
#pragma once

#include <cstdlib>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace ppf::sim {

class CliArgs {
 public:
  // `flags` take no value; every other known key takes exactly one.
  CliArgs(int argc, char** argv, const std::set<std::string>& keys,
          const std::set<std::string>& flags) {
    for (int i = 1; i < argc; ++i) {
      std::string a = argv[i];
      if (a == "-h") a = "--help";
      if (a.rfind("--", 0) != 0) throw std::invalid_argument("unexpected argument '" + a + "'");
      std::string key = a.substr(2), value;
      const auto eq = key.find('=');
      if (eq != std::string::npos) {
        value = key.substr(eq + 1);
        key = key.substr(0, eq);
      }
      if (flags.count(key)) {
        values_[key] = "1";
        continue;
      }
      if (!keys.count(key)) throw std::invalid_argument("unknown option '--" + key + "' (see --help)");
      if (eq == std::string::npos) {
        if (i + 1 >= argc) throw std::invalid_argument("option '--" + key + "' needs a value");
        value = argv[++i];
      }
      values_[key] = value;
    }
  }
  bool Has(const std::string& k) const { return values_.count(k) > 0; }
  std::string Str(const std::string& k, const std::string& def) const {
    auto it = values_.find(k);
    return it == values_.end() ? def : it->second;
  }
  double Num(const std::string& k, double def) const {
    auto it = values_.find(k);
    if (it == values_.end()) return def;
    char* end = nullptr;
    const double v = std::strtod(it->second.c_str(), &end);
    if (end == it->second.c_str() || *end != '\0')
      throw std::invalid_argument("option '--" + k + "': not a number: '" + it->second + "'");
    return v;
  }
  std::vector<double> List(const std::string& k, size_t n, std::vector<double> def) const {
    auto it = values_.find(k);
    if (it == values_.end()) return def;
    std::vector<double> out;
    std::string s = it->second;
    for (char& c : s)
      if (c == ',') c = ' ';
    const char* p = s.c_str();
    char* end = nullptr;
    while (true) {
      const double v = std::strtod(p, &end);
      if (end == p) break;
      out.push_back(v);
      p = end;
    }
    if (out.size() != n)
      throw std::invalid_argument("option '--" + k + "': expected " + std::to_string(n) + " numbers");
    return out;
  }

 private:
  std::map<std::string, std::string> values_;
};

}  // namespace ppf::sim
