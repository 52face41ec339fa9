#include "ppf_tools/offline_runner.hpp"

#include <chrono>
#include <utility>

namespace ppf::tools {

OfflineRun RunOffline(const std::string& bag_path, const Config& config,
                      const OfflineOptions& options) {
  OfflineRun run;
  LioPpf lio(config);
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
    if (options.on_topics_resolved) options.on_topics_resolved(s);
  };
  callbacks.on_imu = [&](const ImuSample& s) { lio.AddImu(s); };
  callbacks.on_scan = [&](const CloudView& v) {
    lio.AddScan(v);
    consume(lio.Process());
  };
  callbacks.on_error = options.on_error;

  const auto t0 = std::chrono::steady_clock::now();
  run.source = StreamBag(bag_path, options.source, callbacks);
  consume(lio.Process(/*flush=*/true));
  run.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return run;
}

}  // namespace ppf::tools
