#include "ppf_trajectory/map_export.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>

namespace ppf {

size_t MapAccumulator::KeyHash::operator()(const Key& k) const {
  uint64_t h = static_cast<uint64_t>(static_cast<uint32_t>(k.x)) * 0x9E3779B97F4A7C15ULL ^
               static_cast<uint64_t>(static_cast<uint32_t>(k.y)) * 0xC2B2AE3D27D4EB4FULL ^
               static_cast<uint64_t>(static_cast<uint32_t>(k.z)) * 0x165667B19E3779F9ULL;
  h ^= h >> 29;
  return static_cast<size_t>(h);
}

MapAccumulator::MapAccumulator(double voxel_size)
    : voxel_size_(voxel_size > 1e-4 ? voxel_size : 1e-4), inv_(1.0 / voxel_size_) {}

void MapAccumulator::Add(const Eigen::Vector3d& p) {
  constexpr double kLimit = static_cast<double>(std::numeric_limits<int32_t>::max()) - 1.0;
  const double fx = std::floor(p.x() * inv_), fy = std::floor(p.y() * inv_),
               fz = std::floor(p.z() * inv_);
  // Also false for NaN.
  if (!(std::abs(fx) < kLimit && std::abs(fy) < kLimit && std::abs(fz) < kLimit)) {
    ++rejected_;
    return;
  }
  const Key key{static_cast<int32_t>(fx), static_cast<int32_t>(fy), static_cast<int32_t>(fz)};
  const auto [it, inserted] = index_.emplace(key, static_cast<uint32_t>(cells_.size()));
  if (inserted) cells_.emplace_back();
  Cell& c = cells_[it->second];
  c.sx += p.x();
  c.sy += p.y();
  c.sz += p.z();
  ++c.n;
  ++added_;
}

void MapAccumulator::AddScan(const std::vector<Eigen::Vector3f>& points_lidar,
                             const Eigen::Isometry3d& T_world_lidar) {
  for (const Eigen::Vector3f& p : points_lidar) Add(T_world_lidar * p.cast<double>());
  ++scans_;
}

std::vector<MapPoint> MapAccumulator::Points() const {
  std::vector<MapPoint> out;
  out.reserve(cells_.size());
  for (const Cell& c : cells_) {
    const double n = static_cast<double>(c.n);
    out.push_back({static_cast<float>(c.sx / n), static_cast<float>(c.sy / n),
                   static_cast<float>(c.sz / n), static_cast<float>(c.n)});
  }
  return out;
}

std::vector<MapPoint> ToMapPoints(const std::vector<Eigen::Vector3f>& points) {
  std::vector<MapPoint> out;
  out.reserve(points.size());
  for (const Eigen::Vector3f& p : points) out.push_back({p.x(), p.y(), p.z(), 1.f});
  return out;
}

namespace {

bool EndsWith(const std::string& s, const std::string& tail) {
  if (s.size() < tail.size()) return false;
  for (size_t i = 0; i < tail.size(); ++i) {
    const char c = s[s.size() - tail.size() + i];
    if (std::tolower(static_cast<unsigned char>(c)) != tail[i]) return false;
  }
  return true;
}

// Little-endian whatever the host's order (PCD's binary data and the PLY header both say so).
void PutFloatLe(float f, char* out) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof(u));
  for (int b = 0; b < 4; ++b) out[b] = static_cast<char>((u >> (8 * b)) & 0xFFu);
}

}  // namespace

bool MapFormatForFile(const std::string& path, bool ply_ascii, MapFormat* format) {
  if (EndsWith(path, ".pcd")) {
    *format = MapFormat::kPcdBinary;
    return true;
  }
  if (EndsWith(path, ".ply")) {
    *format = ply_ascii ? MapFormat::kPlyAscii : MapFormat::kPlyBinary;
    return true;
  }
  return false;
}

// One header line per source line.
// clang-format off
std::string PcdHeader(size_t points) {
  const std::string n = std::to_string(points);
  return "# .PCD v0.7 - Point Cloud Data file format\n"
         "VERSION 0.7\n"
         "FIELDS x y z intensity\n"
         "SIZE 4 4 4 4\n"
         "TYPE F F F F\n"
         "COUNT 1 1 1 1\n"
         "WIDTH " + n + "\n"
         "HEIGHT 1\n"
         "VIEWPOINT 0 0 0 1 0 0 0\n"
         "POINTS " + n + "\n"
         "DATA binary\n";
}

std::string PlyHeader(size_t points, bool binary) {
  return std::string("ply\n") +
         (binary ? "format binary_little_endian 1.0\n" : "format ascii 1.0\n") +
         "comment LIO-PPF map, world frame; intensity = registered points in the voxel\n"
         "element vertex " + std::to_string(points) + "\n"
         "property float x\n"
         "property float y\n"
         "property float z\n"
         "property float intensity\n"
         "end_header\n";
}
// clang-format on

bool WriteMapFile(const std::string& path, const std::vector<MapPoint>& points, MapFormat format,
                  std::string* error) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream os(tmp, std::ios::binary | std::ios::trunc);
    if (!os) {
      *error = "cannot write " + tmp + ": " + std::strerror(errno);
      return false;
    }
    if (format == MapFormat::kPlyAscii) {
      os << PlyHeader(points.size(), false);
      char line[128];
      for (const MapPoint& p : points) {
        // 9 significant digits give every float back exactly.
        const int len =
            std::snprintf(line, sizeof(line), "%.9g %.9g %.9g %.9g\n", p.x, p.y, p.z, p.intensity);
        os.write(line, len);
      }
    } else {
      os << (format == MapFormat::kPcdBinary ? PcdHeader(points.size())
                                             : PlyHeader(points.size(), true));
      std::vector<char> buf;
      constexpr size_t kChunk = 1 << 16;  // points per write
      for (size_t begin = 0; begin < points.size(); begin += kChunk) {
        const size_t end = std::min(points.size(), begin + kChunk);
        buf.resize((end - begin) * 16);
        char* out = buf.data();
        for (size_t i = begin; i < end; ++i, out += 16) {
          PutFloatLe(points[i].x, out);
          PutFloatLe(points[i].y, out + 4);
          PutFloatLe(points[i].z, out + 8);
          PutFloatLe(points[i].intensity, out + 12);
        }
        os.write(buf.data(), static_cast<std::streamsize>(buf.size()));
      }
    }
    os.flush();
    if (!os) {
      *error = "cannot write " + tmp + " (disk full?)";
      std::remove(tmp.c_str());
      return false;
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    *error = "cannot rename " + tmp + " to " + path + ": " + std::strerror(errno);
    std::remove(tmp.c_str());
    return false;
  }
  return true;
}

}  // namespace ppf
