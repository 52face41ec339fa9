// ppf_import_pcd: a directory of PCD scans (+ optional IMU CSV) -> rosbag2.
#include "import_cli.hpp"

static const char* kHelp = R"(usage: ppf_import_pcd --dir DIR --out BAG [options]

Every DIR/*.pcd (ascii, binary or binary_compressed), in file-name order, becomes one
sensor_msgs/PointCloud2 on /points with the PCD's fields and layout unchanged (e.g. a
per-point `timestamp` F64 or `t` U32 and `ring` stay as they are, for the core to detect).

Time: header.stamp = scan START, taken from (first that applies)
  --stamps FILE   one time per scan in file-name order (seconds, or integer ns): the first
                  column of each line, '#' lines skipped, so a TUM trajectory file with one
                  row per scan (e.g. reference_poses.tum) gives its times
  --rate HZ       no times anywhere: scan i at i / HZ seconds
  a per-point absolute time field (F64 timestamp/time/t > 1e9 s): the earliest point
  the file name: 1673403880898440686.pcd (ns), 1673403880.898440686.pcd (s),
                 2021-10-26-16-21-29-468.pcd (UTC date-time-ms)
The bag (receive) time of a cloud is stamp + --period (scan end).

Options
  --dir DIR          directory of .pcd files                       [required]
  --out BAG          output bag directory (must not exist or be empty) [required]
  --imu CSV          IMU samples "t,wx,wy,wz,ax,ay,az" (t in s or integer ns; rad/s, m/s^2;
                     a header line is skipped) -> sensor_msgs/Imu on /imu
  --stamps FILE      scan times, see above (a TUM file's first column works)
  --rate HZ          scan times i / HZ s when there are none (no IMU can be aligned to them)
  --period S         sweep period                                  [0.1]
  --storage S        mcap | sqlite3                                [mcap]
  --compression C    none | lz4 | zstd (mcap)                      [none]
  --lidar-frame F    [lidar]        --imu-frame F   [imu]
  --points-topic T   [/points]      --imu-topic T   [/imu]
)";

namespace {

using namespace ppf::sim;

ImportSummary Import(const CliArgs& args, const std::string& dir, const std::string& out,
                     const BagOutputOptions& bag) {
  PcdOptions opt;
  opt.imu_csv = args.Str("imu", "");
  opt.stamps_file = args.Str("stamps", "");
  opt.rate_hz = args.Num("rate", 0.0);
  opt.scan_period = args.Num("period", 0.1);
  opt.lidar_frame = args.Str("lidar-frame", "lidar");
  opt.imu_frame = args.Str("imu-frame", "imu");
  return ImportPcdDirectory(dir, out, bag, opt);
}

}  // namespace

int main(int argc, char** argv) {
  return RunImporter(argc, argv, "ppf_import_pcd", kHelp, "dir",
                     {"imu", "stamps", "rate", "period", "lidar-frame", "imu-frame"}, Import);
}
