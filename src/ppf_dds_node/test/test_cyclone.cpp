// Interop with a second DDS implementation: an Eclipse Cyclone DDS program (C, types from its own
// IDL compiler) feeds a short simulated sequence into ppf_node on rt/imu + rt/points and checks
// rt/odometry and rt/skeleton_planes, across processes and vendors (UDP; shared memory is vendor
// specific). Discovery: see RunNodeAndPeer (cyclone_peer_util.hpp).
#include <gtest/gtest.h>

#include <string>

#include "cyclone_peer_util.hpp"
#include "dds_test_util.hpp"
#include "test_domain.hpp"
#include "tool_paths.hpp"

using ppf::test::SummaryField;

TEST(Cyclone, CycloneDdsPeerFeedsNodeAndReceivesOdometryAndPlanes) {
  if (std::string(PPF_CYCLONE_PEER).empty()) {
    GTEST_SKIP() << "Cyclone DDS (cyclonedds-dev + idlc) not found at configure time";
  }
  const std::string sim = ppf::test::FindTool("ppf_sim", PPF_SIM_CONFIGURED);
  if (sim.empty()) GTEST_SKIP() << "ppf_sim not found (PATH or configure time): build ppf_sim";

  const std::string dir = ppf::test::TempDir("ppf_dds_cyclone");
  // Short sequence: 2.5 s static (IMU initialization), then hand-held motion indoors; VLP-16
  // clouds (~0.9 MB) so the UDP path between vendors carries them comfortably.
  int clouds = 0, imus = 0;
  ASSERT_TRUE(ppf::test::SimulateDump(sim,
                                      {"--scene", "indoor", "--lidar", "vlp16", "--duration", "6",
                                       "--seed", "2", "--storage", "mcap"},
                                      dir, &clouds, &imus));
  ASSERT_GE(clouds, 55);
  ASSERT_GE(imus, 1000);

  ppf::test::PeerRun run;
  // PPF mode, so the skeleton-plane messages carry planes.
  ASSERT_NO_FATAL_FAILURE(ppf::test::RunNodeAndPeer(
      PPF_CYCLONE_PEER, dir, ppf::test::TestDomainId(21),
      "core: {config_file: \"" PPF_CONFIG_DIR "/vlp16.yaml\", mode: ppf}\n", {}, &run));
  const std::string& result = run.result;
  const std::string& summary = run.summary;

  // What Cyclone sent.
  EXPECT_EQ(SummaryField(result, "sent_scans"), clouds);
  EXPECT_EQ(SummaryField(result, "sent_imu"), imus);
  EXPECT_EQ(SummaryField(result, "write_errors"), 0);
  // What the node made of it: Cyclone's XCDR1 payloads decode (nothing malformed), every scan is
  // processed, and the IMU stream arrives whole (reliable writer, loopback UDP).
  const double received = SummaryField(summary, "scans_received");
  EXPECT_EQ(SummaryField(summary, "scans_malformed"), 0);
  EXPECT_EQ(SummaryField(summary, "imu_malformed"), 0);
  EXPECT_EQ(SummaryField(summary, "imu_received"), imus);
  EXPECT_GE(received, clouds - 2) << "more than 2 clouds lost between vendors";
  EXPECT_LE(received, clouds);
  EXPECT_EQ(SummaryField(summary, "scans_processed") + SummaryField(summary, "scans_dropped"),
            received);
  EXPECT_EQ(SummaryField(summary, "resets"), 0);
  // What Cyclone received back: every odometry message the node published (reliable), one per
  // scan with a pose (2.5 s static start: ~10 scans initialize), all finite, right frames, and
  // one skeleton-plane message per odometry message.
  const double published = SummaryField(summary, "odometry_published");
  EXPECT_EQ(SummaryField(result, "odom"), published);
  EXPECT_GE(published, received - 30);
  EXPECT_GT(published, 20);
  EXPECT_EQ(SummaryField(result, "odom_bad"), 0);
  EXPECT_EQ(SummaryField(result, "odom_frames_bad"), 0);
  EXPECT_EQ(SummaryField(result, "odom_not_monotonic"), 0);
  EXPECT_EQ(SummaryField(result, "planes"), published);
  EXPECT_EQ(SummaryField(result, "planes_bad"), 0);
  // Sparse VLP-16 scans do not give a plane in every scan (docs/decisions.md, "Figures behind
  // test bounds").
  EXPECT_GT(SummaryField(result, "planes_total"), 0);
  if (!HasFailure()) std::system(("rm -rf '" + dir + "'").c_str());  // the dump is ~50 MB
}
