// Cross-process transport: this process publishes 20 PointCloud2 of 2 MiB and 200 Imu over the
// XML profile; a separate process (transport_peer, fork+exec) subscribes and checks every byte.
// Reliable keep-all on both sides, so anything short of "all, intact, in order" is a failure.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "ppf_dds_node/child_process.hpp"
#include "ppf_dds_node/dds_common.hpp"
#include "sensor_msgs/msg/ImuPubSubTypes.h"
#include "sensor_msgs/msg/PointCloud2PubSubTypes.h"
#include "test_domain.hpp"
#include "transport_payload.hpp"

namespace fdds = eprosima::fastdds::dds;
using namespace std::chrono_literals;

namespace {

class MatchCounter : public fdds::DataWriterListener {
 public:
  void on_publication_matched(fdds::DataWriter*, const fdds::PublicationMatchedStatus& s) override {
    matched = s.current_count;
  }
  std::atomic<int> matched{0};
};

struct Publisher {
  fdds::DomainParticipant* participant = nullptr;
  fdds::DataWriter* cloud_writer = nullptr;
  fdds::DataWriter* imu_writer = nullptr;
  MatchCounter cloud_matches, imu_matches;

  ~Publisher() {
    if (participant) {
      participant->delete_contained_entities();
      fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
    }
  }
};

// The subscriber uses `peer_profiles_file` / `peer_profile` (default: the publisher's) and
// `peer_env` (e.g. FASTRTPS_DEFAULT_PROFILES_FILE).
void RunTransportTest(const std::string& profiles_file, const std::string& profile_name,
                      int domain_salt, const std::string* peer_profiles_file = nullptr,
                      const std::string* peer_profile = nullptr,
                      const std::vector<std::string>& peer_env = {},
                      int expect_user_transports = -1) {
  const int domain = ppf::test::TestDomainId(domain_salt);
  Publisher pub;
  ppf::dds::ParticipantOptions opt;
  opt.domain_id = domain;
  opt.profiles_file = profiles_file;
  opt.profile_name = profile_name;
  opt.participant_name = "transport_test_pub";
  std::string error;
  pub.participant = ppf::dds::CreateParticipant(opt, &error);
  ASSERT_NE(pub.participant, nullptr) << error;

  fdds::TypeSupport cloud_type(new sensor_msgs::msg::PointCloud2PubSubType());
  fdds::TypeSupport imu_type(new sensor_msgs::msg::ImuPubSubType());
  ASSERT_EQ(cloud_type.get_type_name(), "sensor_msgs::msg::dds_::PointCloud2_");
  cloud_type.register_type(pub.participant);
  imu_type.register_type(pub.participant);
  fdds::Publisher* publisher = pub.participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  fdds::Topic* cloud_topic = pub.participant->create_topic(
      "rt/ppf_test/points", cloud_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  fdds::Topic* imu_topic = pub.participant->create_topic(
      "rt/ppf_test/imu", imu_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  const fdds::DataWriterQos wqos = ppf::dds::KeepAllWriterQos(10000);
  pub.cloud_writer = publisher->create_datawriter(cloud_topic, wqos, &pub.cloud_matches);
  pub.imu_writer = publisher->create_datawriter(imu_topic, wqos, &pub.imu_matches);
  ASSERT_NE(pub.cloud_writer, nullptr);
  ASSERT_NE(pub.imu_writer, nullptr);

  ppf::dds::ChildProcess peer;
  ASSERT_TRUE(peer.Start({PPF_TRANSPORT_PEER, std::to_string(domain),
                          peer_profiles_file ? *peer_profiles_file : profiles_file,
                          peer_profile ? *peer_profile : profile_name, "40"},
                         peer_env));
  std::string line;
  std::vector<std::string> seen;
  ASSERT_TRUE(peer.WaitForLine("PROFILE", &line, 20s, &seen));
  if (expect_user_transports >= 0) {
    EXPECT_EQ(line, "PROFILE builtin_transports=0 user_transports=" +
                        std::to_string(expect_user_transports));
  }
  ASSERT_TRUE(peer.WaitForLine("READY", &line, 20s, &seen))
      << "subscriber process never matched (domain " << domain << ")";
  // The subscriber matched us; wait for our side too, so nothing is sent to an unknown reader.
  const auto match_deadline = std::chrono::steady_clock::now() + 10s;
  while ((pub.cloud_matches.matched < 1 || pub.imu_matches.matched < 1) &&
         std::chrono::steady_clock::now() < match_deadline) {
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_GE(pub.cloud_matches.matched, 1);
  ASSERT_GE(pub.imu_matches.matched, 1);

  // Interleave as a driver would: 10 IMU samples per cloud.
  int imu_seq = 0;
  for (int c = 0; c < ppf::test::kTransportClouds; ++c) {
    sensor_msgs::msg::PointCloud2 cloud = ppf::test::MakeTransportCloud(c);
    ASSERT_TRUE(pub.cloud_writer->write(&cloud)) << "cloud " << c;
    for (int k = 0; k < ppf::test::kTransportImus / ppf::test::kTransportClouds; ++k) {
      sensor_msgs::msg::Imu imu = ppf::test::MakeTransportImu(imu_seq++);
      ASSERT_TRUE(pub.imu_writer->write(&imu)) << "imu " << imu_seq - 1;
    }
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_EQ(pub.cloud_writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(10, 0)),
            ReturnCode_t::RETCODE_OK);
  EXPECT_EQ(pub.imu_writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(3, 0)),
            ReturnCode_t::RETCODE_OK);

  // The peer reports at the latest 40 s after it started, complete or not.
  ASSERT_TRUE(peer.WaitForLine("RESULT", &line, 45s, &seen)) << "no result from subscriber";
  std::printf("%s\n", line.c_str());
  std::ostringstream expected;
  expected << "RESULT clouds=" << ppf::test::kTransportClouds
           << " imus=" << ppf::test::kTransportImus
           << " corrupt=0 duplicates=0 out_of_order=0 complete=1";
  EXPECT_EQ(line, expected.str());
  EXPECT_TRUE(ppf::dds::ExitedWith(peer.Wait(10s), 0));
}

}  // namespace

TEST(Transport, ShmUdpLoopbackProfileDeliversEveryCloudAndImuAcrossProcesses) {
  RunTransportTest(PPF_DDS_CONFIG_DIR "/test_loopback.xml", "ppf_test_loopback", 0);
}

// The container/multi-host profile must carry the same load (UDP only, 8 MB buffers). Discovery
// is multicast there, as in deployment.
TEST(Transport, UdpOnlyProfileDeliversEveryCloudAndImuAcrossProcesses) {
  RunTransportTest(PPF_DDS_CONFIG_DIR "/udp_only.xml", "ppf_udp_only", 1);
}

// The other way to load the profiles: FASTRTPS_DEFAULT_PROFILES_FILE and no profile name, as
// any Fast DDS 2.x program (or ros2 with rmw_fastrtps) would. The subscriber must get the XML's
// default profile: builtin transports off, our SHM + UDP transports.
TEST(Transport, ProfileFromEnvironmentVariableIsTheDefault) {
  const std::string none;
  RunTransportTest(PPF_DDS_CONFIG_DIR "/test_loopback.xml", "ppf_test_loopback", 3, &none, &none,
                   {"FASTRTPS_DEFAULT_PROFILES_FILE=" PPF_DDS_CONFIG_DIR "/test_loopback.xml"}, 2);
}

TEST(Transport, UnknownProfileIsReportedNotIgnored) {
  ppf::dds::ParticipantOptions opt;
  opt.domain_id = ppf::test::TestDomainId(2);
  opt.profiles_file = PPF_DDS_CONFIG_DIR "/test_loopback.xml";
  opt.profile_name = "no_such_profile";
  std::string error;
  EXPECT_EQ(ppf::dds::CreateParticipant(opt, &error), nullptr);
  EXPECT_NE(error.find("no_such_profile"), std::string::npos) << error;
  opt.profile_name = "";
  opt.profiles_file = "/nonexistent/profile.xml";
  EXPECT_EQ(ppf::dds::CreateParticipant(opt, &error), nullptr);
  EXPECT_NE(error.find("cannot read"), std::string::npos) << error;
}

// ppf_replay / ppf_record without a transport choice must not fall back to Fast DDS's defaults
// (they lose most multi-MB clouds); any explicit choice still wins.
TEST(Transport, ToolsDefaultToTheProjectShmUdpProfileUnlessToldOtherwise) {
  const char* saved_env = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  const std::string saved = saved_env ? saved_env : "";
  unsetenv("FASTRTPS_DEFAULT_PROFILES_FILE");

  ppf::dds::ParticipantOptions none;
  std::string note = ppf::dds::ChooseToolTransport(false, &none);
  ASSERT_FALSE(ppf::dds::ProjectShmUdpProfile().empty());
  EXPECT_EQ(none.profiles_file, ppf::dds::ProjectShmUdpProfile());
  EXPECT_EQ(none.profiles_file.substr(none.profiles_file.size() - 12), "/shm_udp.xml");
  EXPECT_EQ(none.profile_name, "ppf_shm_udp");
  EXPECT_NE(note.find("project default"), std::string::npos) << note;
  std::string error;
  none.domain_id = ppf::test::TestDomainId(5);
  fdds::DomainParticipant* p = ppf::dds::CreateParticipant(none, &error);
  ASSERT_NE(p, nullptr) << error;
  fdds::DomainParticipantQos qos;
  p->get_qos(qos);
  EXPECT_FALSE(qos.transport().use_builtin_transports);
  EXPECT_EQ(qos.transport().user_transports.size(), 2u);  // ppf_shm + ppf_udp
  fdds::DomainParticipantFactory::get_instance()->delete_participant(p);

  ppf::dds::ParticipantOptions explicit_file;
  explicit_file.profiles_file = PPF_DDS_CONFIG_DIR "/udp_only.xml";
  ppf::dds::ChooseToolTransport(false, &explicit_file);
  EXPECT_EQ(explicit_file.profiles_file, PPF_DDS_CONFIG_DIR "/udp_only.xml");
  EXPECT_EQ(explicit_file.profile_name, "");

  // `ppf_replay --profiles shm_udp.xml` (no --profile): the file's default profile applies, not
  // Fast DDS's built-in transports. The old code created this participant with the built-in
  // transports and lost most VLP-16 clouds (0.9 MB) in scripts/soak.sh.
  for (const char* file : {"/shm_udp.xml", "/udp_only.xml"}) {
    ppf::dds::ParticipantOptions file_only;
    file_only.profiles_file = std::string(PPF_DDS_CONFIG_DIR) + file;
    file_only.domain_id = ppf::test::TestDomainId(5);
    p = ppf::dds::CreateParticipant(file_only, &error);
    ASSERT_NE(p, nullptr) << error;
    p->get_qos(qos);
    EXPECT_FALSE(qos.transport().use_builtin_transports) << file;
    EXPECT_EQ(qos.transport().user_transports.size(), std::string(file) == "/shm_udp.xml" ? 2u : 1u)
        << file;
    fdds::DomainParticipantFactory::get_instance()->delete_participant(p);
  }

  ppf::dds::ParticipantOptions defaults;
  note = ppf::dds::ChooseToolTransport(true, &defaults);
  EXPECT_EQ(defaults.profiles_file, "");
  EXPECT_NE(note.find("Fast DDS defaults"), std::string::npos) << note;

  setenv("FASTRTPS_DEFAULT_PROFILES_FILE", PPF_DDS_CONFIG_DIR "/udp_only.xml", 1);
  ppf::dds::ParticipantOptions from_env;
  note = ppf::dds::ChooseToolTransport(false, &from_env);
  EXPECT_EQ(from_env.profiles_file, "");  // Fast DDS loads the environment's file itself
  EXPECT_EQ(from_env.profile_name, "");
  EXPECT_NE(note.find("FASTRTPS_DEFAULT_PROFILES_FILE"), std::string::npos) << note;

  if (saved_env) {
    setenv("FASTRTPS_DEFAULT_PROFILES_FILE", saved.c_str(), 1);
  } else {
    unsetenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  }
}

TEST(Transport, DefaultParticipantProfileIsFoundInTheXml) {
  using ppf::dds::DefaultParticipantProfileIn;
  std::ifstream in(PPF_DDS_CONFIG_DIR "/shm_udp.xml");
  std::stringstream shm_udp;
  shm_udp << in.rdbuf();
  EXPECT_EQ(DefaultParticipantProfileIn(shm_udp.str()), "ppf_shm_udp");
  EXPECT_EQ(DefaultParticipantProfileIn(
                R"(<participant profile_name="a"><rtps/></participant>)"
                R"(<participant is_default_profile = 'true'  profile_name='b'>)"),
            "b");
  // Commented out, not marked default, another element, or cut short: none.
  EXPECT_EQ(DefaultParticipantProfileIn(
                R"(<!-- <participant profile_name="c" is_default_profile="true"> -->)"
                R"(<participant profile_name="d" is_default_profile="false">)"
                R"(<participants profile_name="e" is_default_profile="true">)"
                R"(<participant profile_name="f" is_default_profile="true")"),
            "");
  EXPECT_EQ(DefaultParticipantProfileIn(""), "");
  EXPECT_EQ(DefaultParticipantProfileIn("<!-- never closed <participant"), "");
}

TEST(Transport, RosNameMangling) {
  EXPECT_EQ(ppf::dds::RosTopicToDds("/points"), "rt/points");
  EXPECT_EQ(ppf::dds::RosTopicToDds("ns/imu"), "rt/ns/imu");
  EXPECT_EQ(ppf::dds::RosTopicToDds("rt/tf"), "rt/tf");
  EXPECT_EQ(ppf::dds::DdsTopicToRos("rt/odometry"), "/odometry");
  EXPECT_EQ(ppf::dds::RosTypeToDds("sensor_msgs/msg/Imu"), "sensor_msgs::msg::dds_::Imu_");
  EXPECT_EQ(ppf::dds::RosTypeToDds("Imu"), "");
  EXPECT_EQ(ppf::dds::DdsTypeToRos("nav_msgs::msg::dds_::Odometry_"), "nav_msgs/msg/Odometry");
  EXPECT_EQ(ppf::dds::DdsTypeToRos("Odometry"), "");
}
