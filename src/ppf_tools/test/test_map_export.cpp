// Map export: ppf_offline --map-out / --local-map-out on a simulated indoor drive, the files
// loaded back with PCL's readers, their points measured against the simulator's own surfaces
// (the scene rebuilt from the sequence's options); and the accumulator and writers on their own.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "ppf_sim/scene_distance.hpp"
#include "ppf_sim/world.hpp"
#include "ppf_tools/map_export.hpp"
#include "ppf_trajectory/trajectory_io.hpp"
#include "sim_sequence.hpp"

namespace fs = std::filesystem;

namespace {

using ppf::tools::MapPoint;

double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::infinity();
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The pose of `traj` nearest in time to t.
const ppf::StampedPose& Nearest(const ppf::Trajectory& traj, double t) {
  return *std::min_element(traj.begin(), traj.end(), [t](const auto& a, const auto& b) {
    return std::abs(a.stamp_s - t) < std::abs(b.stamp_s - t);
  });
}

// Estimated world -> simulator world: the first estimated pose put onto the ground truth at its
// stamp (the car is still at rest then, so the stamps' rounding does not matter).
Eigen::Isometry3d SimFromEstimate(const ppf::Trajectory& est, const ppf::Trajectory& gt) {
  return Nearest(gt, est.front().stamp_s).T * est.front().T.inverse();
}

// Median distance of the cloud's points (estimated world) to the scene's surfaces.
double MedianDistance(const pcl::PointCloud<pcl::PointXYZI>& cloud, const ppf::sim::Scene& scene,
                      const Eigen::Isometry3d& T_sim_est) {
  std::vector<double> dist;
  dist.reserve(cloud.size());
  for (const auto& p : cloud) {
    dist.push_back(ppf::sim::DistanceToScene(scene, T_sim_est * Eigen::Vector3d(p.x, p.y, p.z)));
  }
  return Median(dist);
}

// One ppf_offline run on a 12 s indoor drive (the sequence test_accuracy's indoor cases use),
// both map files, one test so the run happens once.
TEST(MapExportSim, FilesLoadWithPclAndLieOnTheSimulatedSurfaces) {
  const double duration = 12.0;
  const std::string bag = ppf::tools::test::GenerateSimSequence(
      "--scene indoor --lidar vlp16 --motion car --speed 1.5", duration);
  const std::string out =
      (fs::path(PPF_TEST_WORKDIR) / ("map_export." + std::to_string(::getpid()))).string();
  fs::create_directories(out);
  std::ostringstream cmd;
  cmd << "'" << PPF_OFFLINE_EXE << "' --bag '" << bag << "' --config '" << PPF_CONFIG_DIR
      << "/vlp16.yaml' --config '" << bag << "/calibration.yaml' --mode knn --out '" << out
      << "/traj.tum' --map-out '" << out << "/map.pcd' --map-voxel 0.1 --local-map-out '" << out
      << "/local.ply' > '" << out << "/ppf_offline.log' 2>&1";
  const int exit_code = std::system(cmd.str().c_str());
  const std::string log = ReadBytes(out + "/ppf_offline.log");
  ASSERT_EQ(exit_code, 0) << log;

  // The PCD: PCL loads it, the header is exactly the documented one, then 16 bytes a point.
  pcl::PointCloud<pcl::PointXYZI> map;
  ASSERT_EQ(pcl::io::loadPCDFile(out + "/map.pcd", map), 0);
  const size_t n = map.size();
  ASSERT_GT(n, 1000u);
  // One header line per source line.
  // clang-format off
  const std::string expected_header =
      "# .PCD v0.7 - Point Cloud Data file format\n"
      "VERSION 0.7\n"
      "FIELDS x y z intensity\n"
      "SIZE 4 4 4 4\n"
      "TYPE F F F F\n"
      "COUNT 1 1 1 1\n"
      "WIDTH " + std::to_string(n) + "\n"
      "HEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\n"
      "POINTS " + std::to_string(n) + "\n"
      "DATA binary\n";
  // clang-format on
  const std::string bytes = ReadBytes(out + "/map.pcd");
  EXPECT_EQ(bytes.substr(0, expected_header.size()), expected_header);
  EXPECT_EQ(bytes.size(), expected_header.size() + 16 * n);
  EXPECT_FALSE(fs::exists(out + "/map.pcd.tmp"));
  EXPECT_NE(log.find("  map: " + std::to_string(n) + " points (0.1 m voxels, "), std::string::npos)
      << log;

  // The scene rebuilt from the sequence's options is the sequence's: its trajectory gives the
  // ground-truth file's poses.
  ppf::sim::WorldOptions wo;
  wo.scene = "indoor";
  wo.motion = ppf::sim::MotionKind::kCar;
  wo.motion_is_default = false;
  wo.speed = 1.5;
  wo.duration = duration;
  wo.seed = 1;
  const ppf::sim::World world = ppf::sim::BuildWorld(wo);
  ppf::Trajectory gt, est;
  std::string error;
  ASSERT_TRUE(ppf::ReadTum(bag + "/groundtruth.tum", &gt, &error)) << error;
  ASSERT_TRUE(ppf::ReadTum(out + "/traj.tum", &est, &error)) << error;
  ASSERT_FALSE(gt.empty());
  ASSERT_FALSE(est.empty());
  const double start_s = 1700000000.0;  // ppf_sim's sim time 0
  for (size_t i : {size_t{0}, gt.size() / 2, gt.size() - 1}) {
    const Eigen::Isometry3d T = world.trajectory.Pose(gt[i].stamp_s - start_s);
    EXPECT_LT((T.translation() - gt[i].T.translation()).norm(), 1e-3) << "ground truth row " << i;
  }
  const Eigen::Isometry3d T_sim_est = SimFromEstimate(est, gt);

  const double median = MedianDistance(map, world.scene, T_sim_est);
  float max_count = 0.f;
  for (const auto& p : map) max_count = std::max(max_count, p.intensity);
  std::printf("map: %zu points, median distance to the scene %.4f m, most points in a voxel %.0f\n",
              n, median, max_count);
  EXPECT_LT(median, 0.05);
  // The measure tells a map off by 15 cm from one on the surfaces.
  const Eigen::Isometry3d shifted = Eigen::Translation3d(0.15, 0.15, 0.15) * T_sim_est;
  EXPECT_GT(MedianDistance(map, world.scene, shifted), 0.1);
  EXPECT_GE(max_count, 2.f);  // a voxel seen by several scans is one point, not several

  // The local map's binary PLY: PCL loads it, its points lie on the surfaces too.
  pcl::PointCloud<pcl::PointXYZI> local;
  ASSERT_EQ(pcl::io::loadPLYFile(out + "/local.ply", local), 0);
  ASSERT_GT(local.size(), 1000u);
  EXPECT_NE(log.find("  local map: " + std::to_string(local.size()) + " points -> "),
            std::string::npos)
      << log;
  EXPECT_EQ(ReadBytes(out + "/local.ply").rfind(ppf::tools::PlyHeader(local.size(), true), 0), 0u);
  for (const auto& p : local) ASSERT_EQ(p.intensity, 1.0f);
  const double local_median = MedianDistance(local, world.scene, T_sim_est);
  std::printf("local map: %zu points, median distance to the scene %.4f m\n", local.size(),
              local_median);
  EXPECT_LT(local_median, 0.05);

  // The ASCII PLY of the map's points loads to the same floats.
  std::vector<MapPoint> points;
  for (const auto& p : map) points.push_back({p.x, p.y, p.z, p.intensity});
  ASSERT_TRUE(ppf::tools::WriteMapFile(out + "/map_ascii.ply", points,
                                       ppf::tools::MapFormat::kPlyAscii, &error))
      << error;
  pcl::PointCloud<pcl::PointXYZI> ascii;
  ASSERT_EQ(pcl::io::loadPLYFile(out + "/map_ascii.ply", ascii), 0);
  ASSERT_EQ(ascii.size(), n);
  for (size_t i = 0; i < n; ++i) {
    ASSERT_EQ(ascii[i].x, map[i].x) << i;
    ASSERT_EQ(ascii[i].y, map[i].y) << i;
    ASSERT_EQ(ascii[i].z, map[i].z) << i;
    ASSERT_EQ(ascii[i].intensity, map[i].intensity) << i;
  }
  if (!::testing::Test::HasFailure()) {
    std::error_code ec;
    fs::remove_all(out, ec);
  }
}

TEST(MapAccumulator, OneMeanPointPerVoxelAndTrustedScansOnly) {
  ppf::tools::MapAccumulator acc(0.5);
  acc.Add({0.1, 0.1, 0.1});
  acc.Add({0.3, 0.2, 0.4});
  acc.Add({1.2, 0.1, 0.1});
  acc.Add({std::nan(""), 0.0, 0.0});
  acc.Add({1e12, 0.0, 0.0});
  const auto pts = acc.Points();
  ASSERT_EQ(pts.size(), 2u);
  EXPECT_FLOAT_EQ(pts[0].x, 0.2f);
  EXPECT_FLOAT_EQ(pts[0].y, 0.15f);
  EXPECT_FLOAT_EQ(pts[0].z, 0.25f);
  EXPECT_EQ(pts[0].intensity, 2.0f);
  EXPECT_FLOAT_EQ(pts[1].x, 1.2f);
  EXPECT_EQ(pts[1].intensity, 1.0f);
  EXPECT_EQ(acc.points_added(), 3u);
  EXPECT_EQ(acc.rejected(), 2u);

  // Memory follows the voxels: many scans over the same 1 m cube stay 8 voxels of 0.5 m.
  ppf::ScanResult r;
  r.status = ppf::Status::kOk;
  r.pose_valid = true;
  r.T_world_lidar.translation() = Eigen::Vector3d(10.0, 0.0, 0.0);
  for (int i = 0; i < 1000; ++i) {
    r.deskewed_points_lidar.push_back(Eigen::Vector3f(0.001f * i, 0.0007f * i, 0.0009f * i));
  }
  ppf::tools::MapAccumulator cube(0.5);
  for (int scan = 0; scan < 50; ++scan) EXPECT_TRUE(cube.AddResult(r));
  EXPECT_EQ(cube.points_added(), 50000u);
  EXPECT_LE(cube.voxels(), 8u);
  for (const auto& p : cube.Points()) EXPECT_GE(p.x, 10.0f);  // placed with T_world_lidar

  // Only a trusted pose adds: kOk or kDegenerate with pose_valid.
  ppf::tools::MapAccumulator none(0.5);
  r.status = ppf::Status::kDegenerate;
  EXPECT_TRUE(none.AddResult(r));
  r.pose_valid = false;
  EXPECT_FALSE(none.AddResult(r));
  for (ppf::Status s : {ppf::Status::kInitializing, ppf::Status::kReset, ppf::Status::kRejected}) {
    r.status = s;
    r.pose_valid = true;
    EXPECT_FALSE(none.AddResult(r));
  }
  EXPECT_EQ(none.scans_added(), 1u);
}

TEST(MapExportFiles, FormatsFromTheFileNameAndExactPlyBytes) {
  ppf::tools::MapFormat f;
  ASSERT_TRUE(ppf::tools::MapFormatForFile("a/map.PCD", false, &f));
  EXPECT_EQ(f, ppf::tools::MapFormat::kPcdBinary);
  ASSERT_TRUE(ppf::tools::MapFormatForFile("map.ply", false, &f));
  EXPECT_EQ(f, ppf::tools::MapFormat::kPlyBinary);
  ASSERT_TRUE(ppf::tools::MapFormatForFile("map.ply", true, &f));
  EXPECT_EQ(f, ppf::tools::MapFormat::kPlyAscii);
  EXPECT_FALSE(ppf::tools::MapFormatForFile("map.xyz", false, &f));
  EXPECT_FALSE(ppf::tools::MapFormatForFile("pcd", false, &f));

  const std::string dir = (fs::path(PPF_TEST_WORKDIR) / "map_export_files").string();
  fs::create_directories(dir);
  const std::vector<MapPoint> pts = {{1.0f, -2.5f, 0.125f, 3.0f}};
  std::string error;
  ASSERT_TRUE(
      ppf::tools::WriteMapFile(dir + "/one.ply", pts, ppf::tools::MapFormat::kPlyBinary, &error))
      << error;
  const std::string header =
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment LIO-PPF map, world frame; intensity = registered points in the voxel\n"
      "element vertex 1\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property float intensity\n"
      "end_header\n";
  // 1.0, -2.5, 0.125, 3.0 as IEEE-754 little-endian.
  const std::string body("\x00\x00\x80\x3f\x00\x00\x20\xc0\x00\x00\x00\x3e\x00\x00\x40\x40", 16);
  EXPECT_EQ(ReadBytes(dir + "/one.ply"), header + body);
  ASSERT_TRUE(ppf::tools::WriteMapFile(dir + "/one_ascii.ply", pts,
                                       ppf::tools::MapFormat::kPlyAscii, &error));
  EXPECT_EQ(ReadBytes(dir + "/one_ascii.ply"),
            ppf::tools::PlyHeader(1, false) + "1 -2.5 0.125 3\n");

  // An unwritable place is one clear error, not a crash or a partial file.
  EXPECT_FALSE(ppf::tools::WriteMapFile(dir + "/no/such/dir/map.pcd", pts,
                                        ppf::tools::MapFormat::kPcdBinary, &error));
  EXPECT_NE(error.find("cannot write " + dir + "/no/such/dir/map.pcd.tmp"), std::string::npos)
      << error;
}

}  // namespace
