// CoreExecutor: the executor thread's side of the node. It owns ppf::LioPpf (the only thread that
// touches it), drains the input queues into it in time order, applies the node's time-jump policy,
// matches each result to the scan it came from and hands it to the outputs and the statistics.
// Everything here but RequestDrain() runs on the executor thread, so its state needs no lock.
#pragma once

#include <atomic>
#include <chrono>
#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "imu_rate_output.hpp"
#include "node_inputs.hpp"
#include "node_map.hpp"
#include "node_outputs.hpp"
#include "node_stats.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_dds_node/logging.hpp"
#include "ppf_dds_node/node_config.hpp"

namespace ppf::dds {

class CoreExecutor {
 public:
  // The core as the node config asks for it (core config and calibration files, mode), its log
  // routed to the node's. Null with `error` on a bad core config.
  static std::unique_ptr<LioPpf> CreateCore(const NodeConfig& config, std::string* error);

  CoreExecutor(const NodeConfig& config, std::unique_ptr<LioPpf> core, NodeInputs* inputs,
               NodeOutputs* outputs, NodeMap* map, NodeStats* stats);

  // The executor thread's body. Returns after RequestDrain() once the queues are empty and the
  // core has been flushed.
  void Run();
  // The IMU-rate odometry, told of every result and restart (outputs.odometry_imu_rate; none
  // if off). Set before Run().
  void SetImuRateOutput(ImuRateOutput* output) { imu_rate_ = output; }
  // Thread-safe.
  void RequestDrain();
  // Reports the suppressed tails of the rate-limited logs (any thread).
  void FlushLogs();

 private:
  // Per scan handed to the core, in AddScan order, until its result (same input id) comes back.
  struct PendingScan {
    uint64_t id = 0;  // LioPpf::AddScan's
    std::chrono::steady_clock::time_point received;
    std::chrono::steady_clock::time_point added;  // AddScan returned
    double decode_ms = 0.0;
    double queue_ms = 0.0;
    double behind_core_ms = 0.0;
    double add_scan_ms = 0.0;
  };

  void FeedImu(const ImuSample& s);
  void AddImuToCore(const ImuSample& s);
  void DropImuCandidates();
  void RestartCore(const std::string& why);
  bool AcceptScanStamp(double stamp);
  void AddScan(ScanItem item);
  void RunCore(bool flush);
  void Publish(const ScanResult& r, const PendingScan& p, double core_ms, double imu_wait_ms);
  void ReportNotice(const ScanResult& r);

  const NodeConfig config_;
  std::unique_ptr<LioPpf> core_;
  ScanQueue& scan_queue_;
  ImuQueue& imu_queue_;
  NodeOutputs& outputs_;
  NodeMap& map_;
  NodeStats& stats_;
  ImuRateOutput* imu_rate_ = nullptr;
  std::atomic<bool> drain_requested_{false};

  double last_imu_fed_ = -std::numeric_limits<double>::infinity();
  ImuSample last_imu_;  // the sample last fed, to tell a redelivered copy from a conflicting one
  double last_scan_fed_ = -std::numeric_limits<double>::infinity();
  std::vector<ImuSample> imu_candidates_;  // off the timeline, waiting for confirmation
  std::deque<PendingScan> pending_;

  // One limiter per kind of defect, so that one kind's burst does not hide another's line.
  RateLimitedLog ahead_log_, late_log_, imu_late_log_, imu_dup_log_, outlier_log_, nonfinite_log_;
  RateLimitedLog status_log_{1.0};
};

}  // namespace ppf::dds
