// Test-side DDS endpoints: a participant on the test profile, typed writers that report matches,
// and readers that collect every sample with its receive time. Includers define
// PPF_DDS_CONFIG_DIR (config/dds of the workspace).
#pragma once

#include <stdlib.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "ppf_dds_node/dds_common.hpp"

namespace ppf::test {

namespace fdds = eprosima::fastdds::dds;

// The loopback transport profile every cross-process test runs on.
inline const char* const kProfiles = PPF_DDS_CONFIG_DIR "/test_loopback.xml";
inline const char* const kProfile = "ppf_test_loopback";

// A fresh directory /tmp/<prefix>_XXXXXX (mkdtemp); "/tmp" if it cannot be made.
inline std::string TempDir(const std::string& prefix) {
  std::string tmpl = "/tmp/" + prefix + "_XXXXXX";
  const char* d = mkdtemp(tmpl.data());
  return d ? d : "/tmp";
}

class WriterMatches : public fdds::DataWriterListener {
 public:
  void on_publication_matched(fdds::DataWriter*, const fdds::PublicationMatchedStatus& s) override {
    matched = s.current_count;
  }
  std::atomic<int> matched{0};
};

template <typename MsgT>
class Collector : public fdds::DataReaderListener {
 public:
  void on_data_available(fdds::DataReader* reader) override {
    MsgT msg;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&msg, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      std::lock_guard<std::mutex> lock(mutex_);
      samples_.push_back(msg);
    }
  }
  void on_subscription_matched(fdds::DataReader*,
                               const fdds::SubscriptionMatchedStatus& s) override {
    matched = s.current_count;
  }
  std::vector<MsgT> Samples() {
    std::lock_guard<std::mutex> lock(mutex_);
    return samples_;
  }
  size_t Count() {
    std::lock_guard<std::mutex> lock(mutex_);
    return samples_.size();
  }
  std::atomic<int> matched{0};

 private:
  std::mutex mutex_;
  std::vector<MsgT> samples_;
};

// One participant with helpers; deletes its entities on destruction.
class TestParticipant {
 public:
  TestParticipant(int domain, const std::string& profiles, const std::string& profile,
                  const std::string& name) {
    ppf::dds::ParticipantOptions o{domain, profiles, profile, name};
    participant_ = ppf::dds::CreateParticipant(o, &error);
    if (participant_) {
      publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
      subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
    }
  }
  ~TestParticipant() {
    if (participant_) {
      participant_->delete_contained_entities();
      fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
    }
  }
  bool ok() const { return participant_ != nullptr; }

  fdds::DataWriter* Writer(fdds::TopicDataType* type, const std::string& dds_topic,
                           const fdds::DataWriterQos& qos, WriterMatches* listener) {
    fdds::Topic* topic = Topic(type, dds_topic);
    return topic ? publisher_->create_datawriter(topic, qos, listener) : nullptr;
  }
  fdds::DataReader* Reader(fdds::TopicDataType* type, const std::string& dds_topic,
                           const fdds::DataReaderQos& qos, fdds::DataReaderListener* listener) {
    fdds::Topic* topic = Topic(type, dds_topic);
    return topic ? subscriber_->create_datareader(topic, qos, listener) : nullptr;
  }
  std::string error;

 private:
  fdds::Topic* Topic(fdds::TopicDataType* type, const std::string& dds_topic) {
    fdds::TypeSupport ts(type);
    ts.register_type(participant_);
    return participant_->create_topic(dds_topic, ts.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  }
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
};

template <typename Pred>
bool WaitUntil(Pred pred, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!pred()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

// "key=value" from a SUMMARY line; NaN if absent.
inline double SummaryField(const std::string& line, const std::string& key) {
  const size_t p = line.find(" " + key + "=");
  if (p == std::string::npos) return std::nan("");
  return std::atof(line.c_str() + p + key.size() + 2);
}

}  // namespace ppf::test
