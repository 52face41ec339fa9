// Test-side DDS endpoints: a participant on the test profile, typed writers that report matches,
// and readers that collect every sample with its receive time; and the steps every cross-process
// test repeats (simulate a sequence, stop a node and read its summary, read a log). Includers
// define PPF_DDS_CONFIG_DIR (config/dds of the workspace).
#pragma once

#include <stdlib.h>

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
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

#include "ppf_dds_node/child_process.hpp"
#include "ppf_dds_node/dds_common.hpp"

namespace ppf::test {

namespace fdds = eprosima::fastdds::dds;

// The loopback transport profile every cross-process test runs on.
inline const char* const kProfiles = PPF_DDS_CONFIG_DIR "/test_loopback.xml";
inline const char* const kProfile = "ppf_test_loopback";
// UDP only: for tests that SIGKILL a participant (see the profile's comment).
inline const char* const kProfileUdp = "ppf_test_loopback_udp";

// This test binary (and the tools it starts, scripts/sanitize.sh) built with ThreadSanitizer or
// AddressSanitizer. gcc defines __SANITIZE_*__, clang answers __has_feature.
#if defined(__has_feature)
#define PPF_TEST_HAS_FEATURE(x) __has_feature(x)
#else
#define PPF_TEST_HAS_FEATURE(x) 0
#endif
#if defined(__SANITIZE_THREAD__) || PPF_TEST_HAS_FEATURE(thread_sanitizer)
inline constexpr bool kUnderTsan = true;
#else
inline constexpr bool kUnderTsan = false;
#endif
// ASan's allocator holds freed memory in a quarantine (256 MB by default) and its shadow grows with
// what is touched: a process's memory figures then say nothing about the node's own (the Release
// stage checks them).
#if defined(__SANITIZE_ADDRESS__) || PPF_TEST_HAS_FEATURE(address_sanitizer)
inline constexpr bool kUnderAsan = true;
#else
inline constexpr bool kUnderAsan = false;
#endif
#undef PPF_TEST_HAS_FEATURE

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

// Runs `sim` (ppf_sim) with `args` + "--out <bag>", stderr to `log`; success = exit 0 in 120 s.
inline ::testing::AssertionResult SimulateSequence(const std::string& sim,
                                                   std::vector<std::string> args,
                                                   const std::string& bag, const std::string& log) {
  if (sim.empty()) return ::testing::AssertionFailure() << "ppf_sim not found";
  args.insert(args.begin(), sim);
  args.push_back("--out");
  args.push_back(bag);
  ppf::dds::ChildProcess gen;
  if (!gen.Start(args, {}, log)) return ::testing::AssertionFailure() << "cannot start " << sim;
  if (!ppf::dds::ExitedWith(gen.Wait(std::chrono::seconds(120)), 0)) {
    return ::testing::AssertionFailure() << "ppf_sim failed, see " << log;
  }
  return ::testing::AssertionSuccess();
}

inline std::string ReadTextFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The last `n` lines of `text`.
inline std::string LastLines(const std::string& text, int n) {
  size_t start = text.size();  // one past the text's last line (its newline excluded)
  if (start > 0 && text[start - 1] == '\n') --start;
  for (int i = 0; i < n; ++i) {
    const size_t nl = start == 0 ? std::string::npos : text.rfind('\n', start - 1);
    if (nl == std::string::npos) return text;
    start = nl;
  }
  return text.substr(start + 1);
}

// Stops a running ppf_node with `signal` (it drains, flushes and reports), reads its
// PPF_NODE_SUMMARY line and expects exit status 0.
inline ::testing::AssertionResult StopNodeAndReadSummary(ppf::dds::ChildProcess& node,
                                                         std::string* summary,
                                                         int signal = SIGINT) {
  node.Signal(signal);
  const auto signalled = std::chrono::steady_clock::now();
  if (!node.WaitForLine("PPF_NODE_SUMMARY", summary, std::chrono::seconds(30))) {
    // An exit (a sanitizer report, a crash) and a stop that hangs are different bugs: say which,
    // with the end of the node's log (where it was, or the report).
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled)
                         .count();
    auto failure = ::testing::AssertionFailure();
    if (node.stdout_closed()) {
      failure << "ppf_node closed stdout " << s << " s after the signal without a "
              << "PPF_NODE_SUMMARY (exit status " << node.Wait(std::chrono::seconds(10)) << ")";
    } else {
      failure << "no PPF_NODE_SUMMARY within " << s << " s of the signal (still running)";
    }
    if (!node.stderr_file().empty()) {
      failure << "; end of " << node.stderr_file() << ":\n"
              << LastLines(ReadTextFile(node.stderr_file()), 40);
    }
    return failure;
  }
  const int status = node.Wait(std::chrono::seconds(10));
  if (!ppf::dds::ExitedWith(status, 0)) {
    return ::testing::AssertionFailure() << "ppf_node exit status " << status << " (want 0)";
  }
  return ::testing::AssertionSuccess();
}

// Lines of `text` containing `needle`.
inline int CountLinesWith(const std::string& text, const std::string& needle) {
  std::stringstream ss(text);
  std::string line;
  int n = 0;
  while (std::getline(ss, line)) n += line.find(needle) != std::string::npos;
  return n;
}

// Until ppf_node's log (stderr, `node_log`) says its /points and /imu readers matched `points`
// and `imu` writers. Our writer's on_publication_matched only says our side saw the node's
// reader; the node sees our writer independently, and what we send before that is dropped by its
// volatile reader without a trace (no sequence gap: it never saw the writer). Under ThreadSanitizer
// the node's side lagged by more than a 1.5 s IMU burst.
inline bool WaitForNodeInputsMatched(const std::string& node_log, int points, int imu,
                                     std::chrono::milliseconds timeout) {
  const std::string m = " publisher(s) matched";
  return WaitUntil(
      [&] {
        const std::string log = ReadTextFile(node_log);
        return CountLinesWith(log, "] points: " + std::to_string(points) + m) > 0 &&
               CountLinesWith(log, "] imu: " + std::to_string(imu) + m) > 0;
      },
      timeout);
}

// A "Vm...:" field of /proc/<pid>/status in kB (VmRSS, VmHWM), -1 if unreadable.
inline long ProcStatusKb(pid_t pid, const std::string& field) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field + ":", 0) == 0) return std::atol(line.c_str() + field.size() + 1);
  }
  return -1;
}

}  // namespace ppf::test
