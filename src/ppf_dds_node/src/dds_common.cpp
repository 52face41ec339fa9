#include "ppf_dds_node/dds_common.hpp"

#include <unistd.h>

#include <cctype>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>

namespace ppf::dds {

std::string RosTopicToDds(const std::string& ros_name) {
  if (ros_name.rfind("rt/", 0) == 0) return ros_name;  // already mangled
  std::string name = ros_name;
  while (!name.empty() && name.front() == '/') name.erase(name.begin());
  return "rt/" + name;
}

std::string DdsTopicToRos(const std::string& dds_name) {
  if (dds_name.rfind("rt/", 0) == 0) return "/" + dds_name.substr(3);
  if (!dds_name.empty() && dds_name.front() == '/') return dds_name;
  return "/" + dds_name;
}

std::string RosTypeToDds(const std::string& ros_type) {
  const size_t a = ros_type.find('/');
  if (a == std::string::npos) return "";
  const size_t b = ros_type.find('/', a + 1);
  if (b == std::string::npos || ros_type.find('/', b + 1) != std::string::npos) return "";
  const std::string pkg = ros_type.substr(0, a);
  const std::string kind = ros_type.substr(a + 1, b - a - 1);
  const std::string name = ros_type.substr(b + 1);
  if (pkg.empty() || kind.empty() || name.empty()) return "";
  return pkg + "::" + kind + "::dds_::" + name + "_";
}

std::string DdsTypeToRos(const std::string& dds_type) {
  // pkg::kind::dds_::Name_
  const size_t a = dds_type.find("::");
  if (a == std::string::npos) return "";
  const size_t b = dds_type.find("::", a + 2);
  if (b == std::string::npos) return "";
  const std::string rest = dds_type.substr(b + 2);
  if (rest.rfind("dds_::", 0) != 0) return "";
  std::string name = rest.substr(6);
  if (name.size() < 2 || name.back() != '_' || name.find("::") != std::string::npos) return "";
  name.pop_back();
  return dds_type.substr(0, a) + "/" + dds_type.substr(a + 2, b - a - 2) + "/" + name;
}

namespace {

bool Readable(const std::string& path) { return std::ifstream(path).good(); }

std::string ExeDir() {
  char self[4096];
  const ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n <= 0) return "";
  self[n] = '\0';
  const std::string path(self);
  return path.substr(0, path.rfind('/'));
}

}  // namespace

std::string ProjectShmUdpProfile() {
  // ppf_config installs the profiles. Looked up from the executable first, so that an install
  // tree moved elsewhere (a container image) still finds its own: a merged install puts both
  // packages under one prefix, colcon's default isolated install puts them side by side.
  // Build-tree binaries (tests) have neither and use where ppf_config was found at build time.
  const std::string exe = ExeDir();
  for (const std::string& dir :
       {exe + "/../share/ppf_config/dds", exe + "/../../ppf_config/share/ppf_config/dds",
        std::string(PPF_CONFIG_DDS_DIR)}) {
    const std::string path = dir + "/shm_udp.xml";
    if (Readable(path)) return path;
  }
  return "";
}

std::string ChooseToolTransport(bool fastdds_defaults, ParticipantOptions* options) {
  if (!options->profiles_file.empty()) return "DDS profiles: " + options->profiles_file;
  const char* env = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  if (env != nullptr && env[0] != '\0') {
    return std::string("DDS profiles: ") + env + " (FASTRTPS_DEFAULT_PROFILES_FILE)";
  }
  if (Readable("DEFAULT_FASTRTPS_PROFILES.xml")) {
    return "DDS profiles: ./DEFAULT_FASTRTPS_PROFILES.xml (loaded by Fast DDS)";
  }
  if (fastdds_defaults) {
    return "DDS profiles: none, Fast DDS defaults (--fastdds-defaults): clouds over ~512 KB may "
           "be lost between processes";
  }
  const std::string project = ProjectShmUdpProfile();
  if (project.empty()) {
    return "DDS profiles: project shm_udp.xml not found, Fast DDS defaults: clouds over ~512 KB "
           "may be lost between processes (give --profiles)";
  }
  options->profiles_file = project;
  if (options->profile_name.empty()) options->profile_name = kProjectShmUdpProfileName;
  return "DDS profiles: " + project +
         " (project default; --profiles, "
         "FASTRTPS_DEFAULT_PROFILES_FILE or --fastdds-defaults to change)";
}

std::string DefaultParticipantProfileIn(const std::string& xml) {
  // Plain scanning, not std::regex: libstdc++'s regex recurses per character and a long comment
  // in a user's file could exhaust the stack.
  std::string text;
  for (size_t pos = 0; pos < xml.size();) {
    const size_t open = xml.find("<!--", pos);
    text += xml.substr(pos, open == std::string::npos ? std::string::npos : open - pos);
    if (open == std::string::npos) break;
    const size_t close = xml.find("-->", open + 4);
    pos = close == std::string::npos ? xml.size() : close + 3;
  }
  // The value of attribute `key` in a tag's attribute text, "" if absent.
  auto attribute = [](const std::string& attrs, const std::string& key) -> std::string {
    for (size_t at = attrs.find(key); at != std::string::npos; at = attrs.find(key, at + 1)) {
      if (at > 0 && !std::isspace(static_cast<unsigned char>(attrs[at - 1]))) continue;
      size_t i = at + key.size();
      while (i < attrs.size() && std::isspace(static_cast<unsigned char>(attrs[i]))) ++i;
      if (i >= attrs.size() || attrs[i] != '=') continue;
      ++i;
      while (i < attrs.size() && std::isspace(static_cast<unsigned char>(attrs[i]))) ++i;
      if (i >= attrs.size() || (attrs[i] != '"' && attrs[i] != '\'')) continue;
      const size_t end = attrs.find(attrs[i], i + 1);
      if (end == std::string::npos) return "";
      return attrs.substr(i + 1, end - i - 1);
    }
    return "";
  };
  const std::string tag = "<participant";
  for (size_t at = text.find(tag); at != std::string::npos; at = text.find(tag, at + 1)) {
    const size_t after = at + tag.size();
    if (after >= text.size() || !std::isspace(static_cast<unsigned char>(text[after]))) continue;
    const size_t close = text.find('>', after);
    if (close == std::string::npos) break;
    const std::string attrs = text.substr(after, close - after);
    if (attribute(attrs, "is_default_profile") == "true") return attribute(attrs, "profile_name");
  }
  return "";
}

fdds::DomainParticipant* CreateParticipant(const ParticipantOptions& options, std::string* error) {
  auto fail = [error](const std::string& why) -> fdds::DomainParticipant* {
    if (error) *error = why;
    return nullptr;
  };
  // Fast DDS maps domain ids to UDP ports (7400 + 250 * id): ids above 232 overflow.
  if (options.domain_id < 0 || options.domain_id > 232) {
    return fail("domain id " + std::to_string(options.domain_id) + " outside 0..232");
  }
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  // Loads FASTRTPS_DEFAULT_PROFILES_FILE (or DEFAULT_FASTRTPS_PROFILES.xml) once and makes its
  // default profile the default participant QoS; without this, the QoS read below would be the
  // built-in default until the first create_participant call.
  factory->load_profiles();
  if (!options.profiles_file.empty()) {
    if (!std::ifstream(options.profiles_file).good()) {
      return fail("cannot read DDS profiles file '" + options.profiles_file + "'");
    }
    if (factory->load_XML_profiles_file(options.profiles_file) != ReturnCode_t::RETCODE_OK) {
      return fail("Fast DDS rejected profiles file '" + options.profiles_file + "'");
    }
  }
  // A file loaded after the factory came up does not replace the default participant QoS
  // (load_profiles() acts once, for FASTRTPS_DEFAULT_PROFILES_FILE): without a profile name the
  // file's own default profile is looked up by name. Otherwise `--profiles shm_udp.xml` alone
  // ran on the built-in transports, which lose most clouds over 512 KB.
  std::string profile = options.profile_name;
  if (profile.empty() && !options.profiles_file.empty()) {
    std::ifstream in(options.profiles_file);
    std::stringstream text;
    text << in.rdbuf();
    profile = DefaultParticipantProfileIn(text.str());
  }
  fdds::DomainParticipantQos qos = factory->get_default_participant_qos();
  if (!profile.empty()) {
    if (factory->get_participant_qos_from_profile(profile, qos) != ReturnCode_t::RETCODE_OK) {
      return fail("no participant profile '" + profile + "' (profiles file '" +
                  options.profiles_file + "')");
    }
  }
  if (!options.participant_name.empty()) qos.name(options.participant_name);
  fdds::DomainParticipant* participant =
      factory->create_participant(static_cast<fdds::DomainId_t>(options.domain_id), qos);
  if (participant == nullptr) return fail("create_participant failed");
  return participant;
}

namespace {

template <typename QosT>
void SetCommon(QosT* qos, Reliability reliability, int depth) {
  qos->reliability().kind = reliability == Reliability::kReliable
                                ? fdds::RELIABLE_RELIABILITY_QOS
                                : fdds::BEST_EFFORT_RELIABILITY_QOS;
  qos->durability().kind = fdds::VOLATILE_DURABILITY_QOS;
  qos->history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  qos->history().depth = depth;
  // Unbounded types (clouds): grow payload buffers on demand instead of preallocating the
  // type's nominal maximum for every history slot.
  qos->endpoint().history_memory_policy =
      eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
}

}  // namespace

fdds::DataReaderQos SensorReaderQos(Reliability reliability, int depth) {
  fdds::DataReaderQos qos = fdds::DATAREADER_QOS_DEFAULT;
  SetCommon(&qos, reliability, depth);
  return qos;
}

fdds::DataWriterQos SensorWriterQos(Reliability reliability, int depth) {
  fdds::DataWriterQos qos = fdds::DATAWRITER_QOS_DEFAULT;
  SetCommon(&qos, reliability, depth);
  return qos;
}

fdds::DataReaderQos DefaultReaderQos(int depth) {
  return SensorReaderQos(Reliability::kReliable, depth);
}

fdds::DataWriterQos DefaultWriterQos(int depth) {
  return SensorWriterQos(Reliability::kReliable, depth);
}

fdds::DataWriterQos TfWriterQos() { return SensorWriterQos(Reliability::kReliable, 100); }

fdds::DataReaderQos KeepAllReaderQos() {
  fdds::DataReaderQos qos = SensorReaderQos(Reliability::kReliable, 1);
  qos.history().kind = fdds::KEEP_ALL_HISTORY_QOS;
  qos.resource_limits().max_samples = 100000;
  qos.resource_limits().max_instances = 1;
  qos.resource_limits().max_samples_per_instance = 100000;
  return qos;
}

fdds::DataWriterQos KeepAllWriterQos(int max_blocking_ms) {
  fdds::DataWriterQos qos = SensorWriterQos(Reliability::kReliable, 1);
  qos.history().kind = fdds::KEEP_ALL_HISTORY_QOS;
  qos.resource_limits().max_samples = 100000;
  qos.resource_limits().max_instances = 1;
  qos.resource_limits().max_samples_per_instance = 100000;
  qos.reliability().max_blocking_time =
      eprosima::fastrtps::Duration_t(max_blocking_ms / 1000, (max_blocking_ms % 1000) * 1000000u);
  return qos;
}

}  // namespace ppf::dds
