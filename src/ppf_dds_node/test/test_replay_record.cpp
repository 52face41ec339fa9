// ppf_replay -> DDS -> ppf_record across processes: payloads must come back byte for byte, for
// message types the tools know nothing about, in both storages, with remapping, topic filtering
// and --start.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "dds_test_util.hpp"
#include "ppf_bag/bag.hpp"
#include "ppf_bridge/convert.hpp"
#include "ppf_dds_node/child_process.hpp"
#include "ppf_dds_node/raw_type.hpp"
#include "ppf_msgs_cdr/cdr.hpp"
#include "ppf_msgs_cdr/time.hpp"
#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/PointCloud2.h"
#include "test_domain.hpp"

using namespace std::chrono_literals;
using ppf::dds::ChildProcess;
namespace fdds = eprosima::fastdds::dds;

namespace {

struct Stored {
  int64_t t;
  std::vector<uint8_t> data;
};
using Topics = std::map<std::string, std::vector<Stored>>;

// A std_msgs/String payload (a type outside our IDL set): CDR LE header + string, padded to 4
// as ROS does.
std::vector<uint8_t> StringPayload(const std::string& s) {
  std::vector<uint8_t> p = {0x00, 0x01, 0x00, 0x00};
  const uint32_t n = static_cast<uint32_t>(s.size() + 1);
  for (int i = 0; i < 4; ++i) p.push_back(static_cast<uint8_t>(n >> (8 * i)));
  p.insert(p.end(), s.begin(), s.end());
  p.push_back(0);
  while (p.size() % 4) p.push_back(0);
  return p;
}

Topics MakeBag(const std::string& dir, ppf::bag::Storage storage, int64_t t0) {
  Topics written;
  ppf::bag::WriterOptions o;
  o.storage = storage;
  ppf::bag::Writer w(dir, o);
  w.AddTopic({"/imu", "sensor_msgs/msg/Imu", "cdr", ""});
  w.AddTopic({"/chatter", "std_msgs/msg/String", "cdr", ""});
  w.AddTopic({"/points", "sensor_msgs/msg/PointCloud2", "cdr", ""});
  for (int i = 0; i < 60; ++i) {  // 0.6 s at 100 Hz
    const int64_t t = t0 + i * 10000000LL;
    sensor_msgs::msg::Imu imu;
    imu.header().stamp(ppf::msgs::TimeFromNanoseconds(t));
    imu.header().frame_id("imu");
    imu.angular_velocity().x(0.01 * i);
    imu.linear_acceleration().z(9.81);
    const auto payload = ppf::msgs::EncodeCdr(imu);
    w.Write("/imu", t, payload);
    written["/imu"].push_back({t, payload});
    if (i % 3 == 0) {
      const auto s = StringPayload("hello " + std::to_string(i));
      w.Write("/chatter", t + 1, s);
      written["/chatter"].push_back({t + 1, s});
    }
    if (i % 10 == 5) {
      sensor_msgs::msg::PointCloud2 c;
      c.header().stamp(ppf::msgs::TimeFromNanoseconds(t));
      c.header().frame_id("lidar");
      c.height(1);
      c.width(20000);
      c.point_step(16);
      c.row_step(16 * 20000);
      c.data().resize(16 * 20000);
      for (size_t k = 0; k < c.data().size(); ++k) c.data()[k] = static_cast<uint8_t>(k * 7 + i);
      const auto payload = ppf::msgs::EncodeCdr(c);
      w.Write("/points", t + 2, payload);
      written["/points"].push_back({t + 2, payload});
    }
  }
  w.Close();
  return written;
}

Topics ReadBag(const std::string& dir, std::map<std::string, std::string>* types) {
  Topics out;
  ppf::bag::Reader r(dir);
  for (const auto& t : r.Info().topics) (*types)[t.info.name] = t.info.type;
  ppf::bag::Message m;
  while (r.Next(m)) out[m.topic].push_back({m.timestamp_ns, m.data});
  return out;
}

// Records `topics` while ppf_replay plays `bag` with `replay_args`; returns the recorded bag dir.
std::string ReplayAndRecord(const std::string& bag, const std::string& out,
                            const std::vector<std::string>& topics,
                            const std::vector<std::string>& replay_args, const std::string& storage,
                            int salt) {
  const std::string domain = std::to_string(ppf::test::TestDomainId(salt));
  const std::vector<std::string> dds = {"--domain",           domain,      "--profiles",
                                        ppf::test::kProfiles, "--profile", ppf::test::kProfile};
  std::vector<std::string> rec = {PPF_RECORD_EXE, "--out", out, "--storage", storage, "--topics"};
  rec.insert(rec.end(), topics.begin(), topics.end());
  rec.insert(rec.end(), dds.begin(), dds.end());
  ChildProcess record, replay;
  EXPECT_TRUE(record.Start(rec, {}, out + ".record.log"));
  std::string line;
  EXPECT_TRUE(record.WaitForLine("PPF_RECORD_READY", &line, 20s));
  std::vector<std::string> play = {PPF_REPLAY_EXE, "--bag", bag, "--wait-matched", "15"};
  play.insert(play.end(), replay_args.begin(), replay_args.end());
  play.insert(play.end(), dds.begin(), dds.end());
  EXPECT_TRUE(replay.Start(play, {}, out + ".replay.log"));
  EXPECT_TRUE(replay.WaitForLine("PPF_REPLAY_DONE", &line, 40s)) << "see " << out << ".replay.log";
  EXPECT_TRUE(ppf::dds::ExitedWith(replay.Wait(10s), 0));
  // The replay waited for acknowledgements of its reliable writers before reporting DONE.
  record.Signal(SIGINT);
  EXPECT_TRUE(record.WaitForLine("PPF_RECORD_DONE", &line, 20s));
  EXPECT_TRUE(ppf::dds::ExitedWith(record.Wait(10s), 0));
  return out;
}

void ExpectSamePayloads(const std::vector<Stored>& want, const std::vector<Stored>& got,
                        const std::string& topic) {
  ASSERT_EQ(got.size(), want.size()) << topic;
  for (size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(got[i].data, want[i].data) << topic << " message " << i << " differs";
  }
}

}  // namespace

class ReplayRecord : public ::testing::TestWithParam<ppf::bag::Storage> {};

TEST_P(ReplayRecord, EveryPayloadComesBackByteForByteIncludingUnknownTypesAndRemaps) {
  const std::string dir = ppf::test::TempDir("ppf_dds_replay");
  const int64_t t0 = 1700000000LL * 1000000000LL;
  const Topics written = MakeBag(dir + "/in", GetParam(), t0);
  const bool mcap = GetParam() == ppf::bag::Storage::kMcap;
  ReplayAndRecord(dir + "/in", dir + "/out", {"/imu", "/talk", "/points"},
                  {"--remap", "/chatter:=/talk"}, mcap ? "sqlite3" : "mcap", mcap ? 31 : 32);
  std::map<std::string, std::string> types;
  const Topics got = ReadBag(dir + "/out", &types);
  EXPECT_EQ(types["/imu"], "sensor_msgs/msg/Imu");
  EXPECT_EQ(types["/talk"], "std_msgs/msg/String");  // from discovery, never decoded
  EXPECT_EQ(types["/points"], "sensor_msgs/msg/PointCloud2");
  EXPECT_EQ(got.count("/chatter"), 0u);
  ExpectSamePayloads(written.at("/imu"), got.count("/imu") ? got.at("/imu") : std::vector<Stored>{},
                     "/imu");
  ExpectSamePayloads(written.at("/chatter"),
                     got.count("/talk") ? got.at("/talk") : std::vector<Stored>{}, "/talk");
  ExpectSamePayloads(written.at("/points"),
                     got.count("/points") ? got.at("/points") : std::vector<Stored>{}, "/points");
  // Replay keeps the recorded timing: the recording spans about the bag's 0.59 s.
  if (got.count("/imu") && got.at("/imu").size() > 1) {
    const double span =
        1e-9 * static_cast<double>(got.at("/imu").back().t - got.at("/imu").front().t);
    EXPECT_NEAR(span, 0.59, 0.25);
  }
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

INSTANTIATE_TEST_SUITE_P(Storages, ReplayRecord,
                         ::testing::Values(ppf::bag::Storage::kSqlite3, ppf::bag::Storage::kMcap),
                         [](const auto& info) {
                           return std::string(ppf::bag::StorageIdentifier(info.param));
                         });

TEST(ReplayRecordOptions, TopicFilterStartAndRate) {
  const std::string dir = ppf::test::TempDir("ppf_dds_replay");
  const int64_t t0 = 1700000000LL * 1000000000LL;
  const Topics written = MakeBag(dir + "/in", ppf::bag::Storage::kMcap, t0);
  // Only /imu, from 0.3 s on, at 2x.
  ReplayAndRecord(dir + "/in", dir + "/out", {"/imu", "/chatter"},
                  {"--topics", "/imu", "--start", "0.3", "--rate", "2"}, "mcap", 33);
  std::map<std::string, std::string> types;
  const Topics got = ReadBag(dir + "/out", &types);
  EXPECT_EQ(got.count("/chatter"), 0u);
  std::vector<Stored> want;
  for (const auto& s : written.at("/imu")) {
    if (s.t >= t0 + 300000000LL) want.push_back(s);
  }
  ASSERT_EQ(want.size(), 30u);
  ExpectSamePayloads(want, got.count("/imu") ? got.at("/imu") : std::vector<Stored>{}, "/imu");
  if (got.count("/imu") && got.at("/imu").size() > 1) {
    const double span =
        1e-9 * static_cast<double>(got.at("/imu").back().t - got.at("/imu").front().t);
    EXPECT_NEAR(span, 0.29 / 2, 0.12);
  }
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

// A ROS 1 bag (Debian's rosbag, through ppf_bag's test writer) replays as ROS 2
// messages: the PointCloud2, Imu and Livox CustomMsg topics go out exactly as ppf_bag presents
// them (converted to CDR; the Livox clouds as PointCloud2), and a type without a ROS 2 form
// (std_msgs/String in ROS 1 serialization) is skipped with a warning.
TEST(ReplayRecordRos1, Ros1BagReplaysAsRos2Messages) {
  if (std::system("/usr/bin/python3 -c 'import rosbag, roslz4, sensor_msgs.msg' 2>/dev/null") !=
      0) {
    GTEST_SKIP() << "needs Debian's python3-rosbag and python3-sensor-msgs for /usr/bin/python3 "
                    "(apt-get install -y python3-rosbag python3-sensor-msgs)";
  }
  const std::string dir = ppf::test::TempDir("ppf_dds_replay");
  const std::string bag = dir + "/in.bag";
  ASSERT_EQ(
      std::system(("/usr/bin/python3 '" PPF_BAG_ROS1_WRITER "' '" + bag + "' lz4 4096 /dev/null 16")
                      .c_str()),
      0);
  std::map<std::string, std::string> in_types;
  Topics want = ReadBag(bag, &in_types);
  EXPECT_EQ(in_types["/chatter"], "std_msgs/String");
  // ppf_bag returns the CDR unpadded (as ppf_bridge encodes it); on DDS a sample is padded to a
  // multiple of 4 with zeros, as ROS 2 publishers send it (ROS2-INTEROP.md, wire format).
  for (auto& [topic, samples] : want) {
    for (auto& s : samples) s.data.resize((s.data.size() + 3) / 4 * 4, 0);
  }
  ReplayAndRecord(bag, dir + "/out", {"/imu", "/points", "/livox", "/chatter"}, {}, "mcap", 35);
  std::map<std::string, std::string> types;
  const Topics got = ReadBag(dir + "/out", &types);
  EXPECT_EQ(types["/imu"], "sensor_msgs/msg/Imu");
  EXPECT_EQ(types["/points"], "sensor_msgs/msg/PointCloud2");
  EXPECT_EQ(types["/livox"], "sensor_msgs/msg/PointCloud2");
  EXPECT_EQ(got.count("/chatter"), 0u);
  for (const char* topic : {"/imu", "/points", "/livox"}) {
    ASSERT_TRUE(want.count(topic)) << topic;
    ExpectSamePayloads(want.at(topic), got.count(topic) ? got.at(topic) : std::vector<Stored>{},
                       topic);
  }
  std::ifstream log(dir + "/out.replay.log");
  const std::string text((std::istreambuf_iterator<char>(log)), {});
  EXPECT_NE(text.find("skipping /chatter: type 'std_msgs/String' / format 'ros1'"),
            std::string::npos)
      << text;
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

// --loop plays the bag again until SIGINT; --types makes ppf_record subscribe before any writer
// is discovered (reliable keep-all), with the given type.
TEST(ReplayRecordOptions, LoopUntilInterruptedAndExplicitTypes) {
  const std::string dir = ppf::test::TempDir("ppf_dds_replay");
  const int64_t t0 = 1700000000LL * 1000000000LL;
  const Topics written = MakeBag(dir + "/in", ppf::bag::Storage::kSqlite3, t0);
  const std::string domain = std::to_string(ppf::test::TestDomainId(34));
  const std::vector<std::string> dds = {"--domain",           domain,      "--profiles",
                                        ppf::test::kProfiles, "--profile", ppf::test::kProfile};
  std::vector<std::string> rec = {PPF_RECORD_EXE,
                                  "--out",
                                  dir + "/out",
                                  "--topics",
                                  "/imu",
                                  "--types",
                                  "/imu:=sensor_msgs/msg/Imu"};
  rec.insert(rec.end(), dds.begin(), dds.end());
  ChildProcess record, replay;
  ASSERT_TRUE(record.Start(rec, {}, dir + "/record.log"));
  std::string line;
  ASSERT_TRUE(record.WaitForLine("PPF_RECORD_READY", &line, 20s));
  std::vector<std::string> play = {PPF_REPLAY_EXE, "--bag",  dir + "/in", "--topics",       "/imu",
                                   "--loop",       "--rate", "2",         "--wait-matched", "15"};
  play.insert(play.end(), dds.begin(), dds.end());
  ASSERT_TRUE(replay.Start(play, {}, dir + "/replay.log"));
  ASSERT_TRUE(replay.WaitForLine("PPF_REPLAY_START", &line, 20s));
  std::this_thread::sleep_for(1500ms);  // 0.3 s per pass at 2x: several passes
  replay.Signal(SIGINT);
  ASSERT_TRUE(replay.WaitForLine("PPF_REPLAY_DONE", &line, 20s));
  EXPECT_TRUE(ppf::dds::ExitedWith(replay.Wait(10s), 0));
  const int loops = std::atoi(line.c_str() + line.find("loops=") + 6);
  EXPECT_GE(loops, 2) << line;
  std::string done;
  record.Signal(SIGINT);
  ASSERT_TRUE(record.WaitForLine("PPF_RECORD_DONE", &done, 20s));
  EXPECT_TRUE(ppf::dds::ExitedWith(record.Wait(10s), 0));
  std::map<std::string, std::string> types;
  const Topics got = ReadBag(dir + "/out", &types);
  EXPECT_EQ(types["/imu"], "sensor_msgs/msg/Imu");
  ASSERT_TRUE(got.count("/imu"));
  const auto& imu = got.at("/imu");
  const size_t per_pass = written.at("/imu").size();
  EXPECT_GT(imu.size(), per_pass);
  // Every pass repeats the bag's payloads in order.
  for (size_t i = 0; i < imu.size(); ++i) {
    EXPECT_EQ(imu[i].data, written.at("/imu")[i % per_pass].data) << "message " << i;
    if (HasFailure()) break;
  }
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

// ppf_record must not hold its own lock while creating readers: Fast DDS calls the recorder's
// discovery callback (which takes that lock) with its discovery lock held, the lock reader
// creation needs, so a writer discovered while readers were being created would deadlock the
// recorder (nothing recorded, SIGINT ignored). Here the recorder joins a participant with many
// writers (one batch of readers to create) while this process keeps creating new writers, so
// discovery callbacks arrive throughout that batch; every round must record every message and
// stop on SIGINT.
TEST(ReplayRecordOptions, RecorderCreatingReadersWhileWritersAppearNeitherHangsNorLosesData) {
  constexpr int kTopics = 30;
  constexpr int kChurnTopics = 8;
  constexpr int kPerTopic = 3;
  constexpr int kRounds = 3;
  const std::string dir = ppf::test::TempDir("ppf_dds_record_race");
  const int domain = ppf::test::TestDomainId(40);
  ppf::dds::ParticipantOptions opt{domain, ppf::test::kProfiles, ppf::test::kProfile, "race_pub"};
  std::string error;
  fdds::DomainParticipant* participant = ppf::dds::CreateParticipant(opt, &error);
  ASSERT_NE(participant, nullptr) << error;
  fdds::TypeSupport type(new ppf::dds::RawPubSubType("std_msgs::msg::dds_::String_"));
  type.register_type(participant);
  fdds::Publisher* publisher = participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  // Reliable keep-all; heartbeats every 50 ms so each round's acknowledgements come back
  // promptly (the default period is 3 s).
  fdds::DataWriterQos wqos = ppf::dds::KeepAllWriterQos();
  wqos.reliable_writer_qos().times.heartbeatPeriod = eprosima::fastrtps::Duration_t(0, 50000000);
  std::vector<std::string> names;
  std::vector<fdds::DataWriter*> writers;
  std::vector<std::unique_ptr<ppf::test::WriterMatches>> matches;
  for (int k = 0; k < kTopics; ++k) {
    names.push_back("/race/t" + std::to_string(k));
    fdds::Topic* topic = participant->create_topic(ppf::dds::RosTopicToDds(names.back()),
                                                   type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
    matches.push_back(std::make_unique<ppf::test::WriterMatches>());
    writers.push_back(topic ? publisher->create_datawriter(topic, wqos, matches.back().get())
                            : nullptr);
    ASSERT_NE(writers.back(), nullptr);
  }
  std::vector<fdds::Topic*> churn_topics;
  for (int k = 0; k < kChurnTopics; ++k) {
    churn_topics.push_back(participant->create_topic(
        "rt/race/churn" + std::to_string(k), type.get_type_name(), fdds::TOPIC_QOS_DEFAULT));
    ASSERT_NE(churn_topics.back(), nullptr);
  }

  for (int round = 0; round < kRounds; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    // New writers (each one a discovery callback in the recorder) every few milliseconds while
    // the recorder starts and creates its readers.
    std::atomic<bool> churn{true};
    std::thread churner([&] {
      std::vector<fdds::DataWriter*> alive(kChurnTopics, nullptr);
      for (int i = 0; churn; ++i) {
        const int k = i % kChurnTopics;
        if (alive[k]) publisher->delete_datawriter(alive[k]);
        alive[k] = publisher->create_datawriter(churn_topics[k], fdds::DATAWRITER_QOS_DEFAULT);
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
      for (fdds::DataWriter* w : alive) {
        if (w) publisher->delete_datawriter(w);
      }
    });
    const std::string out = dir + "/out" + std::to_string(round);
    std::vector<std::string> rec = {PPF_RECORD_EXE, "--out", out, "--storage", "mcap", "--topics"};
    rec.insert(rec.end(), names.begin(), names.end());
    for (const std::string& a : {std::string("--domain"), std::to_string(domain),
                                 std::string("--profiles"), std::string(ppf::test::kProfiles),
                                 std::string("--profile"), std::string(ppf::test::kProfile)}) {
      rec.push_back(a);
    }
    ChildProcess record;
    ASSERT_TRUE(record.Start(rec, {}, out + ".record.log"));
    std::string line;
    EXPECT_TRUE(record.WaitForLine("PPF_RECORD_READY", &line, 20s));
    const bool all_matched = ppf::test::WaitUntil(
        [&] {
          for (const auto& m : matches) {
            if (m->matched < 1) return false;
          }
          return true;
        },
        10s);
    churn = false;
    churner.join();
    EXPECT_TRUE(all_matched) << "the recorder never subscribed to every topic (deadlocked?), see "
                             << out << ".record.log";
    // Our writers matched its readers; give its readers a moment to match our writers too.
    std::this_thread::sleep_for(300ms);
    for (int i = 0; i < kPerTopic; ++i) {
      for (int k = 0; k < kTopics; ++k) {
        ppf::dds::RawMessage raw;
        raw.payload = StringPayload("m" + std::to_string(i) + " of " + names[k]);
        EXPECT_TRUE(writers[k]->write(&raw));
      }
    }
    for (fdds::DataWriter* w : writers) w->wait_for_acknowledgments({5, 0});
    record.Signal(SIGINT);
    std::string done;
    ASSERT_TRUE(record.WaitForLine("PPF_RECORD_DONE", &done, 10s))
        << "ppf_record did not stop on SIGINT (deadlocked?), see " << out << ".record.log";
    EXPECT_TRUE(ppf::dds::ExitedWith(record.Wait(10s), 0));
    // Reliable keep-all on both sides, acknowledged: every message of every topic.
    for (const auto& n : names) {
      EXPECT_NE(done.find(" " + n + "=" + std::to_string(kPerTopic)), std::string::npos)
          << n << " in: " << done;
    }
    if (HasFailure()) break;
  }
  participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());
}

TEST(ReplayRecordOptions, BadArgumentsAreRejected) {
  ChildProcess p;
  ASSERT_TRUE(p.Start({PPF_REPLAY_EXE, "--bag", "/nonexistent/bag"}));
  EXPECT_TRUE(ppf::dds::ExitedWith(p.Wait(15s), 1));
  ChildProcess q;
  ASSERT_TRUE(q.Start({PPF_RECORD_EXE, "--topics", "/x"}));  // no --out
  EXPECT_TRUE(ppf::dds::ExitedWith(q.Wait(15s), 2));
  ChildProcess r;
  ASSERT_TRUE(r.Start({PPF_REPLAY_EXE, "--bag", "/tmp", "--remap", "nonsense"}));
  EXPECT_TRUE(ppf::dds::ExitedWith(r.Wait(15s), 2));
}
