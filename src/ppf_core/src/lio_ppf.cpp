#include "ppf_core/lio_ppf.hpp"

#include <cmath>
#include <limits>
#include <sstream>

#include "lio_ppf_impl.hpp"

namespace ppf {

const char* StatusName(Status status) {
  switch (status) {
    case Status::kOk:
      return "ok";
    case Status::kInitializing:
      return "initializing";
    case Status::kDegenerate:
      return "degenerate";
    case Status::kReset:
      return "reset";
    case Status::kRejected:
      return "rejected";
  }
  return "?";
}

LioPpf::Impl::Impl(const Config& c) : config(c), map(c.map) {
  for (const std::string& note : ValidateConfig(&config)) Log(LogLevel::kWarn, "config: " + note);
  if (config.num_threads > 0) {
    config.knn.num_threads = config.num_threads;
  }
  decoder = TimeFieldDecoder(config.time, config.log);
  decoder.set_num_threads(config.num_threads);
  init = ImuInitializer(config.init);
  map = VoxelMap(config.map);
  knn = std::make_shared<KnnResidualProvider>(config.knn);
  // PPF: the paper's plane pre-fitting + skeleton tracking splits every kPpf scan.
  if (config.mode == Mode::kPpf) {
    if (config.num_threads > 0 && config.ppf.num_threads == 0) {
      config.ppf.num_threads = config.num_threads;
    }
    tracker = std::make_unique<SkeletonTracker>(config.ppf);
  }
}

// Drops filter state and map; the next IMU samples start a new initialization.
void LioPpf::Impl::ResetFilter(const std::string& reason) {
  initialized = false;
  map_initialized = false;
  moving_init = false;
  moving_refused = false;
  moving_poses.clear();
  moving_scans = 0;
  init.Reset();
  motion.Reset();
  recent_fits.clear();
  map.clear();
  imu.clear();
  state = NavState();
  last_scan_end = -std::numeric_limits<double>::infinity();
  bridged_gaps.clear();
  imu_lost = false;
  fallback_scan = false;
  fallback_seeded = false;
  imu_back = false;
  late_imu = false;
  world_is_map = false;
  if (tracker) tracker->Reset();
  knn->Reset();
  scans_since_prune = 0;
  // LiDAR-only needs no initialization: the next scan starts the map again.
  if (lidar_only) initialized = true;
  if (!reason.empty()) {
    Log(LogLevel::kWarn, "reset: " + reason);
    ScanResult r;
    r.status = Status::kReset;
    r.reason = reason;
    r.stamp_s = last_imu_stamp;
    pending.push_back(r);
  }
}

void LioPpf::Impl::AddImu(const ImuSample& s) {
  // kNone: ignored even before the first scan has made the decision (DecideImuMode).
  const bool finite = std::isfinite(s.stamp_s) && s.angular_velocity.allFinite() &&
                      s.linear_acceleration.allFinite();
  if (lidar_only && lidar_only_auto && finite) StartLateImu(s);
  if (lidar_only || config.imu_mode == ImuMode::kNone) {
    ++ignored_imu;
    return;
  }
  if (!lio_decided) {
    lio_decided = true;
    if (config.imu_mode == ImuMode::kAuto) {
      Log(LogLevel::kInfo, "IMU data present: LiDAR-inertial mode");
    }
  }
  if (!finite) {
    ++dropped_imu;
    return;
  }
  JudgeImuGap(s);
  last_imu_stamp = s.stamp_s;
  imu.push_back(s);
  if (!initialized) FeedInitializer(s);
  // Bounded buffer even if no scan ever arrives (a moving-start window trims its own).
  while (imu.size() > 2 && imu[1].stamp_s < state.stamp_s - 1.0 && initialized && !moving_init) {
    imu.pop_front();
  }
  while (imu.size() > 20000) imu.pop_front();
}

// What the time since the last sample means: time going back resets the filter; a gap restarts a
// moving start, ends an IMU-loss fallback (LIO resumes), or is bridged or entered as IMU loss.
void LioPpf::Impl::JudgeImuGap(const ImuSample& s) {
  if (s.stamp_s < last_imu_stamp - 1e-9) {
    std::ostringstream os;
    os << "IMU time went backwards by " << last_imu_stamp - s.stamp_s << " s";
    last_imu_stamp = -std::numeric_limits<double>::infinity();
    ResetFilter(os.str());
  } else if (moving_init && s.stamp_s - last_imu_stamp > config.max_imu_gap_s) {
    // The preintegration would span the gap: register the scans again after it.
    std::ostringstream os;
    os << "IMU gap of " << s.stamp_s - last_imu_stamp << " s";
    RestartMovingInit(os.str());
  } else if (imu_lost && !imu_back) {
    // The fallback's scans were registered LiDAR-only meanwhile: no bridge, LIO resumes
    // (re-anchored) with the first scan these samples cover.
    imu_back = true;
    imu_back_stamp_s = s.stamp_s;
    imu_loss_gap_s = s.stamp_s - last_imu_stamp;
    std::ostringstream os;
    os << "IMU gap of " << imu_loss_gap_s << " s: IMU back, LIO resumes at the next scan it covers"
       << " (re-anchored at the LiDAR-only pose, map, gravity and biases kept)";
    Log(LogLevel::kInfo, os.str());
  } else if (initialized && s.stamp_s - last_imu_stamp > config.max_imu_gap_s) {
    const double gap = s.stamp_s - last_imu_stamp;
    std::ostringstream os;
    os << "IMU gap of " << gap << " s > max_imu_gap " << config.max_imu_gap_s << " s";
    if (gap <= config.max_imu_gap_bridge_s) {
      // Widened when the next scan has been propagated across it (ProcessOne): a scan still
      // queued from before the gap must not see the extra uncertainty.
      bridged_gaps.push_back({last_imu_stamp, gap});
      Log(LogLevel::kWarn, os.str() + ": bridged (state and map kept, uncertainty widened)");
    } else {
      // Both streams were silent (no scan needed the fallback): integrating across the gap would
      // run away, and a reset would need a static start a moving robot never gives. The scans
      // before these samples are registered LiDAR-only, then LIO re-anchors.
      os << " and > max_imu_gap_bridge " << config.max_imu_gap_bridge_s << " s";
      EnterImuLoss(os.str());
      imu_back = true;
      imu_back_stamp_s = s.stamp_s;
      imu_loss_gap_s = gap;
    }
  }
}

void LioPpf::Impl::FeedInitializer(const ImuSample& s) {
  // The scans are registered LiDAR-only while the IMU is judged, so that a moving start has
  // its window of poses by the time the IMU is refused; a static start discards them.
  if (config.init.moving_start) moving_init = true;
  const ImuInitializer::State st = init.Add(s);
  if (st == ImuInitializer::State::kRestarted) {
    Log(LogLevel::kWarn, init.reason());
    if (moving_init && init.refused_for_motion() && !moving_refused) {
      moving_refused = true;
      Log(LogLevel::kInfo,
          "no rest at start: moving-start initialization (gravity and velocity from the "
          "LiDAR-only registration of the first scans and the IMU)");
    }
  }
  if (st == ImuInitializer::State::kDone) StartFilter();
}

uint64_t LioPpf::Impl::AddScan(const CloudView& cloud) {
  QueuedScan q;
  q.id = ++last_input_id;
  q.stamp_s = cloud.stamp_s;
  const auto t0 = Clock::now();
  std::string error;
  if (!std::isfinite(cloud.stamp_s)) {
    q.rejected = true;
    q.error = "header stamp is not finite";
  } else if (!decoder.Decode(cloud, &q.scan, &error)) {
    q.rejected = true;
    q.error = error;
  }
  if (q.rejected) Log(LogLevel::kWarn, "scan rejected: " + q.error);
  q.decode_ms = MsSince(t0);
  scans.push_back(std::move(q));
  return last_input_id;
}

ScanResult LioPpf::Impl::Rejected(const QueuedScan& q) const {
  ScanResult r;
  r.input_id = q.id;
  r.stamp_s = q.stamp_s;
  r.status = Status::kRejected;
  r.reason = "malformed cloud: " + q.error;
  r.map_size = map.size();
  return r;
}

std::vector<ScanResult> LioPpf::Impl::Process(bool flush) {
  std::vector<ScanResult> out;
  if (!DecideImuMode(flush)) return out;
  while (!scans.empty()) {
    QueuedScan& q = scans.front();
    // Wait for the IMU to cover the scan, unless the IMU stream has stalled: scans newer than
    // the last IMU sample by more than max_imu_gap_s are not held back forever.
    const bool imu_stalled = scans.back().stamp_s - last_imu_stamp > config.max_imu_gap_s;
    fallback_scan = !q.rejected && NeedsFallback(q.scan, imu_stalled || flush);
    if (!q.rejected && !flush && !imu_stalled && !fallback_scan && last_imu_stamp < q.scan.t_end) {
      break;
    }
    // Reset notices belong before the first scan processed after the reset.
    for (ScanResult& r : pending) out.push_back(std::move(r));
    pending.clear();
    if (q.rejected) {
      out.push_back(Rejected(q));
    } else {
      const bool moving = moving_init;
      out.push_back(ProcessOne(q));
      if (moving) MovingInitStep(&out.back());
    }
    decoder.Recycle(&q.scan.points);
    scans.pop_front();
  }
  if (flush) {
    for (ScanResult& r : pending) out.push_back(std::move(r));
    pending.clear();
  }
  return out;
}

// IMU loss: true if this scan is registered LiDAR-only. LIO running, a scan ending more than
// imu_loss_timeout_s after the last IMU sample declares the loss (only when the stream has
// stalled or at flush: otherwise the scan waits for samples still on their way); the loss lasts
// until IMU samples are back from the start of the scan on.
bool LioPpf::Impl::NeedsFallback(const DecodedScan& scan, bool may_declare) {
  if (!initialized || !map_initialized || lidar_only || moving_init) return false;
  if (imu_lost) return !(imu_back && imu_back_stamp_s <= state.stamp_s + kResumeSlackS);
  if (!may_declare || scan.t_end - last_imu_stamp <= config.imu_loss_timeout_s) return false;
  std::ostringstream os;
  os << "no IMU sample for " << scan.t_end - last_imu_stamp << " s > imu.loss_timeout "
     << config.imu_loss_timeout_s << " s";
  EnterImuLoss(os.str());
  return true;
}

void LioPpf::Impl::EnterImuLoss(const std::string& why) {
  imu_lost = true;
  imu_back = false;
  fallback_seeded = false;
  Log(LogLevel::kWarn, "IMU lost (" + why +
                           "): continuing LiDAR-only (constant-velocity prediction; map, gravity "
                           "and biases kept) until IMU samples are back");
}

// kAuto: decides when the input says whether there is an IMU. Returns false while undecided
// (the scans wait: none is lost to the decision).
bool LioPpf::Impl::DecideImuMode(bool flush) {
  if (lidar_only || lio_decided) return true;
  if (config.imu_mode == ImuMode::kLio) {
    lio_decided = true;
    return true;
  }
  const bool none = config.imu_mode == ImuMode::kNone;
  if (!none) {
    if (scans.empty()) return true;
    const double span = scans.back().stamp_s - scans.front().stamp_s;
    if (!flush && span < config.imu_auto_wait_s) return false;
  }
  lidar_only = true;
  lidar_only_auto = !none;
  initialized = true;
  imu.clear();
  std::ostringstream os;
  os << (none ? "imu.mode none" : "no IMU data with the first scans")
     << ": LiDAR-only mode (constant-velocity prediction, world = first scan's LiDAR frame)";
  Log(LogLevel::kInfo, os.str());
  return true;
}

// Late IMU (lio_ppf.hpp): the first valid sample after imu.mode auto decided LiDAR-only. The
// scans keep being registered LiDAR-only in the same map while the moving-start window (of
// scans after this sample) estimates gravity, velocity and gyro bias; the static
// initialization is not used, it would start a new world.
void LioPpf::Impl::StartLateImu(const ImuSample& s) {
  lidar_only = false;
  lidar_only_auto = false;
  lio_decided = true;
  late_imu = true;
  late_imu_from_s = s.stamp_s;
  moving_init = true;
  moving_refused = true;
  moving_poses.clear();
  // The map is built: no warm-up, but the scan in flight may begin before this sample.
  moving_scans = kMovingWarmupScans - 1;
  last_imu_stamp = s.stamp_s;  // no gap to the (absent) previous sample
  imu.clear();
  std::ostringstream os;
  os << "IMU data at t=" << s.stamp_s << " after a LiDAR-only start: LiDAR-inertial once "
     << config.init.moving_start_window_s
     << " s of scans estimate gravity in the LiDAR-only world (kept: no reset, no jump)";
  Log(LogLevel::kInfo, os.str());
}

LioPpf::LioPpf(const Config& config) : impl_(std::make_unique<Impl>(config)) {}
LioPpf::~LioPpf() = default;

void LioPpf::AddImu(const ImuSample& sample) { impl_->AddImu(sample); }
uint64_t LioPpf::AddScan(const CloudView& cloud) { return impl_->AddScan(cloud); }
std::vector<ScanResult> LioPpf::Process(bool flush) { return impl_->Process(flush); }

ScanResult LioPpf::ProcessScan(const CloudView& cloud) {
  AddScan(cloud);
  std::vector<ScanResult> results = Process(true);
  if (results.empty()) {
    ScanResult r;
    r.status = Status::kRejected;
    r.reason = "internal: no result";
    return r;
  }
  return results.back();
}

void LioPpf::Reset() {
  impl_->scans.clear();
  impl_->pending.clear();
  impl_->last_imu_stamp = -std::numeric_limits<double>::infinity();
  impl_->ResetFilter("");
  impl_->decoder.Reset();
}
const Config& LioPpf::config() const { return impl_->config; }
MapStats LioPpf::map_stats() const {
  MapStats s;
  s.points = impl_->map.size();
  s.voxels = impl_->map.num_voxels();
  s.capacity_points = impl_->map.capacity_points();
  return s;
}
std::vector<Eigen::Vector3f> LioPpf::LocalMapPoints() const {
  std::vector<Eigen::Vector3f> out;
  out.reserve(impl_->map.size());
  const Eigen::Isometry3f T = impl_->WorldFromMap().cast<float>();
  impl_->map.ForEachPoint([&](const Eigen::Vector3f& p) { out.push_back(T * p); });
  return out;
}
const TimeFieldInfo& LioPpf::time_field_info() const { return impl_->decoder.info(); }
bool LioPpf::initialized() const { return impl_->initialized; }
bool LioPpf::lidar_only() const { return impl_->lidar_only; }

}  // namespace ppf
