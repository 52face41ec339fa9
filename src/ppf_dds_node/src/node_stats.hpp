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

// Scans kept arriving for longer than this without one processed: the node is stalled whatever
// the core said last (the core stuck on one scan, or every scan refused or dropped).
inline constexpr double kCoreStallS = 1.0;

// What NodeStats::CheckCoreStall saw: an episode starting or ending, with what it is made of.
struct CoreStallPoll {
  enum class Event { kNone, kStarted, kEnded };
  Event event = Event::kNone;
  bool stalled = false;
  double seconds = 0.0;  // since the last processed scan
  uint64_t episode = 0;  // core_stalls
  // Scans received since the last processed one, and of those: refused in the listener
  // (malformed, too large, empty, bad stamp), dropped (late, or evicted from the full queue);
  // the rest wait in the scan queue or the core.
  uint64_t received = 0, refused = 0, dropped = 0;
};

class NodeStats {
 public:
  // Adds `n` to one counter; returns its new value (for "total N" in log lines).
  uint64_t Add(uint64_t NodeSummary::*counter, uint64_t n = 1);
  // One cloud sample taken by the listener (counted in scans_received, valid or not).
  void AddScanReceived(std::chrono::steady_clock::time_point t);
  // Diagnostics thread: is the node stalled (scans arriving for more than kCoreStallS, none
  // processed)? Counts each episode once (core_stalls); the caller logs the events.
  CoreStallPoll CheckCoreStall(std::chrono::steady_clock::time_point now);
  // One result returned by the core: status counts, non-finite points, last status.
  void CountResult(const ScanResult& r);
  // A result that belongs to no scan (ScanResult::input_id 0): a reset the core did itself.
  void CountNotice(const ScanResult& r);
  // The core's input totals (LioPpf::input_stats, kept across its Reset) for what no ScanResult
  // carries per scan.
  void SetCoreInputTotals(const InputStats& totals);
  // Scans and IMU samples lost in transport so far (sequence gaps), for log lines.
  std::pair<uint64_t, uint64_t> Lost() const;
  // One scan whose odometry was published.
  void AddPublished(const ScanTiming& t);
  // One IMU-rate odometry message written, `latency_ms` after its IMU sample was taken.
  void AddImuRatePublished(double latency_ms);

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
  // The status also says stalled while the last CheckCoreStall found the node stalled.
  std::string PeriodicLine(size_t* latency_mark, const QueueFill& queues,
                           const std::string& stalled = "") const;
  static std::string FormatSummary(const NodeSummary& s);

 private:
  void CountImuInput(const ScanResult& r);  // with mutex_ held

  mutable std::mutex mutex_;
  NodeSummary summary_;
  // Core stall watch (under mutex_): the scans received since the last result, the first and
  // latest of them, the counters as they were at that result.
  bool have_result_ = false;
  std::chrono::steady_clock::time_point last_result_, first_unanswered_, last_received_,
      stall_since_;
  uint64_t unanswered_ = 0;
  NodeSummary at_last_result_;
  bool core_stalled_ = false;
  double core_stall_s_ = 0.0;
  LatencyStats latency_ms_, core_time_ms_, overhead_ms_, imu_wait_ms_, decode_ms_, queue_ms_,
      behind_core_ms_, publish_ms_;
  LatencyHistogram imu_rate_latency_ms_;
  std::atomic<int64_t> core_busy_ns_{0};
};

}  // namespace ppf::dds
