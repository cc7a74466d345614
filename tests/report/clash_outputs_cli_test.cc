// `mktree clash STORE --tests FILE --bcf OUT.bcf --report OUT.html`: the outputs hold the groups the pair
// lines name, and a run that cannot write them fails without leaving a file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>

#include "coordination/coordination_fixtures.h"
#include "engine/report/bcf_reader.h"
#include "engine/report/bcf_writer.h"
#include "test_dirs.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::ProgramDir;
using testing::TempPath;

testing::ToolRun Clash(const std::string& args) {
  return testing::RunMktree("clash " + args, ProgramDir().path());
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

class ClashOutputsCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    testing::BuildScene(testing::AttributedScene(400, 31), TempPath("s.mkt"));
    std::ofstream(TempPath("tests.json"))
        << R"({"tests": [{"name": "all", "a": {}, "group": {"proximity": 1.5}}]})";
  }
};

TEST_F(ClashOutputsCli, BcfAndReportHoldTheGroupsOfTheLines) {
  const std::string bcf = TempPath("out.bcf"), html = TempPath("out.html");
  const auto r = Clash(TempPath("s.mkt") + " --tests " + TempPath("tests.json") + " --bcf " + bcf +
                       " --report " + html + " --snapshots 2");
  ASSERT_EQ(r.code, 0) << r.err;
  std::set<std::string> groups;
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);) {
    const auto j = nlohmann::json::parse(line);
    if (!j.value("summary", false)) groups.insert(j.at("group").get<std::string>());
  }
  ASSERT_GT(groups.size(), 2u);

  auto archive = ReadBcf(bcf);
  ASSERT_TRUE(archive.ok()) << archive.status().message();
  EXPECT_EQ(archive->version, "2.1");
  std::set<std::string> guids, want;
  uint64_t snapshots = 0;
  for (const BcfTopic& t : archive->topics) {
    guids.insert(t.guid);
    for (const BcfViewpoint& v : t.viewpoints) snapshots += v.has_snapshot;
  }
  for (const std::string& g : groups) want.insert(BcfTopicGuid(g));
  EXPECT_EQ(guids, want);
  EXPECT_EQ(snapshots, 2u);

  const std::string page = ReadText(html);
  EXPECT_NE(page.find("<html"), std::string::npos);
  EXPECT_NE(page.find("data:image/png;base64,"), std::string::npos);
}

TEST_F(ClashOutputsCli, BcfThreeIsAsked) {
  const std::string bcf = TempPath("three.bcf");
  const auto r = Clash(TempPath("s.mkt") + " --tests " + TempPath("tests.json") + " --bcf " + bcf +
                       " --bcf-version 3.0 --snapshots 0");
  ASSERT_EQ(r.code, 0) << r.err;
  auto archive = ReadBcf(bcf);
  ASSERT_TRUE(archive.ok()) << archive.status().message();
  EXPECT_EQ(archive->version, "3.0");
  EXPECT_FALSE(archive->topics.empty());
}

TEST_F(ClashOutputsCli, AnOutputThatCannotBeWrittenFailsAndLeavesNothing) {
  const std::string bcf = TempPath("no-such-folder/out.bcf"), html = TempPath("never.html");
  const auto r =
      Clash(TempPath("s.mkt") + " --tests " + TempPath("tests.json") + " --bcf " + bcf + " --report " + html);
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("no-such-folder"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(bcf));
  EXPECT_FALSE(std::filesystem::exists(html));
}

TEST_F(ClashOutputsCli, OutputsNeedTests) {
  const auto r = Clash(TempPath("s.mkt") + " --bcf " + TempPath("x.bcf"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--tests"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(TempPath("x.bcf")));
}

}  // namespace
}  // namespace mktree
