#include "node_map.hpp"

#include <iomanip>
#include <sstream>
#include <utility>

#include "ppf_dds_node/logging.hpp"

namespace ppf::dds {

namespace {

// Scans queued for the map thread at most: 30 s of a 10 Hz LiDAR. Only a write stuck that long
// (a hung disk) fills it; then scans are left out of the map, counted and reported with the
// next save, instead of the node's memory growing without bound.
constexpr size_t kMaxQueuedScans = 300;

}  // namespace

NodeMap::NodeMap(const NodeConfig& config) : file_(config.map_file), grid_(config.map_voxel) {
  if (file_.empty()) return;
  MapFormatForFile(file_, false, &format_);
  thread_ = std::thread([this] { Run(); });
}

NodeMap::~NodeMap() { Finish(); }

void NodeMap::Add(const ScanResult& r) {
  if (!enabled()) return;
  const bool trusted = r.pose_valid && !r.relocalized &&
                       (r.status == Status::kOk || r.status == Status::kDegenerate);
  if (!trusted || r.deskewed_points_lidar.empty()) return;
  Scan scan{r.deskewed_points_lidar, r.T_world_lidar};  // copied before the lock is taken
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (queue_.size() >= kMaxQueuedScans) {
      ++skipped_;
      return;
    }
    queue_.push_back(std::move(scan));
  }
  cv_.notify_one();
}

void NodeMap::RequestSave() {
  if (!enabled()) return;
  save_requested_ = true;
  // Under the lock, so the map thread cannot miss the wake-up between its check and its wait.
  { std::lock_guard<std::mutex> lock(mutex_); }
  cv_.notify_one();
}

void NodeMap::Finish() {
  if (!enabled()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    finishing_ = true;
  }
  cv_.notify_one();
  thread_.join();
}

void NodeMap::Run() {
  std::vector<Scan> batch;
  while (true) {
    bool finish = false;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [this] { return !queue_.empty() || save_requested_ || finishing_; });
      batch.swap(queue_);
      finish = finishing_;  // set after the last Add: this batch holds every scan
    }
    for (const Scan& s : batch) grid_.AddScan(s.points_lidar, s.T_world_lidar);
    batch.clear();
    const bool save = save_requested_.exchange(false);
    if (finish) {
      Save("at shutdown");
      return;
    }
    if (save) Save("on request (SIGUSR1)");
  }
}

void NodeMap::Save(const char* why) {
  const std::vector<MapPoint> points = grid_.Points();
  std::string error;
  if (!WriteMapFile(file_, points, format_, &error)) {
    ++save_errors_;
    Log(Level::kError, "map not saved " + std::string(why) + ": " + error +
                           " (the node goes on mapping; SIGUSR1 tries again)");
    return;
  }
  ++saves_;
  std::ostringstream os;
  os << "map saved " << why << ": " << points.size() << " points (" << std::defaultfloat
     << std::setprecision(6) << grid_.voxel_size() << " m voxels, " << grid_.scans_added()
     << " scans) -> " << file_;
  if (skipped_ > 0) os << "; " << skipped_ << " scans left out (the map thread fell behind)";
  Log(Level::kInfo, os.str());
}

}  // namespace ppf::dds
