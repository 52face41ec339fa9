// PpfNode: the composition of the node's parts, each owning its state and its lock:
//   NodeInputs    DDS readers + listeners, buffer pool, gap counters, validation, input queues
//   CoreExecutor  the executor thread: owns LioPpf, feeds it, time-jump policy, result matching
//   NodeOutputs   odometry, TF, path, skeleton planes, registered points, TUM file
//   ImuRateOutput the odometry at the IMU's rate, published from the IMU listener
//   NodeMap       the saved map (outputs.map_file): its own thread accumulates and writes
//   NodeStats     counters and latency series behind the periodic and summary lines
// This file only creates them in order, runs the diagnostics loop and tears them down.
#include "ppf_dds_node/ppf_node.hpp"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <thread>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>

#include "core_executor.hpp"
#include "imu_rate_output.hpp"
#include "node_inputs.hpp"
#include "node_map.hpp"
#include "node_outputs.hpp"
#include "node_stats.hpp"
#include "ppf_dds_node/dds_common.hpp"
#include "ppf_dds_node/logging.hpp"

namespace ppf::dds {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;

// Declared in the order the parts depend on each other: stats before the parts that count into
// it, the executor (which holds the queues, outputs and stats by reference) last, so it goes first.
struct PpfNode::Impl {
  explicit Impl(const NodeConfig& c) : config(c), inputs(c, &stats), outputs(c), map(c) {}

  // Deletes every DDS entity, so no listener runs afterwards. Never called with one of our locks
  // held: Fast DDS waits for its listener threads here.
  void TearDown() {
    if (!participant) return;
    participant->delete_contained_entities();
    fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
    participant = nullptr;
  }

  void FlushLogs() {
    inputs.FlushLogs();
    if (executor) executor->FlushLogs();
  }

  const NodeConfig config;
  NodeStats stats;
  NodeInputs inputs;
  NodeOutputs outputs;
  std::unique_ptr<ImuRateOutput> imu_rate;  // outputs.odometry_imu_rate
  NodeMap map;
  std::unique_ptr<CoreExecutor> executor;
  fdds::DomainParticipant* participant = nullptr;

  std::mutex stop_mutex;
  std::condition_variable stop_cv;
  bool stop_requested = false;  // guarded by stop_mutex
};

PpfNode::PpfNode(const NodeConfig& config) : impl_(std::make_unique<Impl>(config)) {}

PpfNode::~PpfNode() { impl_->TearDown(); }

bool PpfNode::init(std::string* error) {
  Impl& m = *impl_;
  const NodeConfig& c = m.config;
  // Core first: a bad core config must fail before we appear on the network.
  std::unique_ptr<LioPpf> core = CoreExecutor::CreateCore(c, error);
  if (!core) return false;
  if (c.publish_odometry_imu_rate) {
    m.imu_rate = std::make_unique<ImuRateOutput>(c, core->config(), &m.stats);
  }
  m.executor = std::make_unique<CoreExecutor>(c, std::move(core), &m.inputs, &m.outputs, &m.map,
                                              &m.stats);

  m.participant = CreateParticipant(c.participant, error);
  if (!m.participant) return false;
  fdds::Publisher* publisher = m.participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  fdds::Subscriber* subscriber = m.participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (!publisher || !subscriber) {
    *error = "cannot create publisher/subscriber";
    return false;
  }
  // Writers before readers: data may flow as soon as the readers exist.
  if (!m.outputs.Create(m.participant, publisher, m.inputs.cloud_type(), error)) return false;
  if (m.imu_rate) {
    if (!m.imu_rate->Create(m.participant, publisher, error)) return false;
    m.executor->SetImuRateOutput(m.imu_rate.get());
    m.inputs.SetImuObserver([out = m.imu_rate.get()](const ImuSample& s,
                                                     const builtin_interfaces::msg::Time& stamp,
                                                     Clock::time_point received) {
      out->OnImu(s, stamp, received);
    });
  }
  if (!m.inputs.Create(m.participant, subscriber, error)) return false;
  Log(Level::kInfo,
      "ppf_node up: domain " + std::to_string(c.participant.domain_id) + ", in " +
          RosTopicToDds(c.points_topic) + " + " + RosTopicToDds(c.imu_topic) + " (" +
          (c.sensor_reliability == Reliability::kBestEffort ? "best effort" : "reliable") +
          "), out " + RosTopicToDds(c.odometry_topic) + " [" + c.odom_frame + " -> " +
          c.base_frame + "]");
  return true;
}

namespace {

// Logged outside NodeStats' lock.
void ReportCoreStall(const CoreStallPoll& p) {
  char secs[32];
  std::snprintf(secs, sizeof(secs), "%.1f", p.seconds);
  if (p.event == CoreStallPoll::Event::kStarted) {
    const uint64_t waiting = p.received - std::min(p.received, p.refused + p.dropped);
    Log(Level::kWarn, std::string("stalled: no scan processed for ") + secs + " s while " +
                          std::to_string(p.received) + " arrived (" + std::to_string(p.refused) +
                          " refused at input, " + std::to_string(p.dropped) +
                          " dropped as late or from the full queue, " + std::to_string(waiting) +
                          " waiting for the core); status=stalled until one is (core stall " +
                          std::to_string(p.episode) + ")");
  } else if (p.event == CoreStallPoll::Event::kEnded) {
    Log(Level::kInfo, std::string("scans processed again after ") + secs +
                          " s without (core stall " + std::to_string(p.episode) + " ended)");
  }
}

// After the drain: an episode the drain did not end (the last scans were all refused, or the
// core still had none to answer) is said to be open at the stop, so every core_stalls episode
// has its end in the log.
void ReportCoreStallAtStop(const CoreStallPoll& p) {
  ReportCoreStall(p);
  if (!p.stalled) return;
  char secs[32];
  std::snprintf(secs, sizeof(secs), "%.1f", p.seconds);
  Log(Level::kWarn, std::string("core stall ") + std::to_string(p.episode) +
                        " still open at the stop: no scan processed for the last " + secs + " s");
}

}  // namespace

void PpfNode::run() {
  Impl& m = *impl_;
  std::thread executor([&m] { m.executor->Run(); });
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(m.config.diagnostics_period_s));
  // The stall watch is polled more often than the status line, so a stall is reported about
  // diagnostics.stall_warn_s after the last sample, not up to a status period later.
  // The core stall watch (kCoreStallS) likewise, at a quarter of its interval.
  const double tick_s =
      std::min(m.config.stall_warn_s > 0.0 ? std::clamp(m.config.stall_warn_s / 4.0, 0.05, 1.0)
                                           : m.config.diagnostics_period_s,
               kCoreStallS / 4.0);
  const auto stall_tick =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(tick_s));
  size_t latency_mark = 0;
  auto next_log = Clock::now() + period;
  std::string stalled;
  {
    std::unique_lock<std::mutex> lock(m.stop_mutex);
    while (!m.stop_requested) {
      m.stop_cv.wait_until(lock, std::min(next_log, Clock::now() + stall_tick),
                           [&m] { return m.stop_requested; });
      if (m.stop_requested) break;
      lock.unlock();
      stalled = m.inputs.CheckStalls();
      ReportCoreStall(m.stats.CheckCoreStall(Clock::now()));
      if (Clock::now() >= next_log) {
        m.FlushLogs();
        Log(Level::kInfo, m.stats.PeriodicLine(&latency_mark, m.inputs.Fill(), stalled));
        next_log += period;
      }
      lock.lock();
    }
  }
  // Drain: stop accepting, process what is queued, flush the core.
  const auto stop_start = Clock::now();
  m.inputs.StopAccepting();
  m.executor->RequestDrain();
  executor.join();
  ReportCoreStallAtStop(m.stats.CheckCoreStall(Clock::now()));
  const auto drained = Clock::now();
  m.FlushLogs();  // the counts of bursts no later line reported
  if (!m.config.tum_file.empty()) {
    std::string error;
    if (m.outputs.WriteTum(&error)) {
      Log(Level::kInfo, "trajectory: " + std::to_string(m.outputs.trajectory_size()) +
                            " poses -> " + m.config.tum_file);
    } else {
      Log(Level::kError, error);
    }
  }
  m.map.Finish();  // every scan the executor handed over is in the file (or an ERROR says why)
  m.outputs.WaitForAcknowledgments();
  if (m.imu_rate) m.imu_rate->WaitForAcknowledgments();
  const auto flushed = Clock::now();
  m.TearDown();
  // A stop that takes long says where (the queue, the files and acknowledgments, or Fast DDS).
  const auto s = [](Clock::duration d) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.3f", std::chrono::duration<double>(d).count());
    return std::string(buf);
  };
  Log(Level::kInfo, "stopped: drain " + s(drained - stop_start) + " s, outputs " +
                        s(flushed - drained) + " s, DDS teardown " + s(Clock::now() - flushed) +
                        " s");
}

void PpfNode::stop() {
  {
    std::lock_guard<std::mutex> lock(impl_->stop_mutex);
    impl_->stop_requested = true;
  }
  impl_->stop_cv.notify_all();
}

void PpfNode::SaveMap() {
  if (impl_->map.enabled()) {
    impl_->map.RequestSave();
  } else {
    Log(Level::kInfo, "no map to save: outputs.map_file is not set");
  }
}

NodeSummary PpfNode::summary() const { return impl_->stats.Snapshot(); }

std::string PpfNode::FormatSummary(const NodeSummary& s) { return NodeStats::FormatSummary(s); }

}  // namespace ppf::dds
