// Shared DDS plumbing for ppf_node, ppf_replay, ppf_record and the tests: participant creation
// from an XML profile, ROS 2 topic-name mangling and the QoS profiles ROS 2 uses.
#pragma once

#include <cstdint>
#include <string>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>

namespace ppf::dds {

namespace fdds = eprosima::fastdds::dds;

// "/points" -> "rt/points" (ROS 2 prefixes every topic; the leading slash is dropped).
std::string RosTopicToDds(const std::string& ros_name);
// "rt/points" -> "/points"; a name without the prefix is returned with a leading slash.
std::string DdsTopicToRos(const std::string& dds_name);
// "sensor_msgs/msg/Imu" -> "sensor_msgs::msg::dds_::Imu_"; empty when not of the pkg/msg/Name form.
std::string RosTypeToDds(const std::string& ros_type);
// Inverse of RosTypeToDds; empty when the name is not a ROS 2 DDS type name.
std::string DdsTypeToRos(const std::string& dds_type);

struct ParticipantOptions {
  int domain_id = 0;
  // XML file to load (empty: rely on FASTRTPS_DEFAULT_PROFILES_FILE or the Fast DDS defaults).
  std::string profiles_file;
  // Participant profile to use (empty: the participant profile marked is_default_profile in
  // profiles_file, else the default participant QoS).
  std::string profile_name;
  std::string participant_name;
};

// The transport a tool (ppf_replay, ppf_record) uses when the user did not choose one. Fast DDS's
// own defaults lose most multi-MB clouds between processes (512 KB shared-memory segment), so
// without an explicit choice the tools load the project's SHM+UDP profile (shm_udp.xml), as the
// node presets do. An explicit choice wins: `options->profiles_file` already set (--profiles),
// FASTRTPS_DEFAULT_PROFILES_FILE in the environment or DEFAULT_FASTRTPS_PROFILES.xml in the
// working directory (both loaded by Fast DDS itself), or `fastdds_defaults` (--fastdds-defaults).
// Fills options->profiles_file / profile_name accordingly and returns one line for the log.
std::string ChooseToolTransport(bool fastdds_defaults, ParticipantOptions* options);

// Where the project's shm_udp.xml is: ppf_config's install (share/ppf_config/dds), found from
// the executable's install tree, else where ppf_config was at build time. Empty if neither exists.
std::string ProjectShmUdpProfile();
inline constexpr const char* kProjectShmUdpProfileName = "ppf_shm_udp";

// The profile_name of the <participant> marked is_default_profile="true" in the Fast DDS XML
// text (comments ignored); empty if there is none.
std::string DefaultParticipantProfileIn(const std::string& xml);

// Loads the XML (if any) and creates the participant. Returns nullptr with `error` set on failure
// (unreadable XML, unknown profile, domain id out of range).
fdds::DomainParticipant* CreateParticipant(const ParticipantOptions& options, std::string* error);

enum class Reliability { kBestEffort, kReliable };

// ROS 2 "sensor data": keep last 5, best effort, volatile.
fdds::DataReaderQos SensorReaderQos(Reliability reliability, int depth = 5);
fdds::DataWriterQos SensorWriterQos(Reliability reliability, int depth = 5);
// ROS 2 "default": keep last `depth` (10), reliable, volatile.
fdds::DataReaderQos DefaultReaderQos(int depth = 10);
fdds::DataWriterQos DefaultWriterQos(int depth = 10);
// /tf: keep last 100, reliable, volatile.
fdds::DataWriterQos TfWriterQos();
// Lossless: reliable keep-all (tests, recording). Writers block up to `max_blocking_ms` when the
// reader falls behind instead of dropping.
fdds::DataReaderQos KeepAllReaderQos();
fdds::DataWriterQos KeepAllWriterQos(int max_blocking_ms = 5000);

}  // namespace ppf::dds
