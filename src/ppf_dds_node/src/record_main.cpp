// ppf_record: records DDS topics into a rosbag2 bag (MCAP or sqlite3), like `ros2 bag record`.
// Each topic's type comes from discovery (the first writer seen), or from --types / the node's
// known topics when given; the reader's reliability follows the discovered writer's so both
// reliable and best-effort publishers are recorded. Payloads are stored exactly as received.
#include <atomic>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
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
  std::fprintf(stderr,
               "usage: ppf_record --topics T ... --out DIR [--storage mcap|sqlite3]\n"
               "                  [--types T:=pkg/msg/Type ...] [--duration SEC]\n"
               "                  [--domain ID] [--profiles XML] [--profile NAME]\n"
               "                  [--fastdds-defaults]\n"
               "  records until SIGINT/SIGTERM (or --duration); DIR must not exist\n"
               "  --profiles XML      Fast DDS XML (default: FASTRTPS_DEFAULT_PROFILES_FILE if\n"
               "                      set, else the project's shm_udp.xml)\n"
               "  --fastdds-defaults  no XML: Fast DDS's built-in transports\n");
}

// Types of the topics ppf_node speaks, used to check what discovery reports.
const std::map<std::string, std::string>& KnownTypes() {
  static const std::map<std::string, std::string> k = {
      {"/points", "sensor_msgs/msg/PointCloud2"},
      {"/imu", "sensor_msgs/msg/Imu"},
      {"/odometry", "nav_msgs/msg/Odometry"},
      {"/odometry/imu", "nav_msgs/msg/Odometry"},
      {"/skeleton_planes", "ppf_msgs/msg/SkeletonPlaneArray"},
      {"/tf", "tf2_msgs/msg/TFMessage"},
      {"/path", "nav_msgs/msg/Path"},
      {"/registered_points", "sensor_msgs/msg/PointCloud2"},
  };
  return k;
}

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

class Recorder;

class RecordListener : public fdds::DataReaderListener {
 public:
  RecordListener(Recorder* r, std::string topic) : recorder_(r), topic_(std::move(topic)) {}
  void on_data_available(fdds::DataReader* reader) override;
  void on_subscription_matched(fdds::DataReader*,
                               const fdds::SubscriptionMatchedStatus& s) override;

 private:
  Recorder* recorder_;
  std::string topic_;
};

struct TopicState {
  std::string type;  // ROS type once known
  bool reader_created = false;
  bool creating = false;  // a reader is being created outside the recorder's lock
  uint64_t count = 0;
  fdds::TypeSupport type_support;
  std::unique_ptr<RecordListener> listener;
};

class Recorder : public fdds::DomainParticipantListener {
 public:
  Recorder(ppf::bag::Writer* writer, std::vector<std::string> topics,
           std::map<std::string, std::string> types)
      : writer_(writer), forced_types_(std::move(types)) {
    for (const auto& t : topics) topics_[t];
  }

  void Attach(fdds::DomainParticipant* participant, fdds::Subscriber* subscriber) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      participant_ = participant;
      subscriber_ = subscriber;
      // Topics whose type was given explicitly do not wait for discovery: reliable keep-all,
      // which matches reliable writers (every output of ppf_node). Best-effort writers are
      // matched once discovered (see on_publisher_discovery).
      for (auto& [name, st] : topics_) {
        auto f = forced_types_.find(name);
        if (f != forced_types_.end()) pending_.push_back({name, f->second, true});
      }
    }
    CreatePending();
  }

  void on_publisher_discovery(fdds::DomainParticipant*,
                              eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) override {
    if (info.status != eprosima::fastrtps::rtps::WriterDiscoveryInfo::DISCOVERED_WRITER) return;
    const std::string ros_topic = ppf::dds::DdsTopicToRos(info.info.topicName().to_string());
    const std::string dds_type = info.info.typeName().to_string();
    const bool reliable =
        info.info.m_qos.m_reliability.kind == eprosima::fastrtps::RELIABLE_RELIABILITY_QOS;
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = topics_.find(ros_topic);
    if (it == topics_.end() || subscriber_ == nullptr) return;
    const std::string ros_type = ppf::dds::DdsTypeToRos(dds_type);
    if (ros_type.empty()) {
      Log(Level::kWarn, ros_topic + ": writer with non-ROS type '" + dds_type + "' ignored");
      return;
    }
    if (it->second.reader_created || it->second.creating) {
      if (ros_type != it->second.type) {
        Log(Level::kWarn, ros_topic + ": writer of type " + ros_type + " ignored (recording " +
                              it->second.type + ")");
      }
      return;
    }
    auto known = KnownTypes().find(ros_topic);
    if (known != KnownTypes().end() && known->second != ros_type) {
      Log(Level::kWarn,
          ros_topic + ": discovered type " + ros_type + " differs from the usual " + known->second);
    }
    // Entities are not created inside a discovery callback (Fast DDS holds its discovery lock
    // here); the main loop creates them (CreatePending).
    pending_.push_back({ros_topic, ros_type, reliable});
  }

  // Creates the readers discovery asked for. Lock order: Fast DDS calls on_publisher_discovery
  // with its discovery (PDP) lock held and we then take mutex_; entity creation takes that same
  // discovery lock. So mutex_ is never held across a Fast DDS entity call: the work is claimed
  // under the lock, the entities are created without it, and the results are published under
  // it again. (Holding it across create_datareader deadlocked against a writer being discovered
  // at that moment.)
  void CreatePending() {
    struct Job {
      Pending request;
      RecordListener* listener;
      fdds::TypeSupport type_support;
      fdds::DataReader* reader = nullptr;
    };
    std::vector<Job> jobs;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (participant_ == nullptr || subscriber_ == nullptr) return;
      for (const Pending& p : pending_) {
        TopicState& st = topics_[p.topic];
        // `creating` keeps a writer discovered meanwhile from queueing the same topic again.
        if (st.reader_created || st.creating) continue;
        try {
          // Before the reader exists, so the first sample always has its topic in the bag.
          writer_->AddTopic(ppf::bag::TopicInfo{p.topic, p.type, "cdr", ""});
        } catch (const std::exception& e) {
          Log(Level::kError, e.what());
          continue;
        }
        st.creating = true;
        st.type = p.type;
        st.listener = std::make_unique<RecordListener>(this, p.topic);
        jobs.push_back({p, st.listener.get(), fdds::TypeSupport(), nullptr});
      }
      pending_.clear();
    }
    for (Job& job : jobs) job.reader = CreateReader(&job.request, job.listener, &job.type_support);
    std::lock_guard<std::mutex> lock(mutex_);
    for (Job& job : jobs) {
      TopicState& st = topics_[job.request.topic];
      st.creating = false;
      if (job.reader == nullptr) {
        Log(Level::kError, "cannot create reader for " + job.request.topic);
        continue;
      }
      st.reader_created = true;
      st.type_support = job.type_support;
      Log(Level::kInfo, "recording " + job.request.topic + " [" + job.request.type + "] " +
                            (job.request.reliable ? "reliable" : "best effort"));
    }
  }

  void Store(const std::string& topic, fdds::DataReader* reader) {
    ppf::dds::RawMessage raw;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&raw, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      std::lock_guard<std::mutex> lock(mutex_);
      if (closed_) return;
      try {
        writer_->Write(topic, NowNs(), raw.payload);
        ++topics_[topic].count;
      } catch (const std::exception& e) {
        Log(Level::kError, std::string("bag write failed: ") + e.what());
      }
    }
  }

  void Matched(const std::string& topic, int count) {
    std::printf("PPF_RECORD_MATCHED %s %d\n", topic.c_str(), count);
    std::fflush(stdout);
  }

  void Close() {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
  }

  std::string Counts() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::string s;
    for (auto& [name, st] : topics_) s += " " + name + "=" + std::to_string(st.count);
    return s;
  }

 private:
  struct Pending {
    std::string topic, type;
    bool reliable;
  };

  // Fast DDS calls only: must run without mutex_ (see CreatePending). participant_ and
  // subscriber_ are set once in Attach, before discovery starts.
  fdds::DataReader* CreateReader(const Pending* request, RecordListener* listener,
                                 fdds::TypeSupport* type_support) {
    const std::string dds_type = ppf::dds::RosTypeToDds(request->type);
    *type_support = fdds::TypeSupport(new ppf::dds::RawPubSubType(dds_type));
    type_support->register_type(participant_);
    fdds::Topic* topic = participant_->create_topic(ppf::dds::RosTopicToDds(request->topic),
                                                    dds_type, fdds::TOPIC_QOS_DEFAULT);
    if (topic == nullptr) return nullptr;
    fdds::DataReaderQos qos = ppf::dds::KeepAllReaderQos();
    if (!request->reliable) qos.reliability().kind = fdds::BEST_EFFORT_RELIABILITY_QOS;
    return subscriber_->create_datareader(topic, qos, listener);
  }

  std::mutex mutex_;
  ppf::bag::Writer* writer_;
  std::map<std::string, std::string> forced_types_;
  std::map<std::string, TopicState> topics_;
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
  bool closed_ = false;
  std::vector<Pending> pending_;
};

void RecordListener::on_data_available(fdds::DataReader* reader) {
  recorder_->Store(topic_, reader);
}
void RecordListener::on_subscription_matched(fdds::DataReader*,
                                             const fdds::SubscriptionMatchedStatus& s) {
  recorder_->Matched(topic_, s.current_count);
}

struct RecordOptions {
  std::vector<std::string> topics;           // ROS names, "/..."
  std::map<std::string, std::string> types;  // --types: topic -> ROS type
  std::string out_dir, storage = "mcap";
  double duration_s = 0.0;
  ppf::dds::DdsCliOptions dds;
};

// The command line into *o (topics as ROS names); -1 to go on, else the exit status.
int ParseArgs(int argc, char** argv, RecordOptions* o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (ppf::dds::ParseDdsOption(argc, argv, &i, &o->dds)) continue;
    if (a == "--topics") {
      o->topics = ppf::dds::TakeList(argc, argv, &i);
    } else if (a == "--types") {
      for (const std::string& t : ppf::dds::TakeList(argc, argv, &i)) {
        const size_t sep = t.find(":=");
        if (sep == std::string::npos || ppf::dds::RosTypeToDds(t.substr(sep + 2)).empty()) {
          Log(Level::kError, "--types expects /topic:=pkg/msg/Type, got '" + t + "'");
          return 2;
        }
        o->types[t.substr(0, sep)] = t.substr(sep + 2);
      }
    } else if (a == "--out" && i + 1 < argc) {
      o->out_dir = argv[++i];
    } else if (a == "--storage" && i + 1 < argc) {
      o->storage = argv[++i];
    } else if (a == "--duration" && i + 1 < argc) {
      o->duration_s = std::atof(argv[++i]);
    } else {
      Usage();
      return a == "-h" || a == "--help" ? 0 : 2;
    }
  }
  if (o->topics.empty() || o->out_dir.empty() ||
      (o->storage != "mcap" && o->storage != "sqlite3")) {
    Usage();
    return 2;
  }
  for (auto& t : o->topics) {
    if (t.rfind("rt/", 0) == 0) t = ppf::dds::DdsTopicToRos(t);
    if (t.empty() || t[0] != '/') t = "/" + t;
  }
  return -1;
}

// A participant created disabled: its listener must be attached before discovery starts (the
// caller attaches it, then enables the participant).
fdds::DomainParticipant* CreateDisabledParticipant(const ppf::dds::ParticipantOptions& popt,
                                                   std::string* error) {
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipantFactoryQos fqos;
  factory->get_qos(fqos);
  fqos.entity_factory().autoenable_created_entities = false;
  factory->set_qos(fqos);
  fdds::DomainParticipant* participant = ppf::dds::CreateParticipant(popt, error);
  fqos.entity_factory().autoenable_created_entities = true;
  factory->set_qos(fqos);
  return participant;
}

}  // namespace

int main(int argc, char** argv) {
  RecordOptions o;
  const int parsed = ParseArgs(argc, argv, &o);
  if (parsed >= 0) return parsed;

  std::unique_ptr<ppf::bag::Writer> writer;
  try {
    ppf::bag::WriterOptions wopt;
    wopt.storage = o.storage == "mcap" ? ppf::bag::Storage::kMcap : ppf::bag::Storage::kSqlite3;
    writer = std::make_unique<ppf::bag::Writer>(o.out_dir, wopt);
  } catch (const std::exception& e) {
    Log(Level::kError, e.what());
    return 1;
  }

  ppf::dds::StopOnSignals();

  Recorder recorder(writer.get(), o.topics, o.types);
  ppf::dds::ParticipantOptions popt{o.dds.domain_id, o.dds.profiles_file, o.dds.profile_name,
                                    "ppf_record"};
  Log(Level::kInfo, ppf::dds::ChooseToolTransport(o.dds.fastdds_defaults, &popt));
  // The participant listener must be attached before discovery starts: create the participant
  // disabled, attach, then enable.
  std::string error;
  fdds::DomainParticipant* participant = CreateDisabledParticipant(popt, &error);
  if (!participant) {
    Log(Level::kError, error);
    return 1;
  }
  // Mask none: discovery callbacks still arrive, but data events stay with the readers' own
  // listeners (a participant listener with DATA_ON_READERS enabled would swallow them).
  participant->set_listener(&recorder, fdds::StatusMask::none());
  fdds::Subscriber* subscriber = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  recorder.Attach(participant, subscriber);
  participant->enable();
  std::printf("PPF_RECORD_READY\n");
  std::fflush(stdout);

  const auto t0 = std::chrono::steady_clock::now();
  while (!StopRequested()) {
    if (o.duration_s > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() >=
            o.duration_s) {
      break;
    }
    recorder.CreatePending();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // Stop storing before the entities go away, then finish the bag.
  participant->set_listener(nullptr);
  participant->delete_contained_entities();
  recorder.Close();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
  int rc = 0;
  try {
    writer->Close();
  } catch (const std::exception& e) {
    Log(Level::kError, e.what());
    rc = 1;
  }
  std::printf("PPF_RECORD_DONE%s\n", recorder.Counts().c_str());
  std::fflush(stdout);
  return rc;
}
