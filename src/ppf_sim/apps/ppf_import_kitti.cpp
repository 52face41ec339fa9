// ppf_import_kitti: KITTI raw drive folder -> rosbag2 (PointCloud2 on /points, Imu on /imu).
#include "import_cli.hpp"

static const char* kHelp = R"(usage: ppf_import_kitti --raw DIR --out BAG [options]

DIR is a KITTI raw drive folder (e.g. 2011_09_26_drive_0001_extract or _sync):
  velodyne_points/data/*.bin   float32 x y z reflectance
  velodyne_points/timestamps.txt (+ timestamps_start.txt, timestamps_end.txt)
  oxts/data/*.txt (30 values) + oxts/timestamps.txt   (100 Hz in *_extract, 10 Hz in *_sync)
Writes BAG as a rosbag2 directory with velodyne-layout PointCloud2 (x y z intensity f32,
ring u16, time f32) and sensor_msgs/Imu. BAG/groundtruth.tum gets the OXTS poses (T_world_imu,
east-north-up axes, origin at the first fix, Mercator scale as in the KITTI devkit). If
calib_imu_to_velo.txt is found in DIR or its parent, BAG/calibration.yaml gets T_imu_lidar.

Time: header.stamp = scan START (timestamps_start.txt; without it timestamps.txt - period/2).
KITTI scans have no per-point time: `time` (s after the stamp) is computed from each point's
azimuth for a 10 Hz clockwise sweep that starts and ends behind the sensor. `ring` is the
nearest HDL-64E beam to the point's elevation (an estimate). Timestamps are read as UTC.

Options
  --raw DIR            KITTI raw drive folder                        [required]
  --out BAG            output bag directory (must not exist or be empty) [required]
  --storage S          mcap | sqlite3                                [mcap]
  --compression C      none | lz4 | zstd (mcap)                      [none]
  --imu-axes A         body (ax ay az, wx wy wz) | leveled (af al au, wf wl wu)  [body]
  --period S           sweep period                                  [0.1]
  --lidar-frame F      [velodyne]     --imu-frame F   [imu]
  --points-topic T     [/points]      --imu-topic T   [/imu]
)";

namespace {

using namespace ppf::sim;

ImportSummary Import(const CliArgs& args, const std::string& raw, const std::string& out,
                     const BagOutputOptions& bag) {
  KittiOptions opt;
  const std::string axes = args.Str("imu-axes", "body");
  if (axes != "body" && axes != "leveled")
    throw std::invalid_argument("--imu-axes: body | leveled");
  opt.imu_body_axes = axes == "body";
  opt.scan_period = args.Num("period", 0.1);
  opt.lidar_frame = args.Str("lidar-frame", "velodyne");
  opt.imu_frame = args.Str("imu-frame", "imu");
  return ImportKittiRaw(raw, out, bag, opt);
}

}  // namespace

int main(int argc, char** argv) {
  return RunImporter(argc, argv, "ppf_import_kitti", kHelp, "raw",
                     {"imu-axes", "period", "lidar-frame", "imu-frame"}, Import);
}
