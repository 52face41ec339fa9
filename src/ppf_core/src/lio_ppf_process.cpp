// One scan's path (ProcessOne): accept, preprocess, propagate and de-skew, then start the map
// (first scan) or register the scan (coarse alignment when LiDAR-only, PPF split, iterated EKF),
// judge the update, extend the map, and fill the result in the gravity-aligned world frame.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <thread>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "lio_ppf_impl.hpp"
#include "ppf_core/lio/deskew.hpp"
#include "ppf_core/lio/so3.hpp"

namespace ppf {

ScanResult LioPpf::Impl::ProcessOne(QueuedScan& q) {
  const auto t_total = Clock::now();
  ScanResult r;
  r.input_id = q.id;
  const DecodedScan& scan = q.scan;
  r.stamp_s = scan.t_end;
  r.scan_begin_s = scan.t_begin;
  r.input_points = scan.input_points;
  r.dropped_nan = scan.dropped_nan;
  r.points_bad_time = scan.dropped_bad_time;
  r.map_size = map.size();
  // The moving-start initialization registers its scans as LiDAR-only does.
  const bool lidar = lidar_only || moving_init || fallback_scan;
  r.lidar_only = lidar_only || late_imu;
  if (!AcceptScan(scan, lidar, &r)) return r;
  if (clock_offset) {
    r.imu_clock_offset_s = clock_offset_s;
    std::ostringstream os;
    os << "IMU clock " << clock_offset_s << " s behind the LiDAR's: IMU not used";
    Append(&r.reason, os.str());
  }
  if (fallback_scan) {
    SeedFallback();
    fallback_dt = scan.t_end - state.stamp_s;
    r.imu_lost = true;
    Append(&r.reason, "IMU lost: registered LiDAR-only");
  } else if (imu_lost) {
    ResumeLio(&r);
  }
  Append(&r.reason, scan.note);

  std::vector<TimedPoint> pts;
  Preprocess(q, &pts, &r);

  // Propagate to the scan end and de-skew the downsampled points.
  auto t0 = Clock::now();
  PoseTrace trace;
  const double t_end = Propagate(scan, lidar, &trace, &r);
  Deskew(scan, pts, trace, t_end);
  if (!lidar) CorrectSaturatedTurn(scan, pts, t_end, &r);
  if (!lidar) CorrectGapTurn(scan, pts, t_end, &r);
  r.timings.deskew = MsSince(t0);
  last_scan_end = t_end;
  r.stamp_s = t_end;
  // A re-localized sweep's own gyro samples (GyroTraceToEnd), before they are trimmed below;
  // only those after the gap: one from before it would be interpolated across it.
  sweep_imu.clear();
  if (Relocating() && imu_back) {
    for (const ImuSample& s : imu) {
      if (s.stamp_s >= imu_back_stamp_s) sweep_imu.push_back(s);
    }
  }
  // Keep one sample at or before the state time for the next interpolation (the moving-start
  // initialization keeps all: it preintegrates from its first scan).
  while (!moving_init && imu.size() > 2 && imu[1].stamp_s <= state.stamp_s) imu.pop_front();

  PrepareFrame(t_end);

  if (!map_initialized) {
    StartMap(lidar, t_end, &r);
    r.timings.total = MsSince(t_total) + q.decode_ms;
    return r;
  }

  CoarseAlignment coarse;
  if (lidar) {
    t0 = Clock::now();
    coarse = AlignGuesses(t_end);
    RedeskewLidarOnly(scan, pts, t_end);
    if (Relocating()) EstimateScanVelocity(scan, pts, t_end);
    r.timings.guesses = MsSince(t0);
  }
  SplitScan(lidar, &r);
  Eigen::Isometry3d T_world_lidar;
  const IekfReport rep = Register(scan, pts, t_end, lidar, &T_world_lidar, &r);
  SetUpdateStatus(rep, lidar, &r);
  if (lidar) FinishLidarOnly(coarse, t_end, &r);
  if (Relocating()) ReportRelocalization(&r);
  r.pose_valid = true;

  ExtendMap(rep, T_world_lidar, &r);
  r.map_size = map.size();
  FillState(&r);
  r.timings.total = MsSince(t_total) + q.decode_ms;
  return r;
}

// False for a scan the filter cannot take yet, or one that goes back in time (it resets the
// filter); r is then the scan's whole result.
bool LioPpf::Impl::AcceptScan(const DecodedScan& scan, bool lidar, ScanResult* r) {
  if (!initialized && !moving_init) {
    r->status = Status::kInitializing;
    r->reason = init.reason().empty() ? "waiting for IMU data" : init.reason();
    return false;
  }
  if (!lidar && scan.t_end <= state.stamp_s && !map_initialized) {
    r->status = Status::kInitializing;
    r->reason = "scan ends before IMU initialization finished";
    return false;
  }
  if (scan.t_end < last_scan_end - 1e-6) {
    std::ostringstream os;
    os << "scan time went backwards by " << last_scan_end - scan.t_end << " s";
    ResetFilter("");
    Log(LogLevel::kWarn, "reset: " + os.str());
    r->status = Status::kReset;
    r->reason = os.str();
    return false;
  }
  return true;
}

// Preprocess: stride and range filter plus the voxel grid, on the raw scan; each kept point
// carries the mean time of its voxel (preprocess.hpp: why this comes before de-skew).
void LioPpf::Impl::Preprocess(const QueuedScan& q, std::vector<TimedPoint>* pts, ScanResult* r) {
  const DecodedScan& scan = q.scan;
  auto t0 = Clock::now();
  PreprocessOptions pre;
  pre.min_range = config.preprocess.min_range;
  pre.max_range = config.preprocess.max_range;
  pre.point_stride = config.preprocess.point_stride;
  pre.voxel_size = config.preprocess.scan_voxel_size;
  pre.num_threads = config.num_threads;
  const PreprocessStats pre_stats = downsampler.Run(scan.points, scan.t_begin, pre, pts);
  r->valid_points = pre_stats.valid_points;
  r->downsampled_points = pre_stats.downsampled_points;
  r->timings.preprocess = q.decode_ms;
  r->timings.downsample = MsSince(t0);
}

// The state at the scan end (t_end, returned) and the pose trace over the scan, from the IMU or
// from the LiDAR-only prediction; IMU gaps bridged before t_end widen the covariance.
double LioPpf::Impl::Propagate(const DecodedScan& scan, bool lidar, PoseTrace* trace,
                               ScanResult* r) {
  if (lidar && !map_initialized) StartLidarOnly(scan.t_end);
  const double t_end = std::max(scan.t_end, state.stamp_s);
  if (lidar) {
    PredictConstantVelocity(t_end, trace);
    // Not from samples held across a stalled IMU stream: the model's turn is better then.
    if (moving_init && motion.has_pose() && last_imu_stamp >= t_end - config.imu.max_gap_s &&
        !(late_imu && motion.stamp() < late_imu_from_s)) {
      PredictGyro(t_end, trace);
    }
  } else {
    std::vector<ImuSample> samples(imu.begin(), imu.end());
    // Without a full scale no reading is saturated: nothing to keep for CorrectSaturatedTurn.
    if (config.imu.noise.gyro_range > 0.0) saturation_start = state;
    gap_from_s = gap_to_s = 0.0;
    if (!bridged_gaps.empty() && bridged_gaps.front().begin_s < t_end) {
      const BridgedGap& gap = bridged_gaps.front();
      gap_from_s = std::max(state.stamp_s, gap.begin_s);
      gap_to_s = std::min(t_end, gap.begin_s + gap.length_s);
      gap_start = state;
      gap_samples = samples;
    }
    PropagateImu(samples, t_end, acc_scale, config.imu.noise, &state, trace, &saturation);
    r->gyro_saturated_s = saturation.seconds;
    if (saturation.seconds > 0.0) saturation_samples = samples;
    for (const ImuSample& s : samples) {
      if (s.stamp_s > t_end && s.stamp_s != samples.front().stamp_s) break;
      gyro_at_scan_end = s.angular_velocity;
    }
  }
  if (!lidar && t_end - last_imu_stamp > 0.02) {
    std::ostringstream os;
    os << "IMU extrapolated by " << t_end - last_imu_stamp << " s (last sample held)";
    Append(&r->reason, os.str());
  }
  // Each scan propagated across part of a bridged gap widens for that part: widened all at once,
  // the first scan would take the whole gap's uncertainty for the few milliseconds it crossed,
  // and the scans inside the gap none.
  double bridged_s = 0.0;  // not imu_gap_s: the scan LIO resumes with has that too (ResumeLio)
  while (!bridged_gaps.empty() && bridged_gaps.front().begin_s < t_end) {
    BridgedGap& gap = bridged_gaps.front();
    if (gap.widened_s == 0.0) {
      r->imu_gap_s = std::max(r->imu_gap_s, gap.length_s);
      bridged_s = std::max(bridged_s, gap.length_s);
    }
    const double crossed = std::min(t_end - gap.begin_s, gap.length_s);
    if (crossed > gap.widened_s) {
      WidenForGap(gap.widened_s, crossed);
      gap.widened_s = crossed;
    }
    if (crossed < gap.length_s) break;
    bridged_gaps.pop_front();
  }
  if (bridged_s > 0.0) {
    std::ostringstream os;
    os << "IMU gap of " << bridged_s << " s bridged";
    Append(&r->reason, os.str());
  }
  return t_end;
}

void LioPpf::Impl::Deskew(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                          const PoseTrace& trace, double t_end) {
  frame = ScanFrame();
  deskew_trace = trace;
  if (scan.has_time_field || scan.times_estimated) {
    DeskewToEnd(pts, trace, t_end, config.extrinsic.T_imu_lidar, &frame.points_lidar,
                config.num_threads);
  } else {
    frame.points_lidar.reserve(pts.size());
    for (const TimedPoint& tp : pts) frame.points_lidar.push_back(tp.p);
  }
}

// A sample of the de-skewed frame on the kNN map, for the scan alone.
ScanFrame LioPpf::Impl::ScanAloneSample() {
  frame.map = &map;
  frame.T_imu_lidar = config.extrinsic.T_imu_lidar;
  return SampleFrame(frame, config.consistency.fit_points);
}

// The pose a few Gauss-Newton steps of the scan alone on the map (wide gate, no prior) reach
// from the predicted one.
Eigen::Isometry3d LioPpf::Impl::AlignScanAlone(const ScanFrame& sample, int steps) const {
  Eigen::Isometry3d T = state.T_world_imu() * config.extrinsic.T_imu_lidar;
  for (int k = 0; k < steps; ++k) {
    const PoseProbe p = ProbePose(sample, T, config.lidar_only, config.knn, config.iekf,
                                  config.lidar_only.coarse_max_residual);
    if (p.step_rot.norm() < 1e-4 && p.step_pos.norm() < 1e-3) break;
    T.linear() = NormalizeRotation(SO3Exp(p.step_rot) * T.linear());
    T.translation() += p.step_pos;
  }
  return T;
}

// The turn (world frame, rad) the scan alone makes of the predicted pose: what the scan says the
// prediction missed.
Eigen::Vector3d LioPpf::Impl::ScanAloneTurn(int steps) {
  const Eigen::Matrix3d R_predicted = (state.T_world_imu() * config.extrinsic.T_imu_lidar).linear();
  return SO3Log(AlignScanAlone(ScanAloneSample(), steps).linear() * R_predicted.transpose());
}

// A gyro axis read at saturation while predicting this scan: the turn beyond the reading is
// unknown, and the scan was de-skewed without it, smeared by as much as it turned. The scan's
// end pose cannot show it: registered as it was de-skewed, the smeared points settle at a
// compromise pose that fits them nearly as well as the right one would fit the right points. Their
// smear shows it: de-skewed with the right rate beyond the reading, walls seen early line up with
// those seen late. So the rate beyond each saturated reading (one per axis and sign, constant over
// the scan, 0 to the reading itself) is searched for the de-skew the map fits best (a few
// Gauss-Newton steps of the scan alone on the map for each, wide gate, no prior; the least rate
// within a few points of the best fit, as a flat fit says nothing), and propagation and de-skew run
// with it. The rotation covariance keeps its widening: the update still decides.
void LioPpf::Impl::CorrectSaturatedTurn(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                                        double t_end, ScanResult* r) {
  if (!(saturation.seconds > 0.0) || !map_initialized || r->imu_gap_s > 0.0) return;
  constexpr int kGrid = 4;   // coarse rates per saturated axis: reading * k / kGrid, k = 0..kGrid
  constexpr int kSteps = 4;  // Gauss-Newton steps of the scan alone per rate
  constexpr double kFlat = 0.005;  // share of the covered points within which fits are equal
  Eigen::Matrix<double, 6, 1> excess = Eigen::Matrix<double, 6, 1>::Zero();
  // Propagation and de-skew with `e` beyond the readings.
  auto deskew = [&](const Eigen::Matrix<double, 6, 1>& e) {
    std::vector<ImuSample> samples = saturation_samples;
    AddUnmeasuredRate(e, config.imu.noise.gyro_range, &samples);
    state = saturation_start;
    PoseTrace trace;
    GyroSaturation again;
    PropagateImu(samples, t_end, acc_scale, config.imu.noise, &state, &trace, &again);
    Deskew(scan, pts, trace, t_end);
  };
  // The fit of the scan so de-skewed, at the pose the scan alone settles at: the points near the
  // kNN map within the fit gate of its planes, and in kPpf also those near the skeleton's patches.
  auto deskew_and_score = [&](const Eigen::Matrix<double, 6, 1>& e) {
    deskew(e);
    const ScanFrame sample = ScanAloneSample();
    const Eigen::Isometry3d T = AlignScanAlone(sample, kSteps);
    FitScore score = ScoreFit(sample, T, config.lidar_only, config.knn);
    // kPpf: the kNN map holds the scattered points only; the skeleton's surfaces are in the
    // tracker's patch map, where each sampled point meets the nearest patch of its cell.
    if (tracker) {
      const PlanePatchMap& patches = tracker->patch_map();
      for (const Eigen::Vector3f& q : sample.points_lidar) {
        const Eigen::Vector3d p = T * q.cast<double>();
        const PlanePatchMap::Patch* patch = patches.Find(p, Eigen::Vector3d::UnitZ(), 0.0);
        if (patch == nullptr) continue;
        ++score.covered;
        if (patch->plane.Distance(p) < config.lidar_only.fit_gate) ++score.inliers;
      }
    }
    return score;
  };
  for (int c = 0; c < 6; ++c) {
    const double reading = saturation.reading(c);
    if (saturation.turn_per_rate.col(c).norm() < 1e-6 || !(reading > 0.0)) continue;
    auto score_at = [&](double x) {
      Eigen::Matrix<double, 6, 1> e = excess;
      e(c) = x;
      return deskew_and_score(e);
    };
    // Coarse: the least rate within kFlat of the best fit on a grid.
    std::vector<FitScore> scores;
    size_t most = 0;
    for (int k = 0; k <= kGrid; ++k) {
      scores.push_back(score_at(reading * k / kGrid));
      most = std::max(most, scores.back().inliers);
    }
    const double flat = std::max(2.0, kFlat * static_cast<double>(scores.front().covered));
    int chosen = 0;
    while (static_cast<double>(scores[chosen].inliers) < static_cast<double>(most) - flat) ++chosen;
    double x = reading * chosen / kGrid;
    size_t inliers = scores[chosen].inliers;
    // Fine: halved steps either side, moving only to a strictly better fit.
    for (double h = 0.5 * reading / kGrid; h > 0.2 * reading / kGrid; h *= 0.5) {
      for (double candidate : {x - h, x + h}) {
        if (candidate < 0.0 || candidate > reading) continue;
        const FitScore f = score_at(candidate);
        if (f.inliers > inliers) {
          inliers = f.inliers;
          x = candidate;
          break;
        }
      }
    }
    excess(c) = x;
  }
  deskew(excess);
  std::ostringstream os;
  os << "gyro saturated for " << saturation.seconds << " s";
  if (!excess.isZero()) {
    os << ": the scan's smear showed up to " << excess.maxCoeff() << " rad/s beyond the reading";
  }
  Append(&r->reason, os.str());
}

// Propagation from the gap's start again, with a body rate added to the samples over the part
// of the gap this scan crossed, and the de-skew from it; the covariance stays the prediction's.
void LioPpf::Impl::RepropagateGap(const Eigen::Vector3d& rate, const DecodedScan& scan,
                                  const std::vector<TimedPoint>& pts, double t_end) {
  // The samples with the rate added over [gap_from_s, gap_to_s]: copies at both ends carry it,
  // so that the interpolation outside that part stays the samples' own.
  auto shifted = [&](ImuSample s) {
    s.angular_velocity += rate;
    return s;
  };
  std::vector<ImuSample> samples;
  samples.reserve(gap_samples.size() + 2);
  for (const ImuSample& s : gap_samples) {
    if (s.stamp_s <= gap_from_s) samples.push_back(s);
  }
  samples.push_back(shifted(InterpolateImu(gap_samples, gap_from_s)));
  for (const ImuSample& s : gap_samples) {
    if (s.stamp_s > gap_from_s && s.stamp_s < gap_to_s) samples.push_back(shifted(s));
  }
  samples.push_back(shifted(InterpolateImu(gap_samples, gap_to_s)));
  for (const ImuSample& s : gap_samples) {
    if (s.stamp_s >= gap_to_s) samples.push_back(s);
  }
  const StateCov P = state.P;
  state = gap_start;
  PoseTrace trace;
  GyroSaturation unused;
  PropagateImu(samples, t_end, acc_scale, config.imu.noise, &state, &trace, &unused);
  state.P = P;
  Deskew(scan, pts, trace, t_end);
}

// A scan propagated across part of a bridged gap: the integration assumed the turn rate went
// linearly from the sample before the gap to the one after, which misses whatever the body did
// in between (a pitch oscillating on the suspension), and the scan was de-skewed with it. The
// scan alone (a few Gauss-Newton steps on the map, wide gate, no prior) measures the turn at
// the scan end (ScanAloneTurn); read as a constant rate beyond the interpolated one over
// the part of the gap this scan crossed (the previous scan's update fixed the pose before it),
// it goes into the samples over that part, and propagation and de-skew run again. The
// covariance keeps the gap's widening: the update still decides. Not with a skeleton tracker
// (kPpf): its kNN map holds the scattered points only, against which the whole scan's turn is
// no better known than the gap left it; kPpf takes the update's turn instead (RedeskewGapTurn;
// docs/decisions.md, "IMU gap bridging").
void LioPpf::Impl::CorrectGapTurn(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                                  double t_end, ScanResult* r) {
  if (!(gap_to_s > gap_from_s) || !map_initialized || saturation.seconds > 0.0 || tracker) return;
  constexpr int kSteps = 4;
  constexpr double kMinTurnRad = 0.05 * M_PI / 180.0;
  const Eigen::Vector3d turn = ScanAloneTurn(kSteps);
  if (turn.norm() < kMinTurnRad) return;
  // The scan alone is not exact either: its turn is taken in the proportion the two
  // uncertainties give, the gap's unmeasured rate over the crossed part against the scan-alone
  // steps of the recent scans (the consistency check's, per axis). A scan that crossed a few
  // milliseconds of the gap takes little of it.
  const double crossed = gap_to_s - gap_from_s;
  const double var_gap = std::pow(config.imu.gap_gyro_std * crossed, 2);
  double var_scan = 0.0;
  for (double s : lio_steps_rot) var_scan += s * s / 3.0;
  if (!lio_steps_rot.empty()) var_scan /= static_cast<double>(lio_steps_rot.size());
  const double share = var_gap / (var_gap + var_scan);
  // The body frame's rate that turns the prediction by that share over the crossed part.
  const Eigen::Vector3d rate = state.R_world_imu.transpose() * turn * (share / crossed);
  RepropagateGap(rate, scan, pts, t_end);
  std::ostringstream os;
  os << "the scan alone turns the prediction across the gap by " << turn.norm() * 180.0 / M_PI
     << " deg: de-skewed again with " << share * 100.0 << " % of it";
  Append(&r->reason, os.str());
}

// The map's first scan, inserted at the predicted pose: it defines the map frame.
void LioPpf::Impl::StartMap(bool lidar, double t_end, ScanResult* r) {
  const auto t0 = Clock::now();
  InsertScattered(frame, frame.T_world_lidar_predicted, r);
  map_initialized = !frame.points_lidar.empty();
  map_init_stamp_s = t_end;
  if (lidar && map_initialized) motion.Update(state.T_world_imu(), t_end);
  if (lidar_only && map_initialized) {
    Append(&r->reason, "LiDAR-only (no IMU): world frame = this scan's LiDAR frame");
  }
  r->timings.map_insert = MsSince(t0);
  r->status = map_initialized ? Status::kOk : Status::kInitializing;
  Append(&r->reason, map_initialized ? "map initialized" : "empty first scan");
  r->pose_valid = true;
  r->scattered_points = frame.points_lidar.size();
  FillState(r);
  r->map_size = map.size();
}

// The split into skeleton and scattered points (kPpf) and the count of each label. A scan
// re-localized after a long gap is split too: its guesses were aligned on the kNN map (and its
// velocity probe on the patches), so its prediction is the re-localized pose, and the skeleton's
// rows on the walls and the ground pin what the scattered points alone leave loose (its height).
void LioPpf::Impl::SplitScan(bool lidar, ScanResult* r) {
  if (tracker) {
    const auto t0 = Clock::now();
    if (PrefetchBesideSplit(lidar)) {
      // The pre-fit runs on one thread; the other searches the kNN neighbours of the scan's
      // points at the predicted pose meanwhile, which the update's first iteration then reuses
      // for the points the split leaves scattered (KnnResidualProvider::Prefetch). The update
      // starts from that pose, so its rows are the ones it would have searched itself.
      std::vector<Plane> guessed;
      for (const PlaneGuess& g : tracker->window().GuessesInFrame(frame.T_world_lidar_predicted)) {
        guessed.push_back(g.plane);
      }
      const PpfConfig& c = tracker->config();
      const double band = c.delta * std::max(1.0, c.semi_band_factor);
      std::atomic<bool> split_done{false};
      // A thread of its own rather than an OpenMP team: its start and join are synchronisation
      // the ThreadSanitizer stage sees (the OpenMP runtime's it does not), and the pre-fit keeps
      // the loops it would run on a team of its own (none for the scans let through here).
      std::thread prefetch(
          [&] { knn->Prefetch(frame, frame.T_world_lidar_predicted, guessed, band, split_done); });
      struct JoinOnExit {
        std::atomic<bool>* done;
        std::thread* thread;
        ~JoinOnExit() {
          done->store(true, std::memory_order_release);
          thread->join();
        }
      } join{&split_done, &prefetch};
      tracker->Split(&frame);
    } else {
      tracker->Split(&frame);
    }
    frame.labels.resize(frame.points_lidar.size(), PointLabel::kScattered);
    r->timings.ppf = MsSince(t0);
  }
  CountLabels(r);
}

// Whether this scan's pre-fit gets the kNN prefetch beside it: an IMU-predicted scan (a
// LiDAR-only one is registered from its guesses, not from the predicted pose) on two threads or
// more, a map to search, and a scan small enough that the pre-fit's RANSAC scores its batches
// on one thread (ransac.cpp's kParallelWork over a batch of 16: above it, a team of two beside
// the prefetch would put three threads on the two cores).
bool LioPpf::Impl::PrefetchBesideSplit(bool lidar) const {
#ifdef _OPENMP
  const int threads = config.num_threads > 0 ? config.num_threads : omp_get_max_threads();
#else
  const int threads = 1;
#endif
  return tracker != nullptr && !lidar && threads >= 2 && map.size() > 0 &&
         frame.points_lidar.size() <= 16384;
}

// The de-skewed frame made ready for the split and the update, all points scattered so far.
void LioPpf::Impl::PrepareFrame(double t_end) {
  frame.stamp_s = t_end;
  frame.labels.assign(frame.points_lidar.size(), PointLabel::kScattered);
  frame.T_imu_lidar = config.extrinsic.T_imu_lidar;
  frame.T_world_lidar_predicted = state.T_world_imu() * config.extrinsic.T_imu_lidar;
  frame.map = &map;
  frame.residual_max_range = config.iekf.residual_max_range;
}

void LioPpf::Impl::CountLabels(ScanResult* r) const {
  r->skeleton_points = r->scattered_points = r->discarded_points = 0;
  for (PointLabel l : frame.labels) {
    if (l == PointLabel::kSkeleton)
      ++r->skeleton_points;
    else if (l == PointLabel::kScattered)
      ++r->scattered_points;
    else
      ++r->discarded_points;
  }
}

// The first scan of an IMU loss: the constant-velocity model continues the filter's own motion
// (its velocity and the last turn rate), and the covariance of what LiDAR-only leaves unobserved
// (biases, gravity) is kept for the resume.
void LioPpf::Impl::SeedFallback() {
  if (fallback_seeded) return;
  fallback_seeded = true;
  const Eigen::Isometry3d T_world_imu = state.T_world_imu();
  motion.Seed(T_world_imu, state.stamp_s, gyro_at_scan_end - state.gyro_bias,
              T_world_imu.linear().transpose() * state.v_world);
  P_before_loss = state.P;
  recent_fits.clear();
}

// Back to LIO after an IMU loss: propagation starts from the last LiDAR-only pose with the
// velocity of the LiDAR-only pose history (the path's tangent at that pose: after scans dropped
// on a bend the last interval is long, and its chord points half the bend off); biases and
// gravity keep their estimates and covariance. No reset and no jump: the pose is the registered
// one.
void LioPpf::Impl::ResumeLio(ScanResult* r) {
  // What a constant twist over the last interval would make of the velocity at the pose, versus
  // the interval's chord: their difference is how far the chord can be off (on a bend after
  // scans were dropped, half the bend); the filter is told so and corrects it from the scans.
  Eigen::Vector3d v_spread = Eigen::Vector3d::Zero();
  if (motion.has_twist()) {
    state.v_world = motion.TangentVelocityWorld();
    v_spread = state.v_world - motion.velocity_world();
  }
  // A re-localized scan measured its own velocity: the chord over the gap is only its mean.
  if (relocalized_since_loss && has_scan_velocity) {
    state.v_world = scan_velocity_world;
    v_spread.setZero();
  }
  has_scan_velocity = false;
  // The pose is as good as the last LiDAR-only update made it; the velocity is the difference
  // of two such poses over the scan interval. Neither is correlated with the rest any more.
  const Eigen::Matrix3d P_rot = state.P.block<3, 3>(kRot, kRot);
  Eigen::Matrix3d P_pos = state.P.block<3, 3>(kPos, kPos);
  // A re-localized pose is only as good as its guesses let it be: the update's covariance counts
  // the rows as independent and claims centimetres along a street whose walls leave it free.
  // Trusted so, the filter reads the remaining offset as velocity and drifts on with it; with the
  // LiDAR-only prior's uncertainty back on the position it corrects the position instead.
  if (relocalized_since_loss) {
    P_pos +=
        config.imu.loss_prior_pos_std * config.imu.loss_prior_pos_std * Eigen::Matrix3d::Identity();
  }
  relocalized_since_loss = false;
  const double dt = std::max(fallback_dt, 1e-3);
  state.P = P_before_loss;
  for (int i : {static_cast<int>(kRot), static_cast<int>(kPos), static_cast<int>(kVel)}) {
    state.P.block<3, kStateDim>(i, 0).setZero();
    state.P.block<kStateDim, 3>(0, i).setZero();
  }
  state.P.block<3, 3>(kRot, kRot) = P_rot;
  state.P.block<3, 3>(kPos, kPos) = P_pos;
  // The chord is the mean velocity over the gap, not the velocity at its end: what an unmeasured
  // acceleration makes of it over the gap (as for a bridged gap, WidenForGap) is unknown too.
  // Horizontally only: a vertical velocity error is what a tilt makes of gravity, and the
  // update would explain one by the other.
  const double v_gap = config.imu.gap_acc_std * imu_loss_gap_s;
  const Eigen::Vector3d up = state.gravity_world.norm() > 1e-6 ? state.gravity_world.normalized()
                                                               : Eigen::Vector3d::UnitZ();
  state.P.block<3, 3>(kVel, kVel) =
      2.0 * P_pos / (dt * dt) + v_spread.squaredNorm() * Eigen::Matrix3d::Identity() +
      v_gap * v_gap * (Eigen::Matrix3d::Identity() - up * up.transpose());
  // Samples from before the gap would be interpolated across it.
  while (!imu.empty() && imu.front().stamp_s < imu_back_stamp_s) imu.pop_front();
  imu_lost = false;
  imu_back = false;
  fallback_seeded = false;
  r->imu_gap_s = imu_loss_gap_s;
  r->lio_resumed = true;
  std::ostringstream os;
  os << "IMU back: LIO resumed after " << imu_loss_gap_s << " s without IMU (LiDAR-only meanwhile)";
  Append(&r->reason, os.str());
  Log(LogLevel::kInfo, os.str());
}

// The iterated EKF with this scan's residual providers. The updated pose (T_world_lidar_out) is
// the one at which the splitter and the providers close the scan.
IekfReport LioPpf::Impl::Register(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                                  double t_end, bool lidar, Eigen::Isometry3d* T_world_lidar_out,
                                  ScanResult* r) {
  std::vector<ResidualProvider*> providers;
  // The kNN rows keep their neighbours across iterations (knn.search_again_distance) only when
  // the prediction is that near: the update moves the pose by about the prior's uncertainty, which
  // after a gap, a loss or a re-localization is decimetres for a few scans.
  const double pos_std = std::sqrt(state.P.block<3, 3>(kPos, kPos).diagonal().maxCoeff());
  const bool keep = !lidar && pos_std < config.knn.search_again_distance;
  knn->SetKeepNeighbours(keep);
  providers.push_back(knn.get());
  const bool skeleton = tracker != nullptr;
  // The skeleton rows keep their patch lookups on the same terms.
  if (skeleton) tracker->SetKeepDistance(keep ? config.knn.search_again_distance : 0.0);
  if (skeleton) providers.push_back(tracker->residual_provider().get());  // PPF: skeleton rows
  for (ResidualProvider* p : providers) p->BeginScan(frame);
  IekfOptions iekf = config.iekf;
  if (t_end - map_init_stamp_s < iekf.refined_gate_after_s) iekf.refined_gate = 0.0;
  // A re-localized scan starts from a coarse alignment (decimetres and a degree off), not from an
  // IMU-propagated pose: the few iterations that suffice for the latter stopped its update half
  // way, a pitch error among what was left, and the scans after it extend the map from there. It
  // runs until the same convergence test holds; the cap only bounds one scan's time.
  constexpr int kRelocalizedMaxIterations = 30;
  if (Relocating()) iekf.max_iterations = std::max(iekf.max_iterations, kRelocalizedMaxIterations);
  const NavState predicted = state;
  contradicted = false;
  IekfReport rep = IekfUpdate(iekf, config.extrinsic.T_imu_lidar, providers, &state);
  if (!lidar && skeleton) {
    rep = RedeskewGapTurn(scan, pts, t_end, predicted, iekf, providers, rep, r);
  }
  if (!lidar) rep = RedeskewVelocity(scan, pts, t_end, predicted, iekf, providers, rep, r);
  // The LiDAR-only scans were aligned from guesses already; the IMU's prediction is checked here.
  if (!lidar && config.consistency.check) {
    const auto t0 = Clock::now();
    rep = OverruleIfInconsistent(predicted, iekf, providers, rep, r);
    r->timings.guesses = MsSince(t0);
  }
  r->correction_rot_deg =
      SO3Log(predicted.R_world_imu.transpose() * state.R_world_imu).norm() * 180.0 / M_PI;
  r->correction_pos_m = (state.p_world_imu - predicted.p_world_imu).norm();
  r->timings.residuals = rep.residuals_ms;
  r->timings.update = rep.update_ms;
  r->iterations = rep.iterations;
  r->converged = rep.converged;
  r->eig_rotation = rep.eig_rotation;
  r->eig_translation = rep.eig_translation;
  for (size_t i = 0; i < rep.rows_per_provider.size(); ++i) {
    if (i == 0)
      r->knn_residuals = static_cast<size_t>(rep.rows_per_provider[i]);
    else
      r->skeleton_residuals += static_cast<size_t>(rep.rows_per_provider[i]);
  }
  const Eigen::Isometry3d T_world_lidar = state.T_world_imu() * config.extrinsic.T_imu_lidar;
  if (skeleton) {
    const auto t0 = Clock::now();
    // A re-localized pose extends no map until LIO confirms it (ExtendMap).
    tracker->Finish(frame, T_world_lidar, !Relocating());
    r->skeleton_planes = tracker->window().planes();  // map frame until FillState
    r->skeleton_patches = tracker->patch_map().num_patches();
    r->timings.ppf += MsSince(t0);
  }
  for (ResidualProvider* p : providers) p->EndScan(T_world_lidar);
  *T_world_lidar_out = T_world_lidar;
  return rep;
}

// The frame was de-skewed again (RedeskewGapTurn, RedeskewVelocity): kPpf splits it again, the
// split following the tracked planes from the updated pose, and the update runs again from the
// prediction and its covariance.
IekfReport LioPpf::Impl::UpdateRedeskewed(double t_end, const NavState& updated,
                                          const NavState& predicted, const IekfOptions& iekf,
                                          const std::vector<ResidualProvider*>& providers) {
  PrepareFrame(t_end);
  if (tracker) {
    frame.T_world_lidar_predicted = updated.T_world_imu() * config.extrinsic.T_imu_lidar;
    tracker->Split(&frame);
    frame.labels.resize(frame.points_lidar.size(), PointLabel::kScattered);
  }
  state = predicted;
  frame.T_world_lidar_predicted = state.T_world_imu() * config.extrinsic.T_imu_lidar;
  for (ResidualProvider* p : providers) p->BeginScan(frame);
  return IekfUpdate(iekf, config.extrinsic.T_imu_lidar, providers, &state);
}

// kPpf's answer to a scan propagated across part of a bridged IMU gap (kNN has CorrectGapTurn
// before the update): the interpolation across the gap missed what the body turned there, and the
// scan was de-skewed without it. The update's own rotation correction, read as a constant rate
// over the crossed part, de-skews the scan again, and the update runs again from the same
// prediction and covariance on the re-split scan: the de-skew is linearised at the updated pose
// while the prior stays the IMU's, so the LiDAR is not counted twice. A few passes reach the fixed
// point. The scan alone is no measure here: kPpf's kNN map holds only the scattered points.
IekfReport LioPpf::Impl::RedeskewGapTurn(const DecodedScan& scan,
                                         const std::vector<TimedPoint>& pts, double t_end,
                                         const NavState& predicted, const IekfOptions& iekf,
                                         const std::vector<ResidualProvider*>& providers,
                                         const IekfReport& rep, ScanResult* r) {
  if (!(gap_to_s > gap_from_s) || saturation.seconds > 0.0) return rep;
  constexpr int kPasses = 3;
  constexpr double kMinTurnRad = 0.02 * M_PI / 180.0;
  constexpr double kSettledRad = 0.01 * M_PI / 180.0;
  const auto t0 = Clock::now();
  const double crossed = gap_to_s - gap_from_s;
  IekfReport out = rep;
  Eigen::Vector3d used = Eigen::Vector3d::Zero();
  int passes = 0;
  for (; passes < kPasses; ++passes) {
    const Eigen::Vector3d turn = SO3Log(state.R_world_imu * predicted.R_world_imu.transpose());
    if (turn.norm() < kMinTurnRad || (passes > 0 && (turn - used).norm() < kSettledRad)) break;
    used = turn;
    const Eigen::Vector3d rate = predicted.R_world_imu.transpose() * turn / crossed;
    const NavState updated = state;
    state = predicted;
    RepropagateGap(rate, scan, pts, t_end);
    out = UpdateRedeskewed(t_end, updated, predicted, iekf, providers);
  }
  if (passes == 0) return rep;
  CountLabels(r);
  r->timings.ppf += MsSince(t0);
  std::ostringstream os;
  os << "the update turns the prediction across the gap by " << used.norm() * 180.0 / M_PI
     << " deg: de-skewed again with it (" << passes << (passes == 1 ? " pass)" : " passes)");
  Append(&r->reason, os.str());
  return out;
}

// The scan was de-skewed with the predicted velocity. Where the update corrects it by more than
// a sweep can ignore (the scans after a re-localization, whose velocity one sweep's smear gave,
// or after a bridged gap), the points were displaced along the correction by dv (t_end - t), the
// earliest by the whole sweep's worth: registered and inserted into the map like that, the first
// resumed scans leave their smear in the map ahead, where the old map has little, and the scans
// after them register on it. The update's velocity correction, constant over the sweep, de-skews
// the scan again (and kPpf splits it again), and the update runs again from the same prediction
// and covariance: the de-skew is linearised at the updated velocity while the prior stays the
// IMU's, so the LiDAR is not counted twice. A few passes reach the fixed point. Below a centimetre
// over the sweep (every IMU-propagated scan of an undisturbed run) nothing is done.
IekfReport LioPpf::Impl::RedeskewVelocity(const DecodedScan& scan,
                                          const std::vector<TimedPoint>& pts, double t_end,
                                          const NavState& predicted, const IekfOptions& iekf,
                                          const std::vector<ResidualProvider*>& providers,
                                          const IekfReport& rep, ScanResult* r) {
  if (rep.skipped || !(scan.has_time_field || scan.times_estimated)) return rep;
  if (deskew_trace.knots.empty() || pts.empty()) return rep;
  constexpr int kPasses = 3;
  constexpr double kMinSmearM = 0.01;  // the correction's displacement over the sweep
  constexpr double kSettledM = 0.002;  // a pass that changes it by less is the last
  double t_first = t_end;
  for (const TimedPoint& tp : pts) t_first = std::min(t_first, tp.t);
  const double sweep = t_end - t_first;
  if (!(sweep > 0.0)) return rep;
  const auto t0 = Clock::now();
  const PoseTrace base = deskew_trace;
  IekfReport out = rep;
  Eigen::Vector3d used = Eigen::Vector3d::Zero();
  int passes = 0;
  for (; passes < kPasses; ++passes) {
    const Eigen::Vector3d dv = state.v_world - predicted.v_world;
    if (dv.norm() * sweep < kMinSmearM) break;
    if (passes > 0 && (dv - used).norm() * sweep < kSettledM) break;
    used = dv;
    // The trace with the velocity dv higher throughout and the same end pose.
    PoseTrace trace = base;
    for (ImuKnot& k : trace.knots) {
      k.p += dv * (k.t - t_end);
      k.v += dv;
    }
    const NavState updated = state;
    Deskew(scan, pts, trace, t_end);
    out = UpdateRedeskewed(t_end, updated, predicted, iekf, providers);
  }
  if (passes == 0) return rep;
  CountLabels(r);
  r->timings.deskew += MsSince(t0);
  std::ostringstream os;
  os << "the update corrects the predicted velocity by " << used.norm()
     << " m/s: de-skewed again with it (" << passes << (passes == 1 ? " pass)" : " passes)");
  Append(&r->reason, os.str());
  return out;
}

// Config::consistency: the posterior's fit against the recent scans'; far worse, guesses around
// it (and the prediction) are aligned coarsely, and a clearly better one re-anchors the
// prediction, from which the update runs again. The rows of a scan count too little, and are
// gated too narrowly, to move the state by what the IMU got wrong without knowing; the coarse
// alignment has neither limit, and the covariance is widened only along the correction it found,
// so a heading correction leaves roll and pitch with the IMU.
namespace {
constexpr double kTrustTiltRad = 1.0 * M_PI / 180.0;
// Fewer of the rows' points met the map than this: their share within the fit gate scatters by
// 0.05 or more from scan to scan, and a sample of the whole scan is searched instead.
constexpr size_t kMinAssociated = 100;
}  // namespace

IekfReport LioPpf::Impl::OverruleIfInconsistent(const NavState& predicted, const IekfOptions& iekf,
                                                const std::vector<ResidualProvider*>& providers,
                                                const IekfReport& rep, ScanResult* r) {
  const ConsistencyOptions& co = config.consistency;
  const Eigen::Isometry3d& T_il = config.extrinsic.T_imu_lidar;
  if (rep.skipped) return rep;
  const double wide = config.lidar_only.coarse_max_residual;
  // Every scan: the rows' own associations from the update's last iteration, at the posterior
  // (no search of the map); their fit and step are what the recent scans' baseline holds. Only a
  // scan that fails them searches a sample (below), to compare guesses on it. In kPpf the fit
  // counts the skeleton points against their patches beside the kNN rows: the kNN map holds the
  // scattered points only, whose share within the fit gate moves by a few hundredths whenever
  // the pre-fit moves points between the two sets. The step stays the kNN rows' (the bounds of
  // max_step_pos were set on it; with the skeleton rows it grew on a hand-held walk and set the
  // search off more often): docs/decisions.md, "Consistency check".
  auto associated_at = [&](const NavState& s, PoseProbe* out) {
    if (!knn->Associations(&associated)) return false;
    const size_t knn_points = associated.size();
    if (tracker) tracker->skeleton_provider().AppendAssociations(&associated);
    *out = ProbePoseAssociated(associated, s.T_world_imu() * T_il, config.lidar_only, config.iekf,
                               wide, knn_points);
    return out->score.covered >= kMinAssociated;
  };
  ScanFrame sample;
  auto probe_at = [&](const NavState& s) {
    if (sample.points_lidar.empty()) sample = SampleFrame(frame, co.fit_points);
    return ProbePose(sample, s.T_world_imu() * T_il, config.lidar_only, config.knn, config.iekf,
                     wide);
  };
  PoseProbe probe;
  const bool associated_probe = associated_at(state, &probe);
  if (!associated_probe) probe = probe_at(state);
  // Judged against the recent scans' scores of the same kind (fit_baseline.hpp says why).
  using Kind = FitBaseline::Kind;
  const Kind kind = associated_probe ? Kind::kAssociated : Kind::kSampled;
  // The scan-alone step judges the position only: a heading or tilt error of degrees shows in
  // the fit already, and on a fast hand-held walk the step's rotation scatters by a degree or two
  // (de-skew within the sweep; in kPpf a map of scattered points only), which would set it off
  // (docs/decisions.md, "Consistency check"). Beyond the bound and well beyond what the scan
  // alone said on the recent scans.
  const double usual_pos = 3.0 * lio_baseline.MedianStepPos(kind);
  auto too_far = [&](const PoseProbe& p) {
    const double pos = p.step_pos.norm();
    return pos > co.max_step_pos && pos > usual_pos;
  };
  const double fit = probe.score.fit;
  r->fit = fit;
  r->disagreement_rot_deg = probe.step_rot.norm() * 180.0 / M_PI;
  r->disagreement_pos_m = probe.step_pos.norm();
  auto remember = [this](Kind k, double f, const PoseProbe& p) {
    lio_baseline.Remember(k, f, p.step_pos.norm());
    lio_steps_rot.push_back(p.step_rot.norm());
    if (lio_steps_rot.size() > 10) lio_steps_rot.pop_front();
  };
  // No baseline of this kind yet (a young map fits unevenly; in kPpf the sampled kind comes only
  // with the scans whose scattered points meet the map too rarely).
  if (!lio_baseline.Ready(kind)) {
    remember(kind, fit, probe);
    return rep;
  }
  const double baseline = lio_baseline.MedianFit(kind);
  const bool poor_fit = fit < co.fit_ratio * baseline;
  // A step only its few or scattered rows make (in kPpf the scattered points alone, a hundred
  // on a hand-held walk) is no evidence: it must also stand out from its own scatter.
  const bool step_off =
      too_far(probe) && (co.min_step_sigmas <= 0.0 || probe.step_pos_sigmas > co.min_step_sigmas);
  if (!poor_fit && !step_off) {
    remember(kind, fit, probe);
    return rep;
  }

  r->consistency_search = poor_fit ? ConsistencySearch::kPoorFit : ConsistencySearch::kScanStep;
  // The guesses are compared on a sample of the whole scan, searched at each pose.
  const PoseProbe sampled = associated_probe ? probe_at(state) : probe;

  // Guesses: the update's pose, it moved by the scan's own step, the prediction, and the update's
  // pose turned about the vertical (the map frame's gravity) through the sensor.
  const Eigen::Isometry3d T_post = state.T_world_imu() * T_il;
  auto about_sensor = [&](const Eigen::Vector3d& rot, const Eigen::Vector3d& pos) {
    Eigen::Isometry3d d = Eigen::Isometry3d::Identity();
    d.linear() = SO3Exp(rot);
    d.translation() = T_post.translation() - d.linear() * T_post.translation() + pos;
    return d * T_post;
  };
  std::vector<MotionHypothesis> h;
  h.push_back({"update", T_post});
  h.push_back({"scan step", about_sensor(sampled.step_rot, sampled.step_pos)});
  h.push_back({"prediction", predicted.T_world_imu() * T_il});
  const Eigen::Vector3d up = -state.gravity_world.normalized();
  const double a = co.turn_deg * M_PI / 180.0;
  // The turns are for a heading the IMU got wrong by degrees, and that shows in the fit. A scan
  // that fits as well as the recent ones and only steps too far is off in position (or by the
  // fraction of a degree its own step holds, the "scan step" guess): four turned alignments
  // cannot win there and cost more than the rest of the scan. Where the IMU did not measure the
  // whole interval (a bridged gap, a saturated gyro) they stay, whatever the trigger.
  const bool turns = poor_fit || r->imu_gap_s > 0.0 || r->gyro_saturated_s > 0.0;
  if (turns && a > 0.0) {
    for (double k : {1.0, -1.0, 2.0, -2.0}) {
      std::ostringstream os;
      os << "turn " << (k > 0 ? "+" : "") << k * co.turn_deg << " deg";
      h.push_back({os.str(), about_sensor(up * (k * a), Eigen::Vector3d::Zero())});
    }
  }
  // After a bridged gap the IMU's integration across it may be off along the way by metres.
  if (r->imu_gap_s > 0.0) AddAlongTrackGuesses(T_post, state.v_world, r->imu_gap_s, &h);
  LidarOnlyOptions options = config.lidar_only;
  options.good_fit = 1.0;  // every guess: the winner is judged below, not by the first good fit
  const CoarseAlignment c = AlignHypotheses(frame, h, options, config.iekf, config.knn);
  r->guesses_tried = c.tried;
  r->motion_guess = c.name;
  std::ostringstream why;
  why.precision(2);
  why << std::fixed << "the map contradicts the prediction (";
  if (poor_fit) {
    why << "fit " << fit << " < " << co.fit_ratio << " x recent " << baseline;
  } else {
    why << "the scan alone moves it " << r->disagreement_pos_m << " m, " << std::setprecision(0)
        << probe.step_pos_sigmas << " sigma" << std::setprecision(2);
  }
  why << ")";

  // The prediction moved to the aligned pose, its velocity turned with it, and the covariance
  // widened by each correction along its own direction.
  // Roll and pitch stay the IMU's unless the aligned pose differs there by more than a scan's
  // own tilt can be off (kTrustTiltRad): the rows' shared errors tilt a LiDAR-only pose by a
  // fraction of a degree (iekf.hpp), which the filter must not adopt from one scan.
  NavState anchored = predicted;
  const Eigen::Isometry3d T_anchor = c.T_world_lidar * T_il.inverse();
  const Eigen::Vector3d d_world = SO3Log(T_anchor.linear() * predicted.R_world_imu.transpose());
  const Eigen::Vector3d d_yaw = d_world.dot(up) * up;
  const bool tilt_too = (d_world - d_yaw).norm() > kTrustTiltRad;
  const Eigen::Matrix3d dR = SO3Exp(tilt_too ? d_world : d_yaw);
  anchored.R_world_imu = NormalizeRotation(dR * predicted.R_world_imu);
  anchored.p_world_imu = T_anchor.translation();
  anchored.v_world = dR * predicted.v_world;
  const Eigen::Vector3d d_rot = SO3Log(predicted.R_world_imu.transpose() * anchored.R_world_imu);
  const Eigen::Vector3d d_pos = anchored.p_world_imu - predicted.p_world_imu;
  const Eigen::Vector3d d_vel = anchored.v_world - predicted.v_world;
  anchored.P.block<3, 3>(kRot, kRot) += d_rot * d_rot.transpose();
  anchored.P.block<3, 3>(kPos, kPos) += d_pos * d_pos.transpose();
  anchored.P.block<3, 3>(kVel, kVel) += d_vel * d_vel.transpose();
  frame.T_world_lidar_predicted = c.T_world_lidar;
  for (ResidualProvider* p : providers) p->BeginScan(frame);
  NavState s = anchored;
  const IekfReport rep2 = IekfUpdate(iekf, T_il, providers, &s);
  const PoseProbe probe2 = probe_at(s);
  const double fit2 = probe2.score.fit;
  const double fit1 = sampled.score.fit;
  const bool better =
      fit2 >= fit1 + co.min_gain || (fit2 >= fit1 && too_far(sampled) && !too_far(probe2));
  if (rep2.skipped || !better) {
    // Nothing fits clearly better: the update's pose stands, and the status says it may be off.
    why << "; no guess does better (best " << c.name << ", fit " << fit2 << "): pose kept";
    Append(&r->reason, why.str());
    contradicted = poor_fit;
    remember(kind, fit, probe);
    for (ResidualProvider* p : providers) p->BeginScan(frame);
    return rep;
  }
  state = s;
  r->fit = fit2;
  r->disagreement_rot_deg = probe2.step_rot.norm() * 180.0 / M_PI;
  r->disagreement_pos_m = probe2.step_pos.norm();
  r->overruled = true;
  why << "; LiDAR overruled it by " << d_rot.norm() * 180.0 / M_PI << " deg, " << d_pos.norm()
      << " m (guess " << c.name << ", fit " << fit2 << ")";
  Append(&r->reason, why.str());
  Log(LogLevel::kWarn, why.str());
  // The baseline holds what every scan measures: the associations of the update just run.
  PoseProbe after;
  if (associated_probe && associated_at(s, &after)) {
    remember(Kind::kAssociated, after.score.fit, after);
  } else if (!associated_probe) {
    remember(Kind::kSampled, fit2, probe2);
  }
  return rep2;
}

void LioPpf::Impl::SetUpdateStatus(const IekfReport& rep, bool lidar, ScanResult* r) const {
  if (rep.skipped) {
    r->status = Status::kDegenerate;
    std::ostringstream os;
    os << "too few residuals (" << rep.num_rows << " < " << config.iekf.min_rows
       << "): " << (lidar ? "motion-model prediction only" : "IMU prediction only");
    Append(&r->reason, os.str());
  } else if (rep.degenerate) {
    r->status = Status::kDegenerate;
    Append(&r->reason, "degenerate: " + rep.degenerate_reason);
  } else if (contradicted) {
    r->status = Status::kDegenerate;  // the reason says how the map contradicts the pose
  } else {
    r->status = Status::kOk;
  }
}

// LiDAR-only: the coarse alignment's verdict joins the result, and the registered pose moves the
// constant-velocity model on.
void LioPpf::Impl::FinishLidarOnly(const CoarseAlignment& coarse, double t_end, ScanResult* r) {
  r->fit = coarse.fit;
  r->motion_guess = coarse.name;
  r->guesses_tried = coarse.tried;
  if (coarse.fit < config.lidar_only.min_fit) {
    std::ostringstream os;
    os.precision(2);
    os << "LiDAR-only: poor fit " << coarse.fit << " < " << config.lidar_only.min_fit << " after "
       << coarse.tried << " guesses (best " << coarse.name << "): the pose may be off";
    r->status = Status::kDegenerate;
    Append(&r->reason, os.str());
  }
  motion.Update(state.T_world_imu(), t_end);
}

void LioPpf::Impl::ReportRelocalization(ScanResult* r) {
  r->relocalized = true;
  relocalized_since_loss = true;
  std::ostringstream os;
  os.precision(3);
  os << "re-localized after " << fallback_dt << " s without data: " << r->motion_guess << ", fit "
     << r->fit;
  if (has_scan_velocity) {
    os << ", speed " << scan_velocity_world.norm() << " m/s from the scan's own smear ("
       << speed_before_gap << " before the gap)";
  }
  os << " (the map is extended again once LIO confirms the pose)";
  Append(&r->reason, os.str());
  Log(LogLevel::kWarn, os.str());
}

void LioPpf::Impl::ExtendMap(const IekfReport& rep, const Eigen::Isometry3d& T_world_lidar,
                             ScanResult* r) {
  const auto t0 = Clock::now();
  // A scan that could not be registered is not trusted to extend the map.
  if (!rep.skipped && !Relocating()) InsertScattered(frame, T_world_lidar, r);
  if (config.map.radius > 0.0 && ++scans_since_prune >= 10) {
    map.RemoveFarFrom(state.p_world_imu, config.map.radius);
    scans_since_prune = 0;
  }
  r->timings.map_insert = MsSince(t0);
}

// Rotation of the map frame into the frame whose -z is the estimated gravity: the smallest one,
// so yaw is kept.
Eigen::Isometry3d LioPpf::Impl::WorldFromMap() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (world_is_map) return T;  // late IMU: the LiDAR-only start's world goes on
  T.linear() = Eigen::Quaterniond::FromTwoVectors(state.gravity_world.normalized(),
                                                  -Eigen::Vector3d::UnitZ())
                   .toRotationMatrix();
  return T;
}

void LioPpf::Impl::FillState(ScanResult* r) const {
  r->T_world_map = WorldFromMap();
  const Eigen::Matrix3d R = r->T_world_map.linear();
  r->T_world_imu = r->T_world_map * state.T_world_imu();
  r->T_world_lidar = r->T_world_imu * config.extrinsic.T_imu_lidar;
  r->velocity_world = R * state.v_world;
  r->angular_velocity = gyro_at_scan_end - state.gyro_bias;
  if (config.output_deskewed_points) {
    r->deskewed_points_lidar = frame.points_lidar;
    r->deskewed_point_labels = frame.labels;
  }
  r->gyro_bias = state.gyro_bias;
  r->acc_bias = state.acc_bias;
  r->gravity_map = state.gravity_world;
  // Rotation errors are body-frame (unchanged); position and velocity errors turn with the map.
  StateCov J = StateCov::Identity();
  J.block<3, 3>(kPos, kPos) = R;
  J.block<3, 3>(kVel, kVel) = R;
  r->covariance = J * state.P * J.transpose();
  r->pose_covariance = r->covariance.topLeftCorner<6, 6>();
  for (SkeletonPlane& sp : r->skeleton_planes) {
    sp.plane = TransformPlane(r->T_world_map, sp.plane);
    sp.centroid = r->T_world_map * sp.centroid;
    sp.scatter = R * sp.scatter * R.transpose();
  }
}

// The IMU did not measure the motion during a gap: integration across it assumed the samples on
// either side held throughout. Allow a constant unmeasured acceleration and turn rate for its
// length, so the registration of the scans across it can move the pose as far as that explains.
// A scan that crossed the gap from from_s to to_s seconds after its start adds the growth of
// that uncertainty over its part: the whole gap adds what a constant error over it gives.
void LioPpf::Impl::WidenForGap(double from_s, double to_s) {
  auto grown = [&](double std_per_s, double power) {
    return std_per_s * std_per_s * (std::pow(to_s, 2.0 * power) - std::pow(from_s, 2.0 * power));
  };
  const double rot = grown(config.imu.gap_gyro_std, 1.0);
  const double vel = grown(config.imu.gap_acc_std, 1.0);
  const double pos = grown(0.5 * config.imu.gap_acc_std, 2.0);
  state.P.block<3, 3>(kRot, kRot).diagonal().array() += rot;
  state.P.block<3, 3>(kVel, kVel).diagonal().array() += vel;
  state.P.block<3, 3>(kPos, kPos).diagonal().array() += pos;
}

void LioPpf::Impl::InsertScattered(const ScanFrame& f, const Eigen::Isometry3d& T_world_lidar,
                                   ScanResult* r) {
  const Eigen::Isometry3f T = T_world_lidar.cast<float>();
  for (size_t i = 0; i < f.points_lidar.size(); ++i) {
    if (f.labels[i] != PointLabel::kScattered) continue;
    map.Insert(T * f.points_lidar[i]);
    ++r->map_inserted;
  }
}

}  // namespace ppf
