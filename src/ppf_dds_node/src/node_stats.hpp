// NodeStats: the node's counters and latency series. Written by the listener threads and the
// executor, read by the diagnostics loop and summary(); one mutex for all of it, held only inside
// these methods (never while logging or calling into Fast DDS).
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>
#include <utility>

#include "ppf_core/lio_ppf.hpp"
#include "ppf_dds_node/latency_stats.hpp"
#include "ppf_dds_node/node_summary.hpp"

namespace ppf::dds {

// Where one published scan's time went, DDS receive to the last output written.
struct ScanTiming {
  std::chrono::steady_clock::time_point received;  // listener entry
  std::chrono::steady_clock::time_point publish_start;
  std::chrono::steady_clock::time_point published;  // all outputs written
  double core_ms = 0.0;         // AddScan + this scan's share of the Process call
  double imu_wait_ms = 0.0;     // waited in the core for IMU covering its end
  double decode_ms = 0.0;       // listener: take + CDR decode + checks
  double queue_ms = 0.0;        // waiting in the scan queue for the executor
  double behind_core_ms = 0.0;  // part of queue_ms during which the executor ran the core
};

// Queue fill levels for the periodic line (the queues belong to NodeInputs).
struct QueueFill {
  size_t scans = 0, scan_capacity = 0, imus = 0;
};

class NodeStats {
 public:
  // Adds `n` to one counter; returns its new value (for "total N" in log lines).
  uint64_t Add(uint64_t NodeSummary::*counter, uint64_t n = 1);
  // One result returned by the core: status counts, non-finite points, last status.
  void CountResult(const ScanResult& r);
  // A result that belongs to no scan (ScanResult::input_id 0): a reset the core did itself.
  void CountNotice(const ScanResult& r);
  // Scans and IMU samples lost in transport so far (sequence gaps), for log lines.
  std::pair<uint64_t, uint64_t> Lost() const;
  // One scan whose odometry was published.
  void AddPublished(const ScanTiming& t);

  // Executor time inside the core, total: a queued scan's share of it is how long it waited
  // behind older scans (read by the listener when it queues a scan).
  void AddCoreBusy(std::chrono::steady_clock::duration d) {
    core_busy_ns_ += std::chrono::duration_cast<std::chrono::nanoseconds>(d).count();
  }
  int64_t core_busy_ns() const { return core_busy_ns_.load(); }

  NodeSummary Snapshot() const;
  // The periodic diagnostics line over the scans published since `*latency_mark`; advances it.
  // `stalled` names the streams matched but silent (NodeInputs::CheckStalls), "" if none: the
  // status then says stalled, whatever the core said last.
  std::string PeriodicLine(size_t* latency_mark, const QueueFill& queues,
                           const std::string& stalled = "") const;
  static std::string FormatSummary(const NodeSummary& s);

 private:
  mutable std::mutex mutex_;
  NodeSummary summary_;
  LatencyStats latency_ms_, core_time_ms_, overhead_ms_, imu_wait_ms_, decode_ms_, queue_ms_,
      behind_core_ms_, publish_ms_;
  std::atomic<int64_t> core_busy_ns_{0};
};

}  // namespace ppf::dds
