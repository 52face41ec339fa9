// The TUM text form every tool writes, byte for byte: users and tests parse these files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "ppf_trajectory/trajectory_io.hpp"

namespace ppf {
namespace {

Eigen::Isometry3d Pose(double x, double y, double z, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

TEST(TumLine, NanosecondStampIsExactAndEveryNumberHasNineDecimals) {
  // A 2023 epoch stamp: as a double it would print ...123456717, not ...123456789.
  EXPECT_EQ(FormatTumLine(1700000000123456789LL, Pose(1.5, -2.25, 0.125, M_PI / 2)),
            "1700000000.123456789 1.500000000 -2.250000000 0.125000000 0.000000000 0.000000000 "
            "0.707106781 0.707106781");
  EXPECT_EQ(FormatTumLine(-1500000000LL, Pose(0, 0, 0, 0)),
            "-1.500000000 0.000000000 0.000000000 0.000000000 0.000000000 0.000000000 "
            "0.000000000 1.000000000");
}

TEST(TumLine, SecondsStampMatchesTheNanosecondForm) {
  const Eigen::Isometry3d T = Pose(-3.0, 4.0, 0.5, 0.3);
  EXPECT_EQ(FormatTumLine(StampedPose{12.5, T}), FormatTumLine(12500000000LL, T));
  EXPECT_EQ(FormatTumLine(StampedPose{12.5, T}).substr(0, 13), "12.500000000 ");
}

TEST(TumLine, QuaternionIsWrittenWithNonNegativeW) {
  // 200 degrees about z: Eigen's matrix-to-quaternion gives w = cos(100 deg) < 0 here. The flip
  // negates the zero components too ("-0.000000000"), byte for byte what ppf_sim's ground truth
  // has always held; every reader parses it as 0.
  EXPECT_EQ(FormatTumLine(0, Pose(0, 0, 0, 200.0 * M_PI / 180.0)),
            "0.000000000 0.000000000 0.000000000 0.000000000 -0.000000000 -0.000000000 "
            "-0.984807753 0.173648178");
}

TEST(TumWriter, CommentLineOnlyWhenGivenAndOneLinePerPose) {
  const std::string bare = ::testing::TempDir() + "/ppf_tum_bare.tum";
  const std::string commented = ::testing::TempDir() + "/ppf_tum_commented.tum";
  {
    TumWriter w(bare);
    ASSERT_TRUE(w.ok());
    w.Write(StampedPose{1.0, Pose(1, 2, 3, 0)});
    w.Write(2000000000LL, Pose(4, 5, 6, 0));
    EXPECT_TRUE(w.Close());
  }
  EXPECT_EQ(Slurp(bare),
            "1.000000000 1.000000000 2.000000000 3.000000000 0.000000000 0.000000000 "
            "0.000000000 1.000000000\n"
            "2.000000000 4.000000000 5.000000000 6.000000000 0.000000000 0.000000000 "
            "0.000000000 1.000000000\n");
  {
    TumWriter w(commented, "T_world_imu at every IMU sample");
    w.Write(StampedPose{1.0, Pose(1, 2, 3, 0)});
    EXPECT_TRUE(w.Close());
  }
  EXPECT_EQ(Slurp(commented).substr(0, 34), "# T_world_imu at every IMU sample\n");
  Trajectory back;
  std::string error;
  ASSERT_TRUE(ReadTum(commented, &back, &error)) << error;
  ASSERT_EQ(back.size(), 1u);
  EXPECT_TRUE(back[0].T.isApprox(Pose(1, 2, 3, 0), 1e-12));
  std::remove(bare.c_str());
  std::remove(commented.c_str());
}

TEST(TumWriter, UnwritablePathIsReported) {
  TumWriter w("/nonexistent-dir/x.tum");
  EXPECT_FALSE(w.ok());
  w.Write(StampedPose{});
  EXPECT_FALSE(w.Close());
  EXPECT_FALSE(WriteTum("/nonexistent-dir/y.tum", Trajectory{StampedPose{}}));
}

TEST(WriteTum, ColumnHeaderThenTheSameLinesAsTheWriter) {
  const std::string path = ::testing::TempDir() + "/ppf_tum_whole.tum";
  const Trajectory traj = {{0.1, Pose(1, 0, 0, 0.1)}, {0.2, Pose(2, 0, 0, -0.2)}};
  ASSERT_TRUE(WriteTum(path, traj));
  EXPECT_EQ(Slurp(path), "# timestamp tx ty tz qx qy qz qw\n" + FormatTumLine(traj[0]) + "\n" +
                             FormatTumLine(traj[1]) + "\n");
  std::remove(path.c_str());
}

}  // namespace
}  // namespace ppf
