// PpfNode: LIO-PPF on one DomainParticipant, ROS 2 wire compatible.
//
// Threads (and the part, under src/, that owns what each one works on):
//   DDS listener threads  NodeInputs: decode + validate (ppf_bridge), push into bounded
//                         time-ordered queues; never wait for the core. The IMU listener
//                         also propagates and publishes the IMU-rate odometry (ImuRateOutput,
//                         its own copy of the state and lock)
//   executor thread       CoreExecutor: the only thread touching ppf::LioPpf; publishes the
//                         results through NodeOutputs
//   run() caller          periodic diagnostics (NodeStats); on stop(): drain, flush, write TUM
//                         and the map, tear down
//   map thread            NodeMap (outputs.map_file): accumulates the registered scans, writes
//                         the map file on SaveMap() and at shutdown
//
// Usage (as in eProsima's examples): PpfNode node(config); node.init(&err); node.run() until
// stop() is called (e.g. from a signal watcher); the destructor deletes all entities.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "ppf_dds_node/node_config.hpp"
#include "ppf_dds_node/node_summary.hpp"

namespace ppf::dds {

class PpfNode {
 public:
  explicit PpfNode(const NodeConfig& config);
  ~PpfNode();
  PpfNode(const PpfNode&) = delete;
  PpfNode& operator=(const PpfNode&) = delete;

  // Creates the participant and entities in order (types, topics, publisher + writers,
  // subscriber + readers) and the core. False with `error` on any failure.
  bool init(std::string* error);
  // Blocks until stop(); then drains queued data, flushes the core, writes the trajectory.
  void run();
  // Thread-safe, returns at once.
  void stop();
  // Thread-safe, returns at once: the map thread writes outputs.map_file with every scan
  // registered so far (logged with the point count; a failed write is an ERROR line and the node
  // goes on). Without outputs.map_file, one line says so.
  void SaveMap();

  NodeSummary summary() const;
  // "key=value ..." line, stable for scripts and tests.
  static std::string FormatSummary(const NodeSummary& s);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace ppf::dds
