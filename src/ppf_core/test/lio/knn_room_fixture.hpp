// The fixture of the IEKF and kNN residual tests: a kNN map from two scans of the synthetic room
// at the identity, and a third (independently noisy) scan from the same pose as the frame.
#pragma once

#include <random>
#include <vector>

#include "ppf_core/lio/residual_provider.hpp"
#include "ppf_core/lio/voxel_downsample.hpp"
#include "ppf_core/lio/voxel_map.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace test {

struct KnnRoomFixture {
  VoxelMap map;
  ScanFrame frame;
};

// Map from one scan at the identity, and a second (independently noisy) scan from the same pose.
inline void BuildKnnRoom(const Scene& scene, KnnRoomFixture* f, double max_range = 100.0) {
  LidarModel lidar;
  lidar.range_noise = 0.01;
  lidar.max_range = max_range;
  std::mt19937 rng(5);
  const PoseFn still = [](double) { return Eigen::Isometry3d::Identity(); };
  for (double t : {0.0, 0.0123}) {  // two map scans, slightly different noise
    for (const auto& p :
         SimulateScan(scene, still, Eigen::Isometry3d::Identity(), t, lidar, &rng)) {
      f->map.Insert(p.p);
    }
  }
  std::vector<Eigen::Vector3f> scan;
  for (const auto& p :
       SimulateScan(scene, still, Eigen::Isometry3d::Identity(), 1.0, lidar, &rng)) {
    scan.push_back(p.p);
  }
  f->frame.points_lidar = VoxelDownsample(scan, 0.5);
  f->frame.labels.assign(f->frame.points_lidar.size(), PointLabel::kScattered);
  f->frame.map = &f->map;
}

}  // namespace test
}  // namespace ppf
