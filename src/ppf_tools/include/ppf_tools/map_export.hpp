// Map export for ppf_offline: the map files and the voxel grid are ppf_trajectory's (ppf_node
// writes the same files); what is added here is which core results go into the map.
#pragma once

#include "ppf_core/lio_ppf.hpp"
#include "ppf_trajectory/map_export.hpp"

namespace ppf::tools {

using ppf::MapFormat;
using ppf::MapFormatForFile;
using ppf::MapPoint;
using ppf::PcdHeader;
using ppf::PlyHeader;
using ppf::ToMapPoints;
using ppf::WriteMapFile;

class MapAccumulator : public ppf::MapAccumulator {
 public:
  using ppf::MapAccumulator::MapAccumulator;

  // The result's de-skewed points (Config::output_deskewed_points) if the scan has a trusted
  // pose: status kOk or kDegenerate with pose_valid, and not relocalized (a pose found again
  // after a long gap extends no map of the core's either). Returns whether they were added.
  bool AddResult(const ScanResult& result);
};

}  // namespace ppf::tools
