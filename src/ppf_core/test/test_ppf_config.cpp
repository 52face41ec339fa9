#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "ppf_core/config.hpp"
#include "ppf_core/ppf_config.hpp"

namespace ppf {
namespace {

// The `ppf:` section is read by the core's one loader (config.hpp), like every other section;
// these tests look at what it leaves in Config::ppf.
ConfigLoadReport LoadPpfConfigYamlString(const std::string& yaml, PpfConfig* ppf) {
  Config c;
  c.ppf = *ppf;
  const ConfigLoadReport r = LoadConfigYamlString(yaml, &c);
  *ppf = c.ppf;  // unchanged when the load failed (all or nothing)
  return r;
}

TEST(PpfConfig, DefaultsScaleWithBeamCount) {
  EXPECT_EQ(PpfConfigForBeams(16).plane_least_inliers, 80);
  EXPECT_EQ(PpfConfigForBeams(32).plane_least_inliers, 150);
  EXPECT_EQ(PpfConfigForBeams(64).plane_least_inliers, 400);
  EXPECT_GT(PpfConfigForBeams(128).plane_least_inliers, 400);
  EXPECT_TRUE(PpfConfigForBeams(16).incremental_fitting);  // measured, docs/decisions.md
  EXPECT_TRUE(PpfConfigForBeams(32).incremental_fitting);  // measured, see ppf_config.cpp
  EXPECT_TRUE(PpfConfigForBeams(64).incremental_fitting);
  EXPECT_TRUE(PpfConfigForBeams(128).incremental_fitting);
  EXPECT_EQ(PpfConfigForBeams(0).plane_least_inliers, 80);  // unknown -> smallest class
  const PpfConfig d;
  EXPECT_DOUBLE_EQ(d.delta, 0.2);  // the paper: 0.1; wider because patches anchor (ppf_config.hpp)
  EXPECT_DOUBLE_EQ(d.delta * d.semi_band_factor, 0.4);  // the paper's semi band, >= 2 eps
  EXPECT_DOUBLE_EQ(d.point_to_plane_thresh, 0.2);
  EXPECT_DOUBLE_EQ(d.skeleton_normal_gate_deg, 10.0);
  EXPECT_EQ(d.max_planes_per_scan, 10);
  EXPECT_EQ(d.window_size, 5);
  EXPECT_EQ(d.ipca_iterations_new, 3);
  EXPECT_EQ(d.ipca_iterations_guess, 5);
  EXPECT_EQ(d.ransac_max_iterations, 300);
  EXPECT_DOUBLE_EQ(d.min_remaining_ratio, 0.1);
}

TEST(PpfConfig, DefaultsAreValid) {
  for (int beams : {16, 32, 64, 128}) {
    PpfConfig c = PpfConfigForBeams(beams);
    EXPECT_TRUE(ValidatePpfConfig(&c).empty()) << beams;
  }
}

TEST(PpfConfig, ValidationRepairsNonsense) {
  PpfConfig c;
  c.delta = -1.0;
  c.semi_band_factor = std::numeric_limits<double>::quiet_NaN();
  c.plane_least_inliers = 0;
  c.ransac_confidence = 1.0;
  c.min_remaining_ratio = 2.0;
  c.window_size = -3;
  const auto notes = ValidatePpfConfig(&c);
  EXPECT_EQ(notes.size(), 6u);
  const PpfConfig d;
  EXPECT_EQ(c.delta, d.delta);
  EXPECT_EQ(c.semi_band_factor, d.semi_band_factor);
  EXPECT_EQ(c.plane_least_inliers, d.plane_least_inliers);
  EXPECT_EQ(c.ransac_confidence, d.ransac_confidence);
  EXPECT_EQ(c.min_remaining_ratio, d.min_remaining_ratio);
  EXPECT_EQ(c.window_size, d.window_size);
}

TEST(PpfConfig, YamlEveryKeyOptional) {
  PpfConfig c;
  // No ppf section, empty section, null section: defaults, no crash, no warnings.
  for (const char* text : {"", "mode: ppf\n", "ppf:\n", "ppf: {}\n"}) {
    c = PpfConfig{};
    const auto r = LoadPpfConfigYamlString(text, &c);
    EXPECT_TRUE(r.ok) << text << ": " << r.error;
    EXPECT_TRUE(r.warnings.empty()) << text;
    EXPECT_EQ(c.plane_least_inliers, PpfConfig{}.plane_least_inliers);
    EXPECT_EQ(c.plane_least_inliers, 80);
  }
}

TEST(PpfConfig, YamlBeamsSelectDefaultsAndKeysOverride) {
  PpfConfig c;
  const auto r = LoadPpfConfigYamlString(
      "mode: ppf\nppf:\n  beams: 64\n  delta: 0.12\n  ransac_seed: 77\n"
      "  incremental_fitting: false\n  window_size: 7\n  spelled_wrong: 3\n",
      &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(c.plane_least_inliers, 400);  // from beams: 64
  EXPECT_DOUBLE_EQ(c.delta, 0.12);
  EXPECT_EQ(c.ransac_seed, 77u);
  EXPECT_FALSE(c.incremental_fitting);  // explicit key wins over the beam default
  EXPECT_EQ(c.window_size, 7);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("ppf.spelled_wrong"), std::string::npos);
}

TEST(PpfConfig, YamlWrongTypeFailsAndLeavesConfigUnchanged) {
  PpfConfig c;
  c.delta = 0.15;
  auto r = LoadPpfConfigYamlString("ppf:\n  delta: [1, 2]\n  window_size: 3\n", &c);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("ppf.delta"), std::string::npos) << r.error;
  EXPECT_DOUBLE_EQ(c.delta, 0.15);
  EXPECT_EQ(c.window_size, 5);
  r = LoadPpfConfigYamlString("ppf:\n  plane_least_inliers: many\n", &c);
  EXPECT_FALSE(r.ok);
  r = LoadPpfConfigYamlString("ppf: 3\n", &c);
  EXPECT_FALSE(r.ok);
  r = LoadPpfConfigYamlString("ppf: [unbalanced\n", &c);
  EXPECT_FALSE(r.ok);
  // Out-of-range values are repaired with a warning, not fatal.
  r = LoadPpfConfigYamlString("ppf:\n  delta: -1\n", &c);
  EXPECT_TRUE(r.ok);
  EXPECT_EQ(r.warnings.size(), 1u);
  EXPECT_DOUBLE_EQ(c.delta, 0.2);
}

}  // namespace
}  // namespace ppf
