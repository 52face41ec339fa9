// PCL is used here only (binary_compressed PCD decoding), never in a header.
#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>

#include "ppf_sim/importers.hpp"

namespace ppf::sim {

namespace fs = std::filesystem;

CloudBuffer LoadPcd(const std::string& path) {
  pcl::PCLPointCloud2 pc;
  if (pcl::io::loadPCDFile(path, pc) != 0) throw std::runtime_error("cannot read PCD " + path);
  CloudBuffer c;
  c.height = pc.height;
  c.width = pc.width;
  c.point_step = pc.point_step;
  c.row_step = pc.row_step;
  c.is_bigendian = pc.is_bigendian;
  c.is_dense = pc.is_dense != 0;
  for (const auto& f : pc.fields) {
    // pcl::PCLPointField uses the sensor_msgs/PointField datatype numbering.
    c.fields.push_back({f.name, f.offset, f.datatype, f.count});
  }
  c.data = std::move(pc.data);
  if (c.data.size() != static_cast<size_t>(c.row_step) * c.height)
    throw std::runtime_error("PCD " + path + ": data size does not match its header");
  return c;
}

bool StampFromFileName(const std::string& name, int64_t* ns) {
  const std::string stem = fs::path(name).stem().string();
  std::smatch m;
  static const std::regex kNs(R"(^(\d{19})$)");
  static const std::regex kSecFrac(R"(^(\d{9,10})[._](\d{1,9})$)");
  static const std::regex kDate(R"(^(\d{4})-(\d{2})-(\d{2})-(\d{2})-(\d{2})-(\d{2})-(\d{3})$)");
  if (std::regex_match(stem, m, kNs)) {
    *ns = std::stoll(m[1]);
    return true;
  }
  if (std::regex_match(stem, m, kSecFrac)) {
    std::string frac = m[2].str();
    frac.resize(9, '0');
    *ns = std::stoll(m[1]) * 1000000000LL + std::stoll(frac);
    return true;
  }
  if (std::regex_match(stem, m, kDate)) {
    std::tm tm{};
    tm.tm_year = std::stoi(m[1]) - 1900;
    tm.tm_mon = std::stoi(m[2]) - 1;
    tm.tm_mday = std::stoi(m[3]);
    tm.tm_hour = std::stoi(m[4]);
    tm.tm_min = std::stoi(m[5]);
    tm.tm_sec = std::stoi(m[6]);
    *ns = static_cast<int64_t>(timegm(&tm)) * 1000000000LL + std::stoll(m[7]) * 1000000LL;
    return true;
  }
  return false;
}

namespace {

int64_t ParseTime(const std::string& s) {
  // Integer > 1e14 is nanoseconds, anything else seconds.
  if (s.find_first_not_of("0123456789") == std::string::npos && s.size() > 14) return std::stoll(s);
  const auto dot = s.find('.');
  if (dot == std::string::npos) return std::stoll(s) * 1000000000LL;
  std::string frac = s.substr(dot + 1);
  frac.resize(9, '0');
  return std::stoll(s.substr(0, dot)) * 1000000000LL + std::stoll(frac.substr(0, 9));
}

// Earliest absolute per-point time (F64 seconds > 1e9), if the cloud has one.
bool EarliestAbsoluteTime(const CloudBuffer& c, int64_t* ns) {
  for (const char* name : {"timestamp", "time", "t", "time_stamp"}) {
    const PointFieldDesc* f = c.Field(name);
    if (!f || f->datatype != kFloat64) continue;
    double tmin = 1e300;
    for (size_t i = 0; i < c.num_points(); ++i) tmin = std::min(tmin, c.Get<double>(i, *f));
    if (tmin > 1e9 && tmin < 1e11) {
      *ns = static_cast<int64_t>(std::floor(tmin)) * 1000000000LL +
            static_cast<int64_t>(std::llround((tmin - std::floor(tmin)) * 1e9));
      return true;
    }
  }
  return false;
}

std::vector<std::string> ListPcdFiles(const std::string& dir) {
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file() && e.path().extension() == ".pcd") files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw std::runtime_error("no .pcd files in " + dir);
  return files;
}

// One time per line (seconds or integer nanoseconds, first column), one per PCD file.
std::vector<int64_t> ReadStampsFile(const std::string& path, size_t num_files) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read stamps file " + path);
  std::vector<int64_t> listed;
  std::string line;
  while (std::getline(in, line)) {
    line.erase(0, line.find_first_not_of(" \t"));
    if (line.empty() || line[0] == '#') continue;
    listed.push_back(ParseTime(line.substr(0, line.find_first_of(" \t,\r"))));
  }
  if (listed.size() != num_files)
    throw std::runtime_error("stamps file has " + std::to_string(listed.size()) + " times for " +
                             std::to_string(num_files) + " PCD files");
  return listed;
}

struct CsvImu {
  int64_t t;
  double w[3], a[3];
};

// t,wx,wy,wz,ax,ay,az per line (header lines skipped), sorted by time.
std::vector<CsvImu> ReadImuCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read IMU CSV " + path);
  std::vector<CsvImu> imu;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#' || std::isalpha(static_cast<unsigned char>(line[0])))
      continue;  // header
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ss(line);
    std::string t;
    CsvImu s;
    if (!(ss >> t >> s.w[0] >> s.w[1] >> s.w[2] >> s.a[0] >> s.a[1] >> s.a[2]))
      throw std::runtime_error(path + ":" + std::to_string(line_no) +
                               ": expected t,wx,wy,wz,ax,ay,az");
    s.t = ParseTime(t);
    imu.push_back(s);
  }
  std::stable_sort(imu.begin(), imu.end(),
                   [](const CsvImu& a, const CsvImu& b) { return a.t < b.t; });
  return imu;
}

// The header stamp of scan i, from the first source that has one (in this order); `source`
// names it.
int64_t ScanStamp(size_t i, const CloudBuffer& c, const std::string& file,
                  const std::vector<int64_t>& listed, const PcdOptions& opt, std::string* source) {
  int64_t stamp = 0;
  if (!listed.empty()) {
    *source = "stamps file";
    return listed[i];
  }
  if (opt.rate_hz > 0.0) {
    *source = "--rate (scan i at i / rate s)";
    return static_cast<int64_t>(std::llround(static_cast<double>(i) / opt.rate_hz * 1e9));
  }
  if (EarliestAbsoluteTime(c, &stamp)) {
    *source = "per-point absolute time (earliest point)";
    return stamp;
  }
  if (StampFromFileName(file, &stamp)) {
    *source = "file name";
    return stamp;
  }
  throw std::runtime_error("no time for " + file +
                           ": no absolute per-point time, no --stamps or --rate, name not a time");
}

}  // namespace

ImportSummary ImportPcdDirectory(const std::string& dir, const std::string& out_dir,
                                 const BagOutputOptions& bag_opt, const PcdOptions& opt) {
  ImportSummary sum;
  const std::vector<std::string> files = ListPcdFiles(dir);
  const std::vector<int64_t> listed =
      opt.stamps_file.empty() ? std::vector<int64_t>() : ReadStampsFile(opt.stamps_file, files.size());
  const std::vector<CsvImu> imu =
      opt.imu_csv.empty() ? std::vector<CsvImu>() : ReadImuCsv(opt.imu_csv);

  BagOutput bag(out_dir, bag_opt);
  const int64_t period_ns = static_cast<int64_t>(std::llround(opt.scan_period * 1e9));
  size_t next_imu = 0;
  auto flush_imu = [&](int64_t until) {
    sum.imu_samples += WriteImuUntil(bag, imu, &next_imu, until, opt.imu_frame);
  };
  std::string source;
  for (size_t i = 0; i < files.size(); ++i) {
    CloudBuffer c = LoadPcd(files[i]);
    const int64_t stamp = ScanStamp(i, c, files[i], listed, opt, &source);
    c.stamp_ns = stamp;
    c.frame_id = opt.lidar_frame;
    flush_imu(stamp + period_ns);
    bag.WriteCloud(c, stamp + period_ns);
    ++sum.clouds;
    sum.points += c.num_points();
  }
  flush_imu(INT64_MAX);
  bag.Close();
  sum.notes.push_back("header stamp from " + source + "; fields copied unchanged from the PCD");
  return sum;
}

}  // namespace ppf::sim
