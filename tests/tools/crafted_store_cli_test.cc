// The command line on crafted stores (tests/store_format/crafted_store.h) and under memory limits: `info
// --json` prints only statistics that are valid JSON with known keys, a store carrying others is refused
// with one error line, and an open that needs more memory than allowed exits 1 with one `error:` line
// instead of aborting. Crafted* suites run under a short timeout.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>

#include "store_format/crafted_store.h"
#include "tool_runner.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;
using testing::ToolRun;

// One line ending in a newline, starting with "error: " and naming `path`.
void ExpectOneErrorLine(const ToolRun& r, const std::string& path) {
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
  EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
}

class CraftedStatsCliTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    auto img = testing::MakeTestImage(50, 3);
    ASSERT_TRUE(img.ok()) << img.status().ToString();
    image_ = std::move(img).value();
    path_ = dir_.file("stats.mkt");
  }
  ToolRun InfoJson(const std::string& stats) {
    image_.contents.stats_json = stats;
    EXPECT_TRUE(testing::WriteStoreImage(image_, path_, GetParam()).ok());
    return testing::RunMktree("info --json " + path_, dir_.path());
  }

  testing::TempDir dir_;
  testing::StoreImage image_;
  std::string path_;
};

TEST_P(CraftedStatsCliTest, TheBuildersStatisticsArePrintedUnderTree) {
  const std::string stats = image_.contents.stats_json;
  ToolRun r = InfoJson(stats);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"tree\": " + stats + "}\n"), std::string::npos) << r.out;
  r = InfoJson("");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"tree\": null}\n"), std::string::npos) << r.out;
  r = InfoJson("{\"objects\": 50, \"mean_page_fill\": -1.5e-3, \"levels\": [{\"depth\": 0}, {}]}");
  EXPECT_EQ(r.code, 0) << r.err;
}

TEST_P(CraftedStatsCliTest, StatisticsThatAreNotTheBuildersAreRefused) {
  const char* cases[] = {
      "{\"objects\": 1, \"evil\": 2}",            // an extra key
      "{\"objects\": {\"nested\": 1}}",           // a nested object
      "{\"levels\": [{\"depth\": [1]}]}",         // nested in a level
      "1}, \"injected\": {\"x\": 1",              // closes the object and opens another
      "{\"objects\": \"1\\\"}, \\\"x\\\": 2\"}",  // a string
      "{\"objects\": 1}, \"injected\": 2",        // trailing members
      "{\"objects\": 1, \"objects\": 2}",         // a key twice
      "{\"objects\": nan}",                       // not a JSON number
      "{\"objects\": 01}",
      "{\"objects\": 1,}",
      "\x01\xff garbage",
  };
  for (const char* stats : cases) {
    SCOPED_TRACE(stats);
    ToolRun r = InfoJson(stats);
    ExpectOneErrorLine(r, path_);
    EXPECT_NE(r.err.find("build statistics"), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "");
  }
}

TEST_P(CraftedStatsCliTest, ControlCharactersInThePathAreEscaped) {
  path_ = dir_.file("a\tb.mkt");
  ASSERT_TRUE(testing::WriteStoreImage(image_, path_, GetParam()).ok());
  ToolRun r = testing::RunMktree("info --json '" + path_ + "'", dir_.path());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("a\\u0009b.mkt\", "), std::string::npos) << r.out;
}

INSTANTIATE_TEST_SUITE_P(Backends, CraftedStatsCliTest,
                         ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const ::testing::TestParamInfo<Backend>& p) {
                           return std::string(BackendName(p.param));
                         });

// `mktree ARGS` with its address space limited to `mib` MiB (the shell's ulimit -v, i.e. RLIMIT_AS).
ToolRun RunMktreeLimited(uint64_t mib, const std::string& args, const fs::path& scratch) {
  return testing::RunMktree(args, scratch, "ulimit -v " + std::to_string(mib << 10) + "; exec ");
}

// The smallest limit, in MiB, under which `mktree ARGS` succeeds (within 2 MiB), or 0.
uint64_t SmallestLimit(const std::string& args, const fs::path& scratch) {
  uint64_t lo = 8, hi = 4096;  // fails at lo, succeeds at hi
  if (RunMktreeLimited(hi, args, scratch).code != 0) return 0;
  while (hi - lo > 2) {
    const uint64_t mid = (lo + hi) / 2;
    (RunMktreeLimited(mid, args, scratch).code == 0 ? hi : lo) = mid;
  }
  return hi;
}

TEST(CraftedMemoryLimitCliTest, OpenNeedingMoreMemoryThanAllowedIsOneErrorLine) {
  testing::TempDir dir;
  auto img = testing::MakeTestImage(16, 5);
  ASSERT_TRUE(img.ok());
  const std::string small = dir.file("small.mkt"), big = dir.file("big_sources.mkt");
  ASSERT_TRUE(testing::WriteStoreImage(*img, small, Backend::kPagedFile).ok());
  // 16 sources of 2 MiB each: opening needs twice 32 MiB more (the section, then the table). (Names are
  // no longer read at open: they live in the record pages.)
  for (uint64_t i = 1; i < 16; ++i)
    img->objects().sources.push_back(std::string(2 << 20, static_cast<char>('a' + i)));
  ASSERT_TRUE(testing::WriteStoreImage(*img, big, Backend::kPagedFile).ok());

  for (const std::string& command :
       {std::string("info "), std::string("info --json "), std::string("query ")}) {
    SCOPED_TRACE(command);
    const std::string tail = command == "query " ? " --point 0,0,0" : "";
    const uint64_t limit = SmallestLimit(command + small + tail, dir.path());
    ASSERT_GT(limit, 0u);
    ToolRun r = RunMktreeLimited(limit + 8, command + big + tail, dir.path());
    ExpectOneErrorLine(r, big);  // before: "terminate called after throwing 'std::bad_alloc'", rc 134
    EXPECT_NE(r.err.find("out of memory"), std::string::npos) << r.err;
    EXPECT_EQ(RunMktreeLimited(limit + 8, command + small + tail, dir.path()).code, 0);
  }
}

}  // namespace
}  // namespace mktree
