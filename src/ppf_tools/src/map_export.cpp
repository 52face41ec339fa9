#include "ppf_tools/map_export.hpp"

namespace ppf::tools {

bool MapAccumulator::AddResult(const ScanResult& r) {
  const bool trusted = r.pose_valid && !r.relocalized &&
                       (r.status == Status::kOk || r.status == Status::kDegenerate);
  if (!trusted) return false;
  AddScan(r.deskewed_points_lidar, r.T_world_lidar);
  return true;
}

}  // namespace ppf::tools
