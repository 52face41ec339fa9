// Writes the seed corpora under fuzz/corpus/ from the project's own writers, so every seed is
// an input the project itself produces (the fuzzers then mutate away from valid data):
//   ppf_fuzz_make_seeds <fuzz/corpus>
// Seeds are kept to a few KB each: libFuzzer's mutations are cheaper on small inputs and the
// repository stays small.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <array>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "ppf_bag/bag.hpp"
#include "ppf_bridge/convert.hpp"
#include "ppf_msgs_cdr/cdr.hpp"
#include "ppf_msgs_cdr/time.hpp"

namespace fs = std::filesystem;

namespace {

void WriteFile(const fs::path& path, const std::vector<uint8_t>& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

std::vector<uint8_t> ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

sensor_msgs::msg::PointField Field(const std::string& name, uint32_t offset, uint8_t type) {
  sensor_msgs::msg::PointField f;
  f.name(name);
  f.offset(offset);
  f.datatype(type);
  f.count(1);
  return f;
}

// x, y, z, intensity as float32 followed by a time field of the given name and type: the
// Ouster (t, uint32 ns), Velodyne (time, float32 s) and Hesai (timestamp, float64 s) layouts.
sensor_msgs::msg::PointCloud2 Cloud(uint32_t width, uint32_t height, const std::string& time_name,
                                    uint8_t time_type, uint32_t row_padding = 0) {
  sensor_msgs::msg::PointCloud2 c;
  c.header().stamp(ppf::msgs::TimeFromNanoseconds(1700000000123456789LL));
  c.header().frame_id("lidar");
  c.height(height);
  c.width(width);
  c.fields().push_back(Field("x", 0, 7));
  c.fields().push_back(Field("y", 4, 7));
  c.fields().push_back(Field("z", 8, 7));
  c.fields().push_back(Field("intensity", 12, 7));
  uint32_t step = 16;
  if (!time_name.empty()) {
    c.fields().push_back(Field(time_name, 16, time_type));
    step += time_type == 8 ? 8 : 4;
  }
  c.point_step(step);
  c.row_step(width * step + row_padding);
  c.data().assign(static_cast<size_t>(c.row_step()) * height, 0);
  for (uint32_t r = 0; r < height; ++r) {
    for (uint32_t i = 0; i < width; ++i) {
      uint8_t* p = c.data().data() + r * c.row_step() + i * step;
      const float xyzi[4] = {std::cos(0.5f * i) * 10.f, std::sin(0.5f * i) * 10.f, 0.1f * r, 7.f};
      std::memcpy(p, xyzi, sizeof(xyzi));
      if (time_type == 6) {
        const uint32_t ns = 1000000u * i;
        std::memcpy(p + 16, &ns, 4);
      } else if (time_type == 7) {
        const float s = 0.001f * i;
        std::memcpy(p + 16, &s, 4);
      } else if (time_type == 8) {
        const double s = 1700000000.123 + 0.001 * i;
        std::memcpy(p + 16, &s, 8);
      }
    }
  }
  c.is_dense(true);
  return c;
}

// The layout fuzz_time_field reads: options, then the cloud header, fields and point bytes.
std::vector<uint8_t> TimeFieldSeed(uint8_t opt, double stamp, uint16_t width, uint8_t step,
                                   const std::vector<std::array<uint8_t, 3>>& fields,
                                   const std::vector<uint8_t>& points) {
  std::vector<uint8_t> b;
  auto put = [&b](const void* p, size_t n) {
    const auto* u = static_cast<const uint8_t*>(p);
    b.insert(b.end(), u, u + n);
  };
  const double period = 0.1;
  put(&opt, 1);
  put(&period, 8);
  put(&stamp, 8);
  const uint8_t height = 1;
  put(&height, 1);
  put(&width, 2);
  put(&step, 1);
  const uint16_t row_step = 0;
  put(&row_step, 2);
  const uint8_t little = 1;
  put(&little, 1);
  const uint8_t n = static_cast<uint8_t>(fields.size());
  put(&n, 1);
  for (const auto& f : fields) put(f.data(), 3);
  put(points.data(), points.size());
  return b;
}

std::vector<uint8_t> SmallBag(const fs::path& work, ppf::bag::Storage storage,
                              const std::string& compression, size_t chunk_size) {
  fs::remove_all(work);
  ppf::bag::WriterOptions options;
  options.storage = storage;
  options.compression = compression;
  options.chunk_size = chunk_size;
  std::string file;
  {
    ppf::bag::Writer w(work.string(), options);
    w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", ""});
    w.AddTopic({"/points", "sensor_msgs/msg/PointCloud2", "cdr", ""});
    for (int i = 0; i < 4; ++i) {
      ppf::ImuSample s;
      s.stamp_s = 100.0 + 0.01 * i;
      s.angular_velocity = Eigen::Vector3d(0.01 * i, 0, 0);
      s.linear_acceleration = Eigen::Vector3d(0, 0, 9.81);
      // Out of timestamp order on purpose: readers must sort.
      w.Write("/imu", 100000000000LL + 10000000LL * ((i * 3) % 4),
              ppf::msgs::EncodeCdr(ppf::bridge::ToImuMsg(s, "imu")));
    }
    w.Write("/points", 100005000000LL, ppf::msgs::EncodeCdr(Cloud(2, 1, "t", 6)));
    w.Close();
    file = w.storage_file();
  }
  return ReadFile(file);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <fuzz/corpus directory>\n", argv[0]);
    return 2;
  }
  const fs::path out(argv[1]);
  using ppf::msgs::EncodeCdr;

  const fs::path pc = out / "fuzz_cdr_pointcloud2";
  WriteFile(pc / "ouster_t_uint32", EncodeCdr(Cloud(4, 1, "t", 6)));
  WriteFile(pc / "velodyne_time_float32", EncodeCdr(Cloud(4, 1, "time", 7)));
  WriteFile(pc / "hesai_timestamp_float64", EncodeCdr(Cloud(3, 1, "timestamp", 8)));
  WriteFile(pc / "organized_padded_rows", EncodeCdr(Cloud(2, 2, "t", 6, 4)));
  WriteFile(pc / "no_time_field", EncodeCdr(Cloud(4, 1, "", 0)));
  WriteFile(pc / "empty", EncodeCdr(Cloud(0, 1, "t", 6)));
  // Hostile stamps and point times: a header nanosec of 4e9 (out of range), one point 1e6 s
  // after the stamp (relative float32), every point 100 s before it (absolute float64).
  {
    auto c = Cloud(4, 1, "t", 6);
    builtin_interfaces::msg::Time t = c.header().stamp();
    t.nanosec(4000000000u);
    c.header().stamp(t);
    WriteFile(pc / "header_nanosec_4e9", EncodeCdr(c));
    c = Cloud(4, 1, "time", 7);
    const float far = 1e6f;
    std::memcpy(c.data().data() + 2 * c.point_step() + 16, &far, 4);
    WriteFile(pc / "point_time_plus_1e6", EncodeCdr(c));
    c = Cloud(3, 1, "timestamp", 8);
    for (uint32_t i = 0; i < c.width(); ++i) {
      const double s = 1700000000.123456789 - 100.0 + 0.001 * i;
      std::memcpy(c.data().data() + i * c.point_step() + 16, &s, 8);
    }
    WriteFile(pc / "point_time_minus_100", EncodeCdr(c));
    // Layouts taken as they are but named by the node: row_step 0, many extra fields.
    c = Cloud(4, 1, "t", 6);
    c.row_step(0);
    WriteFile(pc / "row_step_zero", EncodeCdr(c));
    c = Cloud(2, 1, "t", 6);
    for (int i = 0; i < 100; ++i) c.fields().push_back(Field("e" + std::to_string(i), i % 20, 2));
    WriteFile(pc / "many_fields", EncodeCdr(c));
    c = Cloud(4, 1, "t", 6);
    c.fields().clear();
    WriteFile(pc / "no_fields", EncodeCdr(c));
  }

  const fs::path imu = out / "fuzz_cdr_imu";
  ppf::ImuSample s;
  s.stamp_s = 1700000000.5;
  s.angular_velocity = Eigen::Vector3d(0.01, -0.02, 0.3);
  s.linear_acceleration = Eigen::Vector3d(0.1, 0.2, 9.81);
  WriteFile(imu / "at_rest", EncodeCdr(ppf::bridge::ToImuMsg(s, "imu_link")));
  {
    auto m = ppf::bridge::ToImuMsg(s, "imu_link");
    builtin_interfaces::msg::Time t = m.header().stamp();
    t.nanosec(4000000000u);
    m.header().stamp(t);
    WriteFile(imu / "header_nanosec_4e9", EncodeCdr(m));
  }
  s.linear_acceleration.z() = std::nan("");
  WriteFile(imu / "nan_acceleration", EncodeCdr(ppf::bridge::ToImuMsg(s, "imu_link")));

  const fs::path tf = out / "fuzz_time_field";
  std::vector<uint8_t> pts;
  const Eigen::Vector3f xyz[3] = {{1, 2, 3}, {-4, 5, 0.5f}, {7, -8, 1}};
  for (int i = 0; i < 3; ++i) {
    const uint8_t* p = reinterpret_cast<const uint8_t*>(xyz[i].data());
    pts.insert(pts.end(), p, p + 12);
    const uint32_t ns = 30000000u * static_cast<uint32_t>(i);
    const uint8_t* t = reinterpret_cast<const uint8_t*>(&ns);
    pts.insert(pts.end(), t, t + 4);
  }
  // Field entries: name index (x y z intensity t time ...), offset, datatype.
  WriteFile(tf / "relative_uint32_t",
            TimeFieldSeed(0, 1700000000.0, 3, 16, {{{0, 0, 7}}, {{1, 4, 7}}, {{2, 8, 7}}, {{4, 12, 6}}},
                          pts));
  WriteFile(tf / "no_time_azimuth",
            TimeFieldSeed(0, 5.0, 3, 16, {{{0, 0, 7}}, {{1, 4, 7}}, {{2, 8, 7}}}, pts));
  WriteFile(tf / "float32_time_at_end",
            TimeFieldSeed(3 * 2, 5.0, 3, 16,
                          {{{0, 0, 7}}, {{1, 4, 7}}, {{2, 8, 7}}, {{5, 12, 7}}, {{3, 12, 7}}}, pts));

  // Point times off the sweep: one float32 relative time 1e6 s late; float64 absolute times 100 s
  // before the stamp.
  {
    std::vector<uint8_t> late, early;
    for (int i = 0; i < 3; ++i) {
      const uint8_t* p = reinterpret_cast<const uint8_t*>(xyz[i].data());
      late.insert(late.end(), p, p + 12);
      const float t = i == 1 ? 1e6f : 0.03f * static_cast<float>(i);
      const uint8_t* tb = reinterpret_cast<const uint8_t*>(&t);
      late.insert(late.end(), tb, tb + 4);
      early.insert(early.end(), p, p + 12);
      const double a = 1700000000.0 - 100.0 + 0.03 * i;
      const uint8_t* ab = reinterpret_cast<const uint8_t*>(&a);
      early.insert(early.end(), ab, ab + 8);
    }
    WriteFile(tf / "relative_float32_plus_1e6",
              TimeFieldSeed(0, 1700000000.0, 3, 16,
                            {{{0, 0, 7}}, {{1, 4, 7}}, {{2, 8, 7}}, {{5, 12, 7}}}, late));
    WriteFile(tf / "absolute_float64_minus_100",
              TimeFieldSeed(0, 1700000000.0, 3, 20,
                            {{{0, 0, 7}}, {{1, 4, 7}}, {{2, 8, 7}}, {{6, 12, 8}}}, early));
  }

  const fs::path work = fs::temp_directory_path() / "ppf_fuzz_make_seeds";
  WriteFile(out / "fuzz_bag_mcap" / "uncompressed", SmallBag(work, ppf::bag::Storage::kMcap, "none", 4 << 20));
  WriteFile(out / "fuzz_bag_mcap" / "lz4_small_chunks", SmallBag(work, ppf::bag::Storage::kMcap, "lz4", 200));
  WriteFile(out / "fuzz_bag_mcap" / "zstd", SmallBag(work, ppf::bag::Storage::kMcap, "zstd", 4 << 20));
  WriteFile(out / "fuzz_bag_sqlite" / "humble", SmallBag(work, ppf::bag::Storage::kSqlite3, "none", 0));
  fs::remove_all(work);
  std::printf("seeds written under %s\n", out.c_str());
  return 0;
}
