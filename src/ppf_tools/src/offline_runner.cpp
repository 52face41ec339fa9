#include "ppf_tools/offline_runner.hpp"

#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <utility>

namespace ppf::tools {
namespace {

// OfflineOptions::drop_scans_*: whether the scan at t (seconds after the first message) is one
// the starved node would have dropped. Counts the scans of the window as they come.
class ScanDropper {
 public:
  explicit ScanDropper(const OfflineOptions& o)
      : every_(o.drop_scans_every),
        begin_s_(o.drop_scans_begin_s),
        length_s_(o.drop_scans_length_s),
        active_(every_ > 1 || (every_ == 1 && length_s_ > 0.0)) {}

  bool Drops(double t) {
    if (!active_) return false;
    if (length_s_ > 0.0 && (t < begin_s_ || t >= begin_s_ + length_s_)) return false;
    return ++in_window_ % static_cast<uint64_t>(every_) == 0;
  }

 private:
  int every_;
  double begin_s_, length_s_;
  bool active_;
  uint64_t in_window_ = 0;
};

}  // namespace

OfflineRun RunOffline(const std::string& bag_path, const Config& config,
                      const OfflineOptions& options) {
  OfflineRun run;
  // Created once the bag's topics are known: a bag without an IMU topic runs LiDAR-only at once
  // (imu.mode auto), instead of holding scans for imu.auto_wait to find out.
  std::unique_ptr<LioPpf> lio;
  auto make = [&](bool has_imu) {
    Config c = config;
    if (!has_imu && c.imu.mode == ImuMode::kAuto) c.imu.mode = ImuMode::kNone;
    lio = std::make_unique<LioPpf>(c);
  };
  uint64_t total_scans = 0;
  double core_ms = 0.0;
  auto consume = [&](std::vector<ScanResult>&& batch) {
    for (auto& r : batch) {
      core_ms += r.timings.total;
      if (r.pose_valid) {
        run.trajectory.push_back({r.stamp_s, options.lidar_frame ? r.T_world_lidar : r.T_world_imu});
      }
      if (options.on_result) options.on_result(run.results.size(), &r);
      run.results.push_back(std::move(r));
    }
    if (options.on_progress) options.on_progress(run.results.size(), total_scans, core_ms);
  };

  BagSourceCallbacks callbacks;
  callbacks.on_topics_resolved = [&](const BagSourceStats& s) {
    total_scans = s.total_scans_in_bag;
    make(!s.imu_topic.empty());
    if (options.on_topics_resolved) options.on_topics_resolved(s);
  };
  double first_stamp = std::numeric_limits<double>::quiet_NaN();
  auto note_first = [&](double t) {
    if (std::isnan(first_stamp) && std::isfinite(t)) first_stamp = t;
  };
  // imu_lead_s: stamps of the scans added but not yet processed, and the newest IMU stamp fed.
  std::deque<double> waiting;
  double imu_fed = -std::numeric_limits<double>::infinity();
  auto process_if_led = [&] {
    if (waiting.empty() || imu_fed < waiting.front() + options.imu_lead_s) return;
    const size_t before = run.results.size();
    consume(lio->Process());
    // The core keeps what the IMU does not cover yet; one result per processed scan, in order.
    for (size_t i = before; i < run.results.size() && !waiting.empty(); ++i) waiting.pop_front();
  };
  callbacks.on_imu = [&](const ImuSample& s) {
    note_first(s.stamp_s);
    const double t = s.stamp_s - first_stamp;
    if (options.imu_gap_length_s > 0.0 && t >= options.imu_gap_begin_s &&
        t < options.imu_gap_begin_s + options.imu_gap_length_s) {
      ++run.imu_dropped;
      return;
    }
    lio->AddImu(s);
    imu_fed = s.stamp_s;
    if (options.imu_lead_s > 0.0) process_if_led();
  };
  ScanDropper dropper(options);
  callbacks.on_scan = [&](const CloudView& v) {
    note_first(v.stamp_s);
    if (dropper.Drops(v.stamp_s - first_stamp)) {
      ++run.scans_dropped;
      return;
    }
    lio->AddScan(v);
    if (options.imu_lead_s > 0.0) {
      waiting.push_back(v.stamp_s);
      process_if_led();
    } else {
      consume(lio->Process());
    }
  };
  callbacks.on_error = options.on_error;

  const auto t0 = std::chrono::steady_clock::now();
  run.source = StreamBag(bag_path, options.source, callbacks);
  if (!lio) make(true);  // no topics resolved: nothing was streamed
  consume(lio->Process(/*flush=*/true));
  run.lidar_only = lio->lidar_only();
  run.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (options.on_finish) options.on_finish(*lio);
  return run;
}

}  // namespace ppf::tools
