// Subscriber side of the cross-process transport test, run by test_transport via fork+exec.
// Prints "READY" once both readers are matched, then "RESULT ..." when everything arrived or the
// timeout expired. Every received sample is compared byte for byte with the regenerated original.
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "ppf_dds_node/dds_common.hpp"
#include "sensor_msgs/msg/ImuPubSubTypes.h"
#include "sensor_msgs/msg/PointCloud2PubSubTypes.h"
#include "transport_payload.hpp"

namespace fdds = eprosima::fastdds::dds;

namespace {

// The sequence numbers one stream delivered intact.
struct Stream {
  std::set<int> received;
  int last = -1;
};

struct Tally {
  std::mutex mutex;
  Stream clouds, imus;
  int corrupt = 0, duplicates = 0, out_of_order = 0;
};

// What identifies a sample and its regenerated original, per message type.
int SequenceNumber(const sensor_msgs::msg::PointCloud2& msg) { return msg.header().stamp().sec(); }
int SequenceNumber(const sensor_msgs::msg::Imu& msg) {
  return msg.header().stamp().sec() * 200 +
         static_cast<int>(msg.header().stamp().nanosec() / 5000000u);
}
bool Intact(const sensor_msgs::msg::PointCloud2& msg, int seq) {
  return seq >= 0 && seq < ppf::test::kTransportClouds && msg == ppf::test::MakeTransportCloud(seq);
}
bool Intact(const sensor_msgs::msg::Imu& msg, int seq) {
  return seq >= 0 && seq < ppf::test::kTransportImus && msg == ppf::test::MakeTransportImu(seq);
}
// A corrupt cloud is logged with its size (truncated or garbled); corrupt IMU samples are only
// counted.
void ReportCorrupt(const sensor_msgs::msg::PointCloud2& msg, int seq) {
  std::fprintf(stderr, "transport_peer: cloud seq %d corrupt (%zu bytes)\n", seq,
               msg.data().size());
}
void ReportCorrupt(const sensor_msgs::msg::Imu&, int) {}

// Checks every sample of one topic against its original and tallies it into `stream`.
template <typename MsgT>
class StreamListener : public fdds::DataReaderListener {
 public:
  StreamListener(Tally* t, Stream* s) : tally_(t), stream_(s) {}
  void on_data_available(fdds::DataReader* reader) override {
    MsgT msg;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&msg, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      const int seq = SequenceNumber(msg);
      const bool intact = Intact(msg, seq);
      std::lock_guard<std::mutex> lock(tally_->mutex);
      if (!intact) {
        ++tally_->corrupt;
        ReportCorrupt(msg, seq);
        continue;
      }
      if (!stream_->received.insert(seq).second) ++tally_->duplicates;
      if (seq < stream_->last) ++tally_->out_of_order;
      stream_->last = seq;
    }
  }
  void on_subscription_matched(fdds::DataReader*,
                               const fdds::SubscriptionMatchedStatus& s) override {
    matched = s.current_count;
  }
  std::atomic<int> matched{0};

 private:
  Tally* tally_;
  Stream* stream_;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    // PROFILES_XML / PROFILE_NAME may be "" (then FASTRTPS_DEFAULT_PROFILES_FILE applies).
    std::fprintf(stderr, "usage: %s DOMAIN PROFILES_XML PROFILE_NAME TIMEOUT_S\n", argv[0]);
    return 2;
  }
  ppf::dds::ParticipantOptions opt;
  opt.domain_id = std::atoi(argv[1]);
  opt.profiles_file = argv[2];
  opt.profile_name = argv[3];
  opt.participant_name = "transport_peer";
  const int timeout_s = std::atoi(argv[4]);

  std::string error;
  fdds::DomainParticipant* participant = ppf::dds::CreateParticipant(opt, &error);
  if (!participant) {
    std::printf("RESULT error=%s\n", error.c_str());
    std::fflush(stdout);
    return 3;
  }
  // What the profile gave us (the env-variable test checks this really is the XML's profile).
  {
    fdds::DomainParticipantQos q;
    participant->get_qos(q);
    std::printf("PROFILE builtin_transports=%d user_transports=%zu\n",
                q.transport().use_builtin_transports ? 1 : 0, q.transport().user_transports.size());
    std::fflush(stdout);
  }
  fdds::TypeSupport cloud_type(new sensor_msgs::msg::PointCloud2PubSubType());
  fdds::TypeSupport imu_type(new sensor_msgs::msg::ImuPubSubType());
  cloud_type.register_type(participant);
  imu_type.register_type(participant);
  fdds::Subscriber* sub = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  fdds::Topic* cloud_topic = participant->create_topic(
      "rt/ppf_test/points", cloud_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  fdds::Topic* imu_topic = participant->create_topic("rt/ppf_test/imu", imu_type.get_type_name(),
                                                     fdds::TOPIC_QOS_DEFAULT);
  Tally tally;
  StreamListener<sensor_msgs::msg::PointCloud2> cloud_listener(&tally, &tally.clouds);
  StreamListener<sensor_msgs::msg::Imu> imu_listener(&tally, &tally.imus);
  const fdds::DataReaderQos qos = ppf::dds::KeepAllReaderQos();
  sub->create_datareader(cloud_topic, qos, &cloud_listener);
  sub->create_datareader(imu_topic, qos, &imu_listener);

  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(timeout_s);
  bool ready_sent = false;
  bool complete = false;
  while (std::chrono::steady_clock::now() < deadline) {
    if (!ready_sent && cloud_listener.matched > 0 && imu_listener.matched > 0) {
      std::printf("READY\n");
      std::fflush(stdout);
      ready_sent = true;
    }
    {
      std::lock_guard<std::mutex> lock(tally.mutex);
      complete = static_cast<int>(tally.clouds.received.size()) == ppf::test::kTransportClouds &&
                 static_cast<int>(tally.imus.received.size()) == ppf::test::kTransportImus;
    }
    if (complete) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  {
    std::lock_guard<std::mutex> lock(tally.mutex);
    std::printf("RESULT clouds=%zu imus=%zu corrupt=%d duplicates=%d out_of_order=%d complete=%d\n",
                tally.clouds.received.size(), tally.imus.received.size(), tally.corrupt,
                tally.duplicates, tally.out_of_order, complete ? 1 : 0);
    std::fflush(stdout);
  }
  participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
  return complete ? 0 : 1;
}
