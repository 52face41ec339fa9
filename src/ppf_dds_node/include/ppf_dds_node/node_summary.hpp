// What ppf_node counted and measured over its run: printed as the PPF_NODE_SUMMARY line that
// tests and scripts parse (PpfNode::FormatSummary), so fields are only ever added.
#pragma once

#include <cstdint>
#include <string>

namespace ppf::dds {

struct NodeSummary {
  uint64_t scans_received = 0;
  uint64_t scans_dropped = 0;       // evicted from the scan queue because the core fell behind
  uint64_t scans_malformed = 0;     // undecodable CDR / unusable layout
  uint64_t scans_processed = 0;     // results returned by the core
  uint64_t scans_rejected = 0;      // core said kRejected
  uint64_t scans_initializing = 0;  // core said kInitializing
  uint64_t resets = 0;              // core said kReset, or the node restarted it (time jump)
  uint64_t degenerate = 0;
  uint64_t odometry_published = 0;
  uint64_t imu_received = 0;
  uint64_t imu_malformed = 0;
  uint64_t imu_overflow = 0;      // evicted from the IMU queue (should never happen)
  uint64_t imu_out_of_order = 0;  // sorted back into time order (within 0.5 s)
  uint64_t time_jumps = 0;        // IMU or scan stamps jumping back > 0.5 s (bag loop)
  uint64_t scans_late = 0;        // not newer than a scan already processed: dropped
  uint64_t imu_late = 0;          // older than IMU already integrated (< 0.5 s): dropped
  // Gaps in the writers' sequence numbers: samples that never reached the listener (transport
  // loss, or the reader history overwrote them while the listener was descheduled).
  uint64_t scans_lost = 0;
  uint64_t imu_lost = 0;
  uint64_t scans_empty = 0;       // well formed, no points: nothing to register, skipped
  uint64_t scans_too_large = 0;   // more points than queues.max_cloud_points: skipped
  uint64_t scans_bad_stamp = 0;   // stamp <= 0, or far ahead of the IMU stream: skipped
  uint64_t points_nonfinite = 0;  // NaN/Inf points the core dropped from scans it processed
  // Points the core dropped for a time outside the plausible sweep window (ScanResult::
  // points_bad_time); a scan left with too few is rejected with the reason.
  uint64_t points_bad_time = 0;
  // Scans whose IMU prediction the map contradicted and the LiDAR moved (ScanResult::overruled:
  // a jolt, a saturated gyro, a gap the IMU bridged wrongly); each also logs one WARN.
  uint64_t lidar_overruled = 0;
  // Scans the core's consistency check searched again from guesses (ScanResult::
  // consistency_search): the overruled ones and those whose pose the search kept.
  uint64_t consistency_searches = 0;
  // Scans re-localized on the map after a gap longer than the IMU bridges (ScanResult::
  // relocalized: both streams silent while moving); each also logs one WARN.
  uint64_t relocalized = 0;
  uint64_t imu_duplicate = 0;     // same stamp and values as the sample before it: dropped
  // Stamps that came with different values (ScanResult::imu_conflicts): the core kept the copy
  // consistent with the samples on either side, or, unresolved, neither.
  uint64_t imu_conflicts = 0;
  uint64_t imu_conflicts_unresolved = 0;
  // Gaps between valid IMU samples longer than the core's imu.max_gap_warn, and the longest.
  uint64_t imu_gaps = 0;
  double imu_gap_warn_max_s = 0;
  // IMU samples the core set aside because the IMU's clock ran seconds behind the LiDAR's
  // (InputStats::imu_clock_offset_dropped; one WARN names the offset, the scans go LiDAR-only).
  uint64_t imu_clock_offset_dropped = 0;
  // Stamps off the stream's timeline (> 0.5 s back or ahead) that the following samples did
  // not confirm: single outliers, dropped instead of restarting the filter.
  uint64_t imu_outliers = 0;
  // IMU gaps (a link down, a stalled driver) the core bridged with state and map kept, by
  // integration or LiDAR-only (IMU loss fallback) until LIO resumed. The longest in seconds of
  // sensor time.
  uint64_t imu_gaps_bridged = 0;
  double imu_gap_max_s = 0;
  // IMU loss fallback (core: imu.loss_timeout): episodes in which the core registered scans
  // LiDAR-only because the IMU stream had stopped, and the scans so registered. While one lasts
  // the status line says "IMU lost: LiDAR-only".
  uint64_t imu_fallbacks = 0;
  uint64_t imu_fallback_scans = 0;
  bool imu_fallback_active = false;
  // Scans registered without an IMU because none has come (imu.mode none, or auto after
  // imu.auto_wait of scans without one); while the last pose was one, the status line says
  // "no IMU: LiDAR-only". An IMU that starts later takes over (lio_started_late: 1).
  uint64_t lidar_only_scans = 0;
  bool lidar_only_active = false;
  uint64_t lio_started_late = 0;
  // Episodes of silence on a stream with a matched publisher, after data had flowed on it
  // (diagnostics.stall_warn_s): the data stopped while matching said all was well.
  uint64_t points_stalls = 0;
  uint64_t imu_stalls = 0;
  // Episodes in which scans kept arriving for more than a second while none was processed (the
  // core stuck, or every scan refused or dropped): status=stalled and one WARN each.
  uint64_t core_stalls = 0;
  // Clouds taken as they are but unusual enough to name once (row_step 0, thousands of fields,
  // a frame_id of kilobytes): each kind logged the first time, all counted.
  uint64_t scans_unusual = 0;
  double latency_p50_ms = 0, latency_p99_ms = 0, latency_max_ms = 0;
  double core_p50_ms = 0, core_p99_ms = 0;
  // overhead = latency - core - imu_wait - behind_core: the node's own cost (decode, hand-over,
  // publishing).
  double overhead_p50_ms = 0, overhead_p99_ms = 0, overhead_max_ms = 0;
  double imu_wait_p50_ms = 0, imu_wait_p99_ms = 0;  // scan waited in the core for IMU coverage
  double decode_p50_ms = 0, decode_p99_ms = 0;      // listener: take + CDR decode + checks
  double queue_p50_ms = 0, queue_p99_ms = 0;        // scan queue -> executor
  double behind_core_p50_ms = 0, behind_core_p99_ms = 0;  // of queue: core busy with older scans
  double publish_p50_ms = 0, publish_p99_ms = 0;          // result -> all outputs written
  // IMU-rate odometry (outputs.odometry_imu_rate): messages written, and the time from taking
  // the IMU sample in the listener to its message written (to 0.01 ms).
  uint64_t odometry_imu_rate_published = 0;
  double imu_rate_latency_p50_ms = 0, imu_rate_latency_p99_ms = 0, imu_rate_latency_max_ms = 0;
  std::string last_status;
};

}  // namespace ppf::dds
