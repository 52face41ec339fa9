#include "ppf_core/lio_ppf.hpp"

#include <algorithm>
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

const char* ConsistencySearchName(ConsistencySearch search) {
  switch (search) {
    case ConsistencySearch::kNone:
      return "none";
    case ConsistencySearch::kPoorFit:
      return "fit";
    case ConsistencySearch::kScanStep:
      return "step";
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
  init = ImuInitializer(config.imu.init);
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
  lio_baseline.Clear();
  lio_steps_rot.clear();
  map.clear();
  imu.clear();
  imu_conflict = ImuConflict();
  state = NavState();
  last_scan_end = -std::numeric_limits<double>::infinity();
  bridged_gaps.clear();
  imu_lost = false;
  fallback_scan = false;
  fallback_seeded = false;
  relocalized_since_loss = false;
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
  if (finite && config.imu.mode != ImuMode::kNone) {
    // The stream's own clock, whether the sample is used or not (JudgeClockOffset).
    ++imu_arrived_since_scan;
    imu_arrived_stamp = s.stamp_s;
    if (clock_offset) {
      ++input_stats.imu_clock_offset_dropped;
      return;
    }
  }
  if (lidar_only && lidar_only_auto && finite) StartLateImu(s);
  if (lidar_only || config.imu.mode == ImuMode::kNone) {
    ++ignored_imu;
    return;
  }
  if (!lio_decided) {
    lio_decided = true;
    if (config.imu.mode == ImuMode::kAuto) {
      Log(LogLevel::kInfo, "IMU data present: LiDAR-inertial mode");
    }
  }
  if (!finite) {
    ++dropped_imu;
    return;
  }
  if (TakeImuDuplicate(s)) return;
  IntegrateImu(s);
  // Bounded buffer even if no scan ever arrives (a moving-start window trims its own).
  while (imu.size() > 2 && imu[1].stamp_s < state.stamp_s - 1.0 && initialized && !moving_init) {
    imu.pop_front();
  }
  while (imu.size() > 20000) imu.pop_front();
}

// A sample taken into the filter's stream: judged against the one before, buffered, and fed to
// the initialization while it runs.
void LioPpf::Impl::IntegrateImu(const ImuSample& s) {
  CountImuGap(s);
  JudgeImuGap(s);
  last_imu_stamp = s.stamp_s;
  imu.push_back(s);
  if (!initialized) FeedInitializer(s);
}

// Duplicate stamps. The same stamp and values as the newest sample (a redelivery): dropped and
// counted. Other values: a conflict. Arrival order says nothing about which copy is right (a
// faulty or hostile sender may send its copy first), so the copies are held, none integrated,
// until every copy of the stamp after them is in (a later stamp arrived); then
// ResolveImuConflict decides. Returns true if `s` was taken here (held or dropped).
bool LioPpf::Impl::TakeImuDuplicate(const ImuSample& s) {
  const auto same = [&s](const ImuSample& o) {
    return o.angular_velocity == s.angular_velocity &&
           o.linear_acceleration == s.linear_acceleration;
  };
  const auto hold = [&](std::vector<ImuSample>* copies) {
    if (std::any_of(copies->begin(), copies->end(), same)) {
      ++input_stats.imu_duplicates;
    } else if (copies->size() < 8) {  // bounded
      copies->push_back(s);
    }
  };
  ImuConflict& c = imu_conflict;
  if (c.active) {
    const double t = c.copies.front().stamp_s;
    if (s.stamp_s < (c.next.empty() ? t : c.next.front().stamp_s)) {
      // Out of order: the held copies go, the sample is judged as any other (time going back).
      c = ImuConflict();
      return false;
    }
    if (s.stamp_s == t) {
      hold(&c.copies);
    } else if (c.next.empty() || s.stamp_s == c.next.front().stamp_s) {
      hold(&c.next);
    } else {
      ResolveImuConflict();
      if (!imu_conflict.active) return false;
      imu_conflict.next.push_back(s);  // the stamp after it was in conflict as well
    }
    return true;
  }
  if (imu.empty() || s.stamp_s != imu.back().stamp_s) return false;
  if (same(imu.back())) {
    ++input_stats.imu_duplicates;
    return true;
  }
  c.active = true;
  c.copies = {imu.back(), s};
  c.next.clear();
  c.has_prev = imu.size() >= 2;
  if (c.has_prev) {
    c.prev = imu[imu.size() - 2];
    last_imu_stamp = c.prev.stamp_s;  // what the stream has settled up to
  }
  imu.pop_back();
  // The static initialization has seen the first copy: its window starts again after the
  // conflict rather than average a value that may be wrong.
  if (!initialized) init.Reset();
  return true;
}

// Decides a conflict once the next stamp's copies are in: each copy is compared with the values
// its neighbours give at its stamp (interpolated between the settled sample before and a copy of
// the next stamp; the closest such pair counts). The copy clearly closest (at most half the
// distance of any other) is integrated, otherwise none is: one sample period without a sample
// costs less than a wrong one. Counted, one WARN line (rate limited). The next stamp is then
// integrated, or, with several values itself, becomes the next conflict.
void LioPpf::Impl::ResolveImuConflict() {
  // Units: 1 m/s^2 of acceleration weighs as much as 0.1 rad/s of turn rate.
  constexpr double kAccUnit = 1.0, kGyroUnit = 0.1;
  ImuConflict c = std::move(imu_conflict);
  imu_conflict = ImuConflict();
  const double t = c.copies.front().stamp_s;
  const auto distance = [&](const ImuSample& copy) {
    double best = std::numeric_limits<double>::infinity();
    for (const ImuSample& n : c.next) {
      Eigen::Vector3d acc = n.linear_acceleration, gyro = n.angular_velocity;
      if (c.has_prev && n.stamp_s > c.prev.stamp_s) {
        const double w = (t - c.prev.stamp_s) / (n.stamp_s - c.prev.stamp_s);
        acc = (1.0 - w) * c.prev.linear_acceleration + w * n.linear_acceleration;
        gyro = (1.0 - w) * c.prev.angular_velocity + w * n.angular_velocity;
      }
      best = std::min(best, (copy.linear_acceleration - acc).norm() / kAccUnit +
                                (copy.angular_velocity - gyro).norm() / kGyroUnit);
    }
    return best;
  };
  size_t best = 0;
  double best_d = std::numeric_limits<double>::infinity(), second_d = best_d;
  for (size_t i = 0; i < c.copies.size(); ++i) {
    const double d = distance(c.copies[i]);
    if (d < best_d) {
      second_d = best_d;
      best_d = d;
      best = i;
    } else if (d < second_d) {
      second_d = d;
    }
  }
  const bool keep = 2.0 * best_d < second_d;
  ++input_stats.imu_conflicts;
  if (!keep) ++input_stats.imu_conflicts_unresolved;
  size_t held = 0;
  if (imu_conflict_log.Allow(t, &held)) {
    const ImuSample& a = c.copies[0];
    const ImuSample& b = c.copies[1];
    std::ostringstream os;
    os << "IMU samples in conflict at t=" << t << ": " << c.copies.size()
       << " copies with different values (acc differs by "
       << (a.linear_acceleration - b.linear_acceleration).norm() << " m/s^2, gyro by "
       << (a.angular_velocity - b.angular_velocity).norm() << " rad/s): ";
    if (keep) {
      os << "kept the copy that arrived " << (best == 0 ? "first" : best == 1 ? "second" : "later")
         << ", consistent with the samples either side";
    } else {
      os << "kept none (no copy clearly consistent with the samples either side)";
    }
    if (held > 0) os << " (" << held << " more conflicts since the last line)";
    Log(LogLevel::kWarn, os.str());
  }
  if (keep) IntegrateImu(c.copies[best]);
  if (c.next.size() == 1) {
    IntegrateImu(c.next.front());
    return;
  }
  imu_conflict.active = true;
  imu_conflict.copies = std::move(c.next);
  imu_conflict.has_prev = !imu.empty();
  if (imu_conflict.has_prev) imu_conflict.prev = imu.back();
}

// Gaps longer than imu.max_gap_warn are counted; each is named in one WARN line, here up to
// imu.max_gap (JudgeImuGap's lines name the longer ones when the filter runs).
void LioPpf::Impl::CountImuGap(const ImuSample& s) {
  const double gap = s.stamp_s - last_imu_stamp;
  if (!(gap > config.imu.max_gap_warn_s) || !std::isfinite(gap)) return;
  ++input_stats.imu_gaps;
  input_stats.imu_gap_longest_s = std::max(input_stats.imu_gap_longest_s, gap);
  imu_gap_longest_since_result_s = std::max(imu_gap_longest_since_result_s, gap);
  const bool named_later = gap > config.imu.max_gap_s && (initialized || moving_init || imu_lost);
  size_t held = 0;
  if (named_later || !imu_gap_log.Allow(s.stamp_s, &held)) return;
  std::ostringstream os;
  os << "IMU gap of " << gap << " s (no sample from t=" << last_imu_stamp << " to " << s.stamp_s
     << ") > imu.max_gap_warn " << config.imu.max_gap_warn_s << " s";
  if (held > 0) os << " (" << held << " more gaps since the last line)";
  Log(LogLevel::kWarn, os.str());
}

// Clock offset: the scan's end against the newest IMU sample, when samples arrived since the
// previous scan (both streams live; a stalled IMU is an IMU loss, not an offset). Only an IMU
// behind is judged: an IMU ahead is what a core lagging behind its input queues sees too.
void LioPpf::Impl::JudgeClockOffset(const DecodedScan& scan) {
  const bool live = imu_arrived_since_scan > 0;
  imu_arrived_since_scan = 0;
  if (!live || scan.points.empty()) return;
  const double offset = scan.t_end - imu_arrived_stamp;
  const bool off = offset >= kClockOffsetS;
  if (clock_offset && off) clock_offset_s = offset;
  clock_offset_votes = off != clock_offset ? clock_offset_votes + 1 : 0;
  if (clock_offset_votes < kClockOffsetScans) return;
  clock_offset_votes = 0;
  if (off) {
    EnterClockOffset(offset, scan);
    return;
  }
  clock_offset = false;
  clock_offset_s = 0.0;
  std::ostringstream os;
  os << "IMU and LiDAR clocks agree again (scan end " << scan.t_end << ", newest IMU sample "
     << imu_arrived_stamp << "): the IMU is used from its next sample on";
  Log(LogLevel::kInfo, os.str());
}

// The IMU's clock runs seconds behind the LiDAR's: its samples never cover a scan, so LIO (or
// its initialization) would wait for good. The scans go on LiDAR-only: with the IMU-loss
// fallback if LIO ran (map, gravity and biases kept; LIO resumes when the clocks agree), else
// as without an IMU (the IMU then takes over as a late IMU). The samples are not used meanwhile.
void LioPpf::Impl::EnterClockOffset(double offset_s, const DecodedScan& scan) {
  clock_offset = true;
  clock_offset_s = offset_s;
  std::ostringstream os;
  os << "IMU clock " << offset_s << " s behind the LiDAR's (scan ending at t=" << scan.t_end
     << ", newest IMU sample t=" << imu_arrived_stamp << ", both streams live for "
     << kClockOffsetScans << " scans)";
  if (initialized && map_initialized && !moving_init && !lidar_only) {
    if (imu_lost) {
      Log(LogLevel::kWarn, os.str() + ": continuing LiDAR-only until the clocks agree");
    } else {
      EnterImuLoss(os.str());
    }
    imu_back = false;
    return;
  }
  if (!lidar_only) {
    if (late_imu) {
      // The LiDAR-only map and world stay; the late IMU's window starts again later.
      late_imu = false;
      moving_poses.clear();
    } else {
      ClearMovingInit();
      init.Reset();
    }
    moving_init = false;
    moving_refused = false;
    lidar_only = true;
    lidar_only_auto = true;
    initialized = true;
    imu.clear();
    imu_conflict = ImuConflict();
  }
  Log(LogLevel::kWarn, os.str() +
                           ": continuing LiDAR-only (constant-velocity prediction) until the "
                           "clocks agree; the IMU then takes over without a reset");
}

// The IMU stream covers scans up to here: while copies of the newest stamp are in conflict,
// only up to the sample before them.
double LioPpf::Impl::ImuCoveredUntil() const {
  if (!imu_conflict.active) return last_imu_stamp;
  return imu_conflict.has_prev ? imu_conflict.prev.stamp_s
                               : -std::numeric_limits<double>::infinity();
}

// The input counts of a result: what happened since the previous result.
void LioPpf::Impl::AddInputCounts(ScanResult* r) {
  r->imu_gaps = input_stats.imu_gaps - input_reported.imu_gaps;
  r->imu_gap_longest_s = imu_gap_longest_since_result_s;
  r->imu_conflicts = input_stats.imu_conflicts - input_reported.imu_conflicts;
  r->imu_conflicts_unresolved =
      input_stats.imu_conflicts_unresolved - input_reported.imu_conflicts_unresolved;
  input_reported = input_stats;
  imu_gap_longest_since_result_s = 0.0;
}

// What the time since the last sample means: time going back resets the filter; a gap restarts a
// moving start, ends an IMU-loss fallback (LIO resumes), or is bridged or entered as IMU loss.
void LioPpf::Impl::JudgeImuGap(const ImuSample& s) {
  if (s.stamp_s < last_imu_stamp - 1e-9) {
    std::ostringstream os;
    os << "IMU time went backwards by " << last_imu_stamp - s.stamp_s << " s";
    last_imu_stamp = -std::numeric_limits<double>::infinity();
    ResetFilter(os.str());
  } else if (moving_init && s.stamp_s - last_imu_stamp > config.imu.max_gap_s) {
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
  } else if (initialized && s.stamp_s - last_imu_stamp > config.imu.max_gap_s) {
    const double gap = s.stamp_s - last_imu_stamp;
    std::ostringstream os;
    os << "IMU gap of " << gap << " s > imu.max_gap " << config.imu.max_gap_s << " s";
    if (gap <= config.imu.max_gap_bridge_s) {
      // Widened when the next scan has been propagated across it (ProcessOne): a scan still
      // queued from before the gap must not see the extra uncertainty.
      bridged_gaps.push_back({last_imu_stamp, gap});
      Log(LogLevel::kWarn, os.str() + ": bridged (state and map kept, uncertainty widened)");
    } else {
      // Both streams were silent (no scan needed the fallback): integrating across the gap would
      // run away, and a reset would need a static start a moving robot never gives. The scans
      // before these samples are registered LiDAR-only, then LIO re-anchors.
      os << " and > imu.max_gap_bridge " << config.imu.max_gap_bridge_s << " s";
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
  if (config.imu.init.moving_start) moving_init = true;
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
  } else if (q.scan.dropped_bad_time > 0) {
    JudgeBadPointTimes(&q);  // logs for itself (rate limited)
    if (!q.rejected) JudgeClockOffset(q.scan);
    q.decode_ms = MsSince(t0);
    scans.push_back(std::move(q));
    return last_input_id;
  } else {
    JudgeClockOffset(q.scan);
  }
  if (q.rejected) Log(LogLevel::kWarn, "scan rejected: " + q.error);
  q.decode_ms = MsSince(t0);
  scans.push_back(std::move(q));
  return last_input_id;
}

// Point times outside the plausible sweep window were dropped by the decoder (time_field.hpp).
// Most of the scan's points: the rest cannot be trusted either, the scan is skipped (rejected,
// nothing changes: no reset, no wait for IMU coverage far ahead). One line, rate limited.
void LioPpf::Impl::JudgeBadPointTimes(QueuedScan* q) {
  const DecodedScan& scan = q->scan;
  std::ostringstream os;
  os << scan.dropped_bad_time << " of " << scan.input_points
     << " point times outside the plausible sweep window of the scan stamped " << q->stamp_s
     << " (from " << kEarlyPointTimeS << " s before a scan-start stamp to 2 x time.scan_period = "
     << 2.0 * config.time.scan_period_s << " s after it)";
  input_stats.points_bad_time += scan.dropped_bad_time;
  if (scan.dropped_bad_time >= scan.points.size()) {
    q->rejected = true;
    q->error = os.str() + ": scan skipped";
    ++input_stats.scans_bad_time;
  }
  size_t held = 0;
  if (!bad_time_log.Allow(q->stamp_s, &held)) return;
  if (held > 0) os << " (" << held << " more such scans since the last line)";
  Log(LogLevel::kWarn, q->rejected ? "scan rejected: " + q->error : os.str() + ": points dropped");
}

ScanResult LioPpf::Impl::Rejected(const QueuedScan& q) const {
  ScanResult r;
  r.input_id = q.id;
  r.stamp_s = q.stamp_s;
  r.status = Status::kRejected;
  r.reason = "malformed cloud: " + q.error;
  r.map_size = map.size();
  r.input_points = q.scan.input_points;
  r.dropped_nan = q.scan.dropped_nan;
  r.points_bad_time = q.scan.dropped_bad_time;
  return r;
}

std::vector<ScanResult> LioPpf::Impl::Process(bool flush) {
  std::vector<ScanResult> out;
  if (!DecideImuMode(flush)) return out;
  while (!scans.empty()) {
    QueuedScan& q = scans.front();
    // Wait for the IMU to cover the scan, unless the IMU stream has stalled: scans newer than
    // the last IMU sample by more than imu.max_gap_s are not held back forever.
    const bool imu_stalled = scans.back().stamp_s - last_imu_stamp > config.imu.max_gap_s;
    fallback_scan = !q.rejected && NeedsFallback(q.scan, imu_stalled || flush);
    if (!q.rejected && !flush && !imu_stalled && !fallback_scan &&
        ImuCoveredUntil() < q.scan.t_end) {
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
    AddInputCounts(&out.back());
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
// imu.loss_timeout_s after the last IMU sample declares the loss (only when the stream has
// stalled or at flush: otherwise the scan waits for samples still on their way); the loss lasts
// until IMU samples are back from the start of the scan on.
bool LioPpf::Impl::NeedsFallback(const DecodedScan& scan, bool may_declare) {
  if (!initialized || !map_initialized || lidar_only || moving_init) return false;
  if (imu_lost) {
    // A re-localized pose gives no velocity to resume from when the next scan comes this late
    // (a core that fell behind dropped the scans between): re-localize again.
    if (relocalized_since_loss && scan.t_end - state.stamp_s > config.imu.max_gap_s) return true;
    return !(imu_back && imu_back_stamp_s <= state.stamp_s + kResumeSlackS);
  }
  if (!may_declare || scan.t_end - last_imu_stamp <= config.imu.loss_timeout_s) return false;
  std::ostringstream os;
  os << "no IMU sample for " << scan.t_end - last_imu_stamp << " s > imu.loss_timeout "
     << config.imu.loss_timeout_s << " s";
  EnterImuLoss(os.str());
  return true;
}

void LioPpf::Impl::EnterImuLoss(const std::string& why) {
  imu_lost = true;
  imu_back = false;
  fallback_seeded = false;
  relocalized_since_loss = false;
  Log(LogLevel::kWarn, "IMU lost (" + why +
                           "): continuing LiDAR-only (constant-velocity prediction; map, gravity "
                           "and biases kept) until IMU samples are back");
}

// kAuto: decides when the input says whether there is an IMU. Returns false while undecided
// (the scans wait: none is lost to the decision).
bool LioPpf::Impl::DecideImuMode(bool flush) {
  if (lidar_only || lio_decided) return true;
  if (config.imu.mode == ImuMode::kLio) {
    lio_decided = true;
    return true;
  }
  const bool none = config.imu.mode == ImuMode::kNone;
  if (!none) {
    if (scans.empty()) return true;
    const double span = scans.back().stamp_s - scans.front().stamp_s;
    if (!flush && span < config.imu.auto_wait_s) return false;
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

// Late IMU (docs/behaviour.md, "Late IMU"): the first valid sample after imu.mode auto decided
// LiDAR-only. The scans keep being registered LiDAR-only in the same map while the moving-start
// window (of scans after this sample) estimates gravity, velocity and gyro bias; the static
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
  imu_conflict = ImuConflict();
  std::ostringstream os;
  os << "IMU data at t=" << s.stamp_s << " after a LiDAR-only start: LiDAR-inertial once "
     << config.imu.init.moving_start_window_s
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
  impl_->clock_offset = false;
  impl_->clock_offset_s = 0.0;
  impl_->clock_offset_votes = 0;
  impl_->imu_arrived_stamp = -std::numeric_limits<double>::infinity();
  impl_->imu_arrived_since_scan = 0;
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
InputStats LioPpf::input_stats() const { return impl_->input_stats; }
const TimeFieldInfo& LioPpf::time_field_info() const { return impl_->decoder.info(); }
bool LioPpf::initialized() const { return impl_->initialized; }
bool LioPpf::lidar_only() const { return impl_->lidar_only; }

}  // namespace ppf
