// LioPpf's state and stages (private: not installed, included only by the lio_ppf*.cpp files).
//
// One struct, split by what a reader looks for:
//   lio_ppf.cpp            facade, input (AddImu, AddScan), the queue (Process), resets and the
//                          IMU-mode decision
//   lio_ppf_process.cpp    one scan's path (ProcessOne and its stages) and the result
//   lio_ppf_init.cpp       the filter's start: static IMU initialization and the moving start
//   lio_ppf_lidar_only.cpp prediction without the IMU's translation: constant-velocity and gyro
//                          prediction and the guesses of the coarse alignment (LiDAR-only mode
//                          and the moving start's window)
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/lio/fit_baseline.hpp"
#include "ppf_core/lio/hypothesis_search.hpp"
#include "ppf_core/lio/iekf.hpp"
#include "ppf_core/lio/imu_init.hpp"
#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/knn_residual.hpp"
#include "ppf_core/lio/motion_model.hpp"
#include "ppf_core/lio/moving_start.hpp"
#include "ppf_core/lio/preprocess.hpp"
#include "ppf_core/lio/residual_provider.hpp"
#include "ppf_core/lio/time_field.hpp"
#include "ppf_core/lio/voxel_map.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_core/ppf/skeleton_tracker.hpp"
#include "ppf_core/ppf/skeleton_window.hpp"

namespace ppf {

struct LioPpf::Impl {
  struct QueuedScan {
    uint64_t id = 0;
    bool rejected = false;
    std::string error;
    double stamp_s = 0.0;
    double decode_ms = 0.0;
    DecodedScan scan;
  };

  using Clock = std::chrono::steady_clock;
  static double MsSince(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  }
  static void Append(std::string* reason, const std::string& what) {
    if (what.empty()) return;
    if (!reason->empty()) *reason += "; ";
    *reason += what;
  }

  // At most one line per interval of data time for a recurring input fault, telling how many
  // were held back since the last one: a driver repeating a fault every scan or sample must not
  // flood the log. Data time, not wall time: replays at any speed log the same lines.
  struct LogLimiter {
    double interval_s = 5.0;
    double next_s = -std::numeric_limits<double>::infinity();
    size_t held = 0;
    // True if a line may go out at data time t (a clock jump back also lets it out); *held_back
    // is then how many were held back before it.
    bool Allow(double t, size_t* held_back) {
      if (t < next_s && t >= next_s - 2.0 * interval_s) {
        ++held;
        return false;
      }
      *held_back = held;
      held = 0;
      next_s = t + interval_s;
      return true;
    }
  };

  explicit Impl(const Config& c);

  // lio_ppf.cpp: input and queue.
  void Log(LogLevel level, const std::string& msg) const {
    if (config.log) config.log(level, msg);
  }
  void ResetFilter(const std::string& reason);
  void AddImu(const ImuSample& s);
  void JudgeImuGap(const ImuSample& s);  // AddImu's steps
  void IntegrateImu(const ImuSample& s);
  bool TakeImuDuplicate(const ImuSample& s);
  void ResolveImuConflict();
  void CountImuGap(const ImuSample& s);
  double ImuCoveredUntil() const;
  void AddInputCounts(ScanResult* r);
  void JudgeClockOffset(const DecodedScan& scan);
  void EnterClockOffset(double offset_s, const DecodedScan& scan);
  void FeedInitializer(const ImuSample& s);
  uint64_t AddScan(const CloudView& cloud);
  void JudgeBadPointTimes(QueuedScan* q);
  ScanResult Rejected(const QueuedScan& q) const;
  std::vector<ScanResult> Process(bool flush);
  bool DecideImuMode(bool flush);
  bool NeedsFallback(const DecodedScan& scan, bool may_declare);
  void StartLateImu(const ImuSample& s);
  void EnterImuLoss(const std::string& why);

  // lio_ppf_process.cpp: one scan.
  ScanResult ProcessOne(QueuedScan& q);
  bool AcceptScan(const DecodedScan& scan, bool lidar, ScanResult* r);
  void Preprocess(const QueuedScan& q, std::vector<TimedPoint>* pts, ScanResult* r);
  double Propagate(const DecodedScan& scan, bool lidar, PoseTrace* trace, ScanResult* r);
  void Deskew(const DecodedScan& scan, const std::vector<TimedPoint>& pts, const PoseTrace& trace,
              double t_end);
  void StartMap(bool lidar, double t_end, ScanResult* r);
  void SplitScan(bool lidar, ScanResult* r);
  bool PrefetchBesideSplit(bool lidar) const;
  IekfReport Register(const DecodedScan& scan, const std::vector<TimedPoint>& pts, double t_end,
                      bool lidar, Eigen::Isometry3d* T_world_lidar_out, ScanResult* r);
  IekfReport RedeskewGapTurn(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                             double t_end, const NavState& predicted, const IekfOptions& iekf,
                             const std::vector<ResidualProvider*>& providers, const IekfReport& rep,
                             ScanResult* r);
  IekfReport UpdateRedeskewed(double t_end, const NavState& updated, const NavState& predicted,
                              const IekfOptions& iekf,
                              const std::vector<ResidualProvider*>& providers);
  IekfReport RedeskewVelocity(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                              double t_end, const NavState& predicted, const IekfOptions& iekf,
                              const std::vector<ResidualProvider*>& providers,
                              const IekfReport& rep, ScanResult* r);
  void PrepareFrame(double t_end);
  void CountLabels(ScanResult* r) const;
  IekfReport OverruleIfInconsistent(const NavState& predicted, const IekfOptions& iekf,
                                    const std::vector<ResidualProvider*>& providers,
                                    const IekfReport& rep, ScanResult* r);
  void SetUpdateStatus(const IekfReport& rep, bool lidar, ScanResult* r) const;
  void FinishLidarOnly(const CoarseAlignment& coarse, double t_end, ScanResult* r);
  void ExtendMap(const IekfReport& rep, const Eigen::Isometry3d& T_world_lidar, ScanResult* r);
  Eigen::Isometry3d WorldFromMap() const;
  void FillState(ScanResult* r) const;
  void WidenForGap(double from_s, double to_s);
  void InsertScattered(const ScanFrame& f, const Eigen::Isometry3d& T_world_lidar, ScanResult* r);
  void SeedFallback();
  void ResumeLio(ScanResult* r);

  // lio_ppf_init.cpp: the filter's start.
  void StartFilter();
  void MovingInitStep(ScanResult* r);
  void SetMovingInitResult(ScanResult* r) const;
  void RestartMovingInit(const std::string& why);
  void ClearMovingInit();
  void StartFilterMoving(const MovingStartEstimate& e);

  // lio_ppf_lidar_only.cpp: prediction without the IMU's translation.
  void StartLidarOnly(double t);
  void PredictConstantVelocity(double t_end, PoseTrace* trace);
  void SetLidarOnlyPrior();
  void PredictGyro(double t_end, PoseTrace* trace);
  CoarseAlignment AlignGuesses(double t_end);
  Eigen::Isometry3d ExtrapolateModel(double t_end) const;
  // The scan is registered LiDAR-only after a gap longer than the IMU bridges: a re-localization
  // whose pose is not trusted to extend the map.
  void ReportRelocalization(ScanResult* r);
  bool Relocating() const { return fallback_scan && fallback_dt > config.imu.max_gap_s; }
  void AddAlongTrackGuesses(const Eigen::Isometry3d& T_world_lidar, const Eigen::Vector3d& v_world,
                            double dt, std::vector<MotionHypothesis>* h) const;
  void RedeskewLidarOnly(const DecodedScan& scan, const std::vector<TimedPoint>& pts, double t_end);
  PoseTrace GyroTraceToEnd(const DecodedScan& scan, const Eigen::Isometry3d& T_end,
                           const Eigen::Vector3d& v_world, double t_end) const;
  void EstimateScanVelocity(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                            double t_end);
  ScanFrame ScanAloneSample();
  Eigen::Isometry3d AlignScanAlone(const ScanFrame& sample, int steps) const;
  Eigen::Vector3d ScanAloneTurn(int steps);
  void RepropagateGap(const Eigen::Vector3d& rate_body, const DecodedScan& scan,
                      const std::vector<TimedPoint>& pts, double t_end);
  void CorrectGapTurn(const DecodedScan& scan, const std::vector<TimedPoint>& pts, double t_end,
                      ScanResult* r);
  void CorrectSaturatedTurn(const DecodedScan& scan, const std::vector<TimedPoint>& pts,
                            double t_end, ScanResult* r);

  Config config;
  TimeFieldDecoder decoder;
  ImuInitializer init;
  VoxelMap map;
  std::shared_ptr<KnnResidualProvider> knn;
  std::vector<AssociatedPoint> associated;   // scratch of OverruleIfInconsistent
  std::unique_ptr<SkeletonTracker> tracker;  // PPF: kPpf only
  std::deque<ImuSample> imu;
  std::vector<ImuSample> sweep_imu;  // a re-localized scan's samples after the gap
  std::deque<QueuedScan> scans;
  std::vector<ScanResult> pending;
  struct BridgedGap {
    double begin_s;  // last IMU stamp before the gap
    double length_s;
    double widened_s = 0.0;  // the part of it the scans propagated so far crossed
  };
  std::deque<BridgedGap> bridged_gaps;  // not yet propagated across
  NavState state;
  // The last propagation's gyro saturation, and what it started from (CorrectSaturatedTurn).
  GyroSaturation saturation;
  NavState saturation_start;
  std::vector<ImuSample> saturation_samples;
  // The part of a bridged gap the last propagation crossed (gap_to_s > gap_from_s), and what it
  // started from (CorrectGapTurn).
  double gap_from_s = 0.0;
  double gap_to_s = 0.0;
  PoseTrace deskew_trace;  // what the current frame was de-skewed with (Deskew)
  NavState gap_start;
  std::vector<ImuSample> gap_samples;
  ScanFrame frame;
  VoxelGridDownsampler downsampler;  // keeps its hash table between scans
  bool initialized = false;
  bool map_initialized = false;
  bool lidar_only = false;       // decided: no IMU (DecideImuMode)
  bool lidar_only_auto = false;  // ... by imu.mode auto: IMU samples arriving later start LIO
  // Late IMU: LIO starting from a LiDAR-only start. The moving-start window runs on the
  // LiDAR-only map and world (no reset), and its scans' results stay valid LiDAR-only poses.
  bool late_imu = false;
  double late_imu_from_s = 0.0;  // ... its first sample: scans that begin earlier stay out
  // The world is the LiDAR-only start's (first scan's LiDAR frame), not turned to gravity once
  // the IMU is known: the published pose goes on without a jump (WorldFromMap).
  bool world_is_map = false;
  bool lio_decided = false;  // decided: the IMU predicts
  // Moving start (moving_start.hpp): scans are registered LiDAR-only until the window is full.
  bool moving_init = false;
  bool moving_refused = false;  // the IMU was refused for motion: the window decides
  bool imu_prediction = false;  // moving start: this scan's prediction is PredictGyro's
  std::vector<MovingStartPose> moving_poses;  // IMU poses of the window's registered scans
  int moving_scans = 0;  // registered since the window (re)started, warm-up included
  static constexpr int kMovingWarmupScans = 5;
  double acc_scale = 1.0;            // of the initialization in use
  ConstantVelocityModel motion;      // LiDAR-only prediction (IMU frame poses)
  std::deque<double> recent_fits;    // LiDAR-only: fits of the last scans (AlignGuesses)
  FitBaseline lio_baseline;          // LIO: posterior fits and scan-alone steps, per score kind
  std::deque<double> lio_steps_rot;  // ... the scan-alone steps' rotation (rad), every kind
  bool contradicted = false;         // this scan's pose fits the map poorly and no guess did better
  size_t ignored_imu = 0;
  // IMU loss (docs/behaviour.md, "IMU loss"): LIO running, but scans are registered LiDAR-only
  // until IMU samples are back and cover the next scan; then propagation re-anchors at the last
  // LiDAR-only pose.
  bool imu_lost = false;
  bool fallback_scan = false;    // the scan in ProcessOne is one of those
  bool fallback_seeded = false;  // the motion model holds the filter's pose and twist
  bool imu_back = false;         // samples arrived after the loss, the first at imu_back_stamp_s
  double imu_back_stamp_s = 0.0;
  double imu_loss_gap_s = 0.0;  // the gap in the IMU stream those samples ended
  bool relocalized_since_loss = false;
  // The velocity the re-localization scan itself showed (EstimateScanVelocity): LIO resumes
  // with it, not with the chord over the gap.
  bool has_scan_velocity = false;
  Eigen::Vector3d scan_velocity_world = Eigen::Vector3d::Zero();
  double speed_before_gap = 0.0;  // the motion model's when the search started (the report's)
  double fallback_dt = 0.0;       // interval of the last LiDAR-only scan (velocity at resume)
  StateCov P_before_loss = StateCov::Identity();  // biases' and gravity's, kept for the resume
  // A scan may resume LIO if the first IMU sample back is at most this much after its start: the
  // propagation holds that sample for the bit before it (a few IMU periods).
  static constexpr double kResumeSlackS = 0.02;
  double map_init_stamp_s = 0.0;
  double last_imu_stamp = -std::numeric_limits<double>::infinity();
  double last_scan_end = -std::numeric_limits<double>::infinity();
  size_t dropped_imu = 0;
  LogLimiter bad_time_log;
  // IMU samples with the newest sample's stamp but other values: which copy is right is decided
  // once the next stamp is complete (ResolveImuConflict); meanwhile none of them, and none of the
  // next stamp's, is in `imu`.
  struct ImuConflict {
    bool active = false;
    bool has_prev = false;
    ImuSample prev;                 // the settled sample before the stamp in conflict
    std::vector<ImuSample> copies;  // in arrival order
    std::vector<ImuSample> next;    // the copies of the stamp after it
  } imu_conflict;
  LogLimiter imu_conflict_log{1.0};
  LogLimiter imu_gap_log{1.0};
  InputStats input_stats;     // totals
  InputStats input_reported;  // totals when the last result was handed out
  double imu_gap_longest_since_result_s = 0.0;
  // Clock offset (docs/behaviour.md, "Clock offset"): the IMU stream live (valid samples
  // arriving between scans) but its newest sample kClockOffsetS or more behind every scan's end
  // for kClockOffsetScans scans. Meanwhile the samples are not used and the scans are registered
  // LiDAR-only; the same count of scans in agreement ends it.
  static constexpr double kClockOffsetS = 1.0;
  static constexpr int kClockOffsetScans = 10;
  bool clock_offset = false;
  double clock_offset_s = 0.0;  // the last offset measured (scan end - newest IMU sample)
  int clock_offset_votes = 0;   // consecutive scans contradicting the current judgement
  double imu_arrived_stamp = -std::numeric_limits<double>::infinity();  // used or not
  size_t imu_arrived_since_scan = 0;
  int scans_since_prune = 0;
  uint64_t last_input_id = 0;
  Eigen::Vector3d gyro_at_scan_end = Eigen::Vector3d::Zero();  // raw, of the scan in ProcessOne
};

}  // namespace ppf
