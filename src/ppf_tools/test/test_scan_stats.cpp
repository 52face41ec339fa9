#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "ppf_tools/scan_stats.hpp"

namespace ppf::tools {
namespace {

ScanResult Result(Status status, double total_ms, size_t map_size) {
  ScanResult r;
  r.status = status;
  r.pose_valid = status == Status::kOk || status == Status::kDegenerate;
  r.timings.total = total_ms;
  r.timings.residuals = total_ms / 2;
  r.map_size = map_size;
  return r;
}

TEST(ScanStats, SummaryAveragesOnlyScansWithAPose) {
  std::vector<ScanResult> rs = {Result(Status::kInitializing, 1.0, 0), Result(Status::kOk, 10.0, 100),
                                Result(Status::kDegenerate, 20.0, 300), Result(Status::kRejected, 0.0, 0)};
  auto s = Summarize(rs, 2.0);
  EXPECT_EQ(s.scans, 4u);
  EXPECT_EQ(s.ok, 1u);
  EXPECT_EQ(s.degenerate, 1u);
  EXPECT_EQ(s.initializing, 1u);
  EXPECT_EQ(s.rejected, 1u);
  EXPECT_DOUBLE_EQ(s.mean.total, 15.0);
  EXPECT_DOUBLE_EQ(s.mean.residuals, 7.5);
  EXPECT_DOUBLE_EQ(s.mean_map_size, 200.0);
  EXPECT_EQ(s.max_map_size, 300u);
  // 4 scans in 31 ms of core time.
  EXPECT_NEAR(s.scans_per_s, 4000.0 / 31.0, 1e-9);
}

TEST(ScanStats, CsvQuotesReasonsAndHasOneColumnPerHeaderField) {
  auto r = Result(Status::kReset, 1.0, 0);
  r.reason = "IMU went back in time, \"loop\"\nreset";
  std::ostringstream os;
  WriteStatsCsvHeader(os);
  WriteStatsCsvRow(os, r);
  std::istringstream is(os.str());
  std::string header, row;
  std::getline(is, header);
  std::getline(is, row);
  EXPECT_FALSE(std::getline(is, row).good() && !row.empty()) << "a newline in the reason leaked";
  is.clear();
  std::istringstream again(os.str());
  std::getline(again, header);
  std::getline(again, row);
  auto count_fields = [](const std::string& line) {
    size_t n = 1;
    bool quoted = false;
    for (char c : line) {
      if (c == '"') quoted = !quoted;
      if (c == ',' && !quoted) ++n;
    }
    return n;
  };
  EXPECT_EQ(count_fields(header), count_fields(row));
  EXPECT_NE(row.find("\"\"loop\"\""), std::string::npos) << row;
}

// What set the consistency check's search off: the CSV's last column per scan, and the summary's
// counts by trigger next to the overruled ones (a search that kept the pose is counted too).
TEST(ScanStats, ConsistencySearchesInTheCsvAndTheSummary) {
  std::vector<ScanResult> rs(4, Result(Status::kOk, 10.0, 100));
  rs[1].consistency_search = ConsistencySearch::kPoorFit;
  rs[1].overruled = true;
  rs[2].consistency_search = ConsistencySearch::kScanStep;
  rs[3].consistency_search = ConsistencySearch::kScanStep;
  std::ostringstream csv;
  WriteStatsCsvHeader(csv);
  for (const auto& r : rs) WriteStatsCsvRow(csv, r);
  std::istringstream is(csv.str());
  std::vector<std::string> last;
  for (std::string line; std::getline(is, line);) last.push_back(line.substr(line.rfind(',') + 1));
  EXPECT_EQ(last, (std::vector<std::string>{"consistency_search", "none", "fit", "step", "step"}));
  const RunSummary s = Summarize(rs, 1.0);
  EXPECT_EQ(s.searched_fit, 1u);
  EXPECT_EQ(s.searched_step, 2u);
  std::ostringstream printed;
  PrintSummary(printed, s, "run");
  EXPECT_NE(printed.str().find("consistency searches: 3 (poor fit 1, scan step 2), LiDAR overruled "
                               "the IMU prediction on 1 scans"),
            std::string::npos)
      << printed.str();
  std::ostringstream quiet;
  PrintSummary(quiet, Summarize({Result(Status::kOk, 10.0, 100)}, 1.0), "run");
  EXPECT_EQ(quiet.str().find("consistency"), std::string::npos) << quiet.str();
}

}  // namespace
}  // namespace ppf::tools
