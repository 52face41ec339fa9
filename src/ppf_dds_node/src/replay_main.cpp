// ppf_replay: publishes a rosbag2 bag (sqlite3 or MCAP) on DDS with its recorded timing, like
// `ros2 bag play`. Payloads go out byte for byte as stored (raw topic type with the ROS DDS type
// name), so any message type replays without being decoded.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "ppf_bag/bag.hpp"
#include "ppf_dds_node/cli.hpp"
#include "ppf_dds_node/dds_common.hpp"
#include "ppf_dds_node/logging.hpp"
#include "ppf_dds_node/raw_type.hpp"

namespace fdds = eprosima::fastdds::dds;
using ppf::dds::Level;
using ppf::dds::Log;
using ppf::dds::StopRequested;

namespace {

void Usage() {
  std::fprintf(
      stderr,
      "usage: ppf_replay --bag DIR [--rate R] [--loop] [--start SEC] [--topics T ...]\n"
      "                  [--remap FROM:=TO ...] [--best-effort] [--depth N]\n"
      "                  [--wait-matched SEC] [--delay SEC] [--linger SEC] [--domain ID]\n"
      "                  [--profiles XML] [--profile NAME] [--fastdds-defaults]\n"
      "  --rate R          playback speed factor (default 1)\n"
      "  --loop            start over at the end (until SIGINT)\n"
      "  --start SEC       skip the first SEC seconds of the bag\n"
      "  --topics T ...    only these topics (default: all)\n"
      "  --remap F:=T      publish topic F as T\n"
      "  --best-effort     best-effort writers (default reliable, which matches both\n"
      "                    reliable and best-effort readers)\n"
      "  --depth N         writer history depth per topic (default 50)\n"
      "  --wait-matched S  before playing, wait up to S s until every writer has a reader\n"
      "  --delay S         after --wait-matched saw every topic matched, wait S s more before\n"
      "                    playing (default 0.5): the subscribers match our writers on their own\n"
      "                    schedule (up to a discovery heartbeat, 3 s, late on a loaded machine)\n"
      "                    and drop what arrives before that\n"
      "  --linger S        keep the writers S s after the last message (default 1) so\n"
      "                    best-effort readers take the tail before the writers leave\n"
      "  --profiles XML    Fast DDS XML (default: FASTRTPS_DEFAULT_PROFILES_FILE if set, else\n"
      "                    the project's shm_udp.xml, which carries multi-MB clouds)\n"
      "  --fastdds-defaults  no XML: Fast DDS's built-in transports\n");
}

class MatchCounter : public fdds::DataWriterListener {
 public:
  void on_publication_matched(fdds::DataWriter*, const fdds::PublicationMatchedStatus& s) override {
    matched = s.current_count;
  }
  std::atomic<int> matched{0};
};

struct TopicOut {
  std::string ros_name;
  fdds::TypeSupport type;
  fdds::DataWriter* writer = nullptr;
  std::unique_ptr<MatchCounter> matches;
  uint64_t count = 0;
};

struct ReplayOptions {
  std::string bag_dir;
  double rate = 1.0, start_s = 0.0, wait_matched_s = 0.0, linger_s = 1.0, delay_s = 0.5;
  bool loop = false, best_effort = false;
  int depth = 50;
  std::vector<std::string> topics;
  std::map<std::string, std::string> remap;
  ppf::dds::DdsCliOptions dds;
};

// The command line into *o; -1 to go on, else the exit status (usage, help or a bad --remap).
int ParseArgs(int argc, char** argv, ReplayOptions* o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (ppf::dds::ParseDdsOption(argc, argv, &i, &o->dds)) continue;
    if (a == "--bag" && i + 1 < argc) {
      o->bag_dir = argv[++i];
    } else if (a == "--rate" && i + 1 < argc) {
      o->rate = std::atof(argv[++i]);
    } else if (a == "--start" && i + 1 < argc) {
      o->start_s = std::atof(argv[++i]);
    } else if (a == "--loop") {
      o->loop = true;
    } else if (a == "--best-effort") {
      o->best_effort = true;
    } else if (a == "--depth" && i + 1 < argc) {
      o->depth = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--wait-matched" && i + 1 < argc) {
      o->wait_matched_s = std::atof(argv[++i]);
    } else if (a == "--delay" && i + 1 < argc) {
      o->delay_s = std::max(0.0, std::atof(argv[++i]));
    } else if (a == "--linger" && i + 1 < argc) {
      o->linger_s = std::max(0.0, std::atof(argv[++i]));
    } else if (a == "--topics") {
      o->topics = ppf::dds::TakeList(argc, argv, &i);
    } else if (a == "--remap") {
      for (const std::string& r : ppf::dds::TakeList(argc, argv, &i)) {
        const size_t sep = r.find(":=");
        if (sep == std::string::npos) {
          Log(Level::kError, "--remap expects FROM:=TO, got '" + r + "'");
          return 2;
        }
        o->remap[r.substr(0, sep)] = r.substr(sep + 2);
      }
    } else {
      Usage();
      return a == "-h" || a == "--help" ? 0 : 2;
    }
  }
  if (o->bag_dir.empty() || !(o->rate > 0.0)) {
    Usage();
    return 2;
  }
  return -1;
}

// One raw writer per bag topic that can go on DDS (and is selected), into *outs by bag topic
// name. False (logged) if a writer cannot be created.
bool CreateWriters(const ppf::bag::BagInfo& info, const ReplayOptions& o,
                   fdds::DomainParticipant* participant, std::map<std::string, TopicOut>* outs) {
  fdds::Publisher* publisher = participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  for (const auto& t : info.topics) {
    if (!o.topics.empty() &&
        std::find(o.topics.begin(), o.topics.end(), t.info.name) == o.topics.end()) {
      continue;
    }
    const std::string dds_type = ppf::dds::RosTypeToDds(t.info.type);
    if (dds_type.empty() || t.info.serialization_format != "cdr") {
      Log(Level::kWarn, "skipping " + t.info.name + ": type '" + t.info.type + "' / format '" +
                            t.info.serialization_format + "' cannot go on DDS");
      continue;
    }
    TopicOut& out = (*outs)[t.info.name];
    const auto remapped = o.remap.find(t.info.name);
    out.ros_name = remapped != o.remap.end() ? remapped->second : t.info.name;
    out.type = fdds::TypeSupport(new ppf::dds::RawPubSubType(dds_type));
    out.type.register_type(participant);
    fdds::Topic* topic = participant->create_topic(ppf::dds::RosTopicToDds(out.ros_name), dds_type,
                                                   fdds::TOPIC_QOS_DEFAULT);
    out.matches = std::make_unique<MatchCounter>();
    const auto qos = ppf::dds::SensorWriterQos(
        o.best_effort ? ppf::dds::Reliability::kBestEffort : ppf::dds::Reliability::kReliable,
        o.depth);
    out.writer = topic ? publisher->create_datawriter(topic, qos, out.matches.get()) : nullptr;
    if (!out.writer) {
      Log(Level::kError, "cannot create writer for " + out.ros_name);
      return false;
    }
    Log(Level::kInfo, "replaying " + t.info.name + " -> " + ppf::dds::RosTopicToDds(out.ros_name) +
                          " [" + dds_type + "], " + std::to_string(t.message_count) + " messages");
  }
  return true;
}

// --wait-matched: until every writer has a reader (or the time is up), then --delay.
void WaitMatched(const ReplayOptions& o, const std::map<std::string, TopicOut>& outs) {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(o.wait_matched_s));
  bool all = false;
  while (!StopRequested() && !all && std::chrono::steady_clock::now() < deadline) {
    all = true;
    for (auto& [name, out] : outs) all = all && out.matches->matched > 0;
    if (!all) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (!all) Log(Level::kWarn, "not every topic has a subscriber; playing anyway");
  // Our writer matching a reader does not mean that reader has matched our writer yet (the
  // two directions of discovery complete independently); a sample sent in between is ignored
  // by the reader, without a trace. Give the other direction a moment (--delay).
  if (all) std::this_thread::sleep_for(std::chrono::duration<double>(o.delay_s));
}

struct PlayResult {
  uint64_t total = 0;
  int loops = 0;
  bool failed = false;
};

// Writes the bag's messages with their recorded timing (scaled by --rate), from --start, again
// and again with --loop, until the end or a signal.
PlayResult Play(const ReplayOptions& o, int64_t start_ns, ppf::bag::Reader* reader,
                std::map<std::string, TopicOut>* outs) {
  PlayResult result;
  ppf::dds::RawMessage raw;
  while (!StopRequested()) {
    const auto wall0 = std::chrono::steady_clock::now();
    int64_t bag0 = -1;
    ppf::bag::Message msg;
    try {
      while (!StopRequested() && reader->Next(msg)) {
        auto it = outs->find(msg.topic);
        if (it == outs->end()) continue;
        if (bag0 < 0) bag0 = msg.timestamp_ns;
        const double offset_s = static_cast<double>(msg.timestamp_ns - bag0) * 1e-9 / o.rate;
        const auto due = wall0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                     std::chrono::duration<double>(offset_s));
        std::this_thread::sleep_until(due);
        raw.payload = std::move(msg.data);
        if (!it->second.writer->write(&raw)) {
          Log(Level::kWarn, "write failed on " + it->second.ros_name);
        } else {
          ++it->second.count;
          ++result.total;
        }
      }
    } catch (const std::exception& e) {
      Log(Level::kError, e.what());
      result.failed = true;
      break;
    }
    ++result.loops;
    if (!o.loop || StopRequested()) break;
    reader->Seek(start_ns);  // rewinds; stamps loop back in time, the node must cope
  }
  return result;
}

void DeleteParticipant(fdds::DomainParticipant* participant) {
  participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
}

}  // namespace

int main(int argc, char** argv) {
  ReplayOptions o;
  const int parsed = ParseArgs(argc, argv, &o);
  if (parsed >= 0) return parsed;

  std::unique_ptr<ppf::bag::Reader> reader;
  try {
    reader = std::make_unique<ppf::bag::Reader>(o.bag_dir);
    if (!o.topics.empty()) reader->SetTopicFilter(o.topics);
  } catch (const std::exception& e) {
    Log(Level::kError, e.what());
    return 1;
  }
  const ppf::bag::BagInfo& info = reader->Info();

  ppf::dds::ParticipantOptions popt{o.dds.domain_id, o.dds.profiles_file, o.dds.profile_name,
                                    "ppf_replay"};
  Log(Level::kInfo, ppf::dds::ChooseToolTransport(o.dds.fastdds_defaults, &popt));
  std::string error;
  fdds::DomainParticipant* participant = ppf::dds::CreateParticipant(popt, &error);
  if (!participant) {
    Log(Level::kError, error);
    return 1;
  }
  std::map<std::string, TopicOut> outs;  // by bag topic name
  if (!CreateWriters(info, o, participant, &outs)) {
    DeleteParticipant(participant);
    return 1;
  }

  ppf::dds::StopOnSignals();
  if (o.wait_matched_s > 0.0) WaitMatched(o, outs);
  std::printf("PPF_REPLAY_START topics=%zu\n", outs.size());
  std::fflush(stdout);

  const int64_t start_ns = info.start_ns + static_cast<int64_t>(std::llround(o.start_s * 1e9));
  if (o.start_s > 0.0) reader->Seek(start_ns);
  const PlayResult played = Play(o, start_ns, reader.get(), &outs);
  // Reliable readers: let them fetch the tail before the writers disappear. Best-effort readers
  // do not acknowledge; when a writer goes away, a reader may discard its samples not yet taken,
  // so linger before deleting the writers.
  for (auto& [name, out] : outs) out.writer->wait_for_acknowledgments({5, 0});
  std::this_thread::sleep_for(std::chrono::duration<double>(o.linger_s));
  std::string counts;
  for (auto& [name, out] : outs) counts += " " + name + "=" + std::to_string(out.count);
  std::printf("PPF_REPLAY_DONE messages=%llu loops=%d%s\n", (unsigned long long)played.total,
              played.loops, counts.c_str());
  std::fflush(stdout);
  DeleteParticipant(participant);
  return played.failed ? 1 : 0;
}
