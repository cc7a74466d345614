// `mktree query --nearest / --ray` and the queries file's nearest and ray lines (docs/cli.md): the JSON lines
// scripts read, and bad input refused naming the option or FILE:LINE with nothing printed.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "test_dirs.h"
#include "tool_runner.h"

namespace {

// Two unit cubes: id 0 at [0, 1]^3, id 1 at [2, 3] x [0, 1] x [0, 1].
const char* kTwoCubes =
    "o cube\n"
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n"
    "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n"
    "o cube2\n"
    "v 2 0 0\nv 3 0 0\nv 2 1 0\nv 3 1 0\nv 2 0 1\nv 3 0 1\nv 2 1 1\nv 3 1 1\n"
    "f -8 -6 -5 -7\nf -4 -3 -1 -2\nf -8 -7 -3 -4\nf -6 -2 -1 -5\nf -8 -4 -2 -6\nf -7 -5 -1 -3\n";

class NearestCliTest : public ::testing::TestWithParam<const char*> {
 protected:
  void SetUp() override {
    std::ofstream(P("two.obj")) << kTwoCubes;
    auto b =
        Mktree("build " + P("two.obj") + " -o " + P("two.mkt") + " --backend " + GetParam() + " --quiet");
    ASSERT_EQ(b.code, 0) << b.err;
  }
  std::string P(const std::string& name) const { return dir_.file(name); }
  mktree::testing::ToolRun Mktree(const std::string& args) const {
    return mktree::testing::RunMktree(args, dir_);
  }
  mktree::testing::ToolRun Query(const std::string& args) const {
    return Mktree("query " + P("two.mkt") + " " + args);
  }

  mktree::testing::TempDir dir_{"mktree_nearest_cli"};
};

bool Has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST_P(NearestCliTest, NearestLines) {
  auto r = Query("--nearest 1.5,0.5,0.5 --k 2");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Has(r.out,
                  "{\"query\": 0, \"kind\": \"nearest\", \"hits\": [0, 1], \"distances\": [0.5, 0.5], "
                  "\"points\": [[1, 0.5, 0.5], [2, 0.5, 0.5]], "))
      << r.out;
  EXPECT_TRUE(Has(r.out, "\"pages_read\": ")) << r.out;
  r = Query("--nearest 0.5,0.5,0.5 --k 5 --max-distance 1");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Has(r.out, "\"hits\": [0], \"distances\": [0], \"points\": [[0.5, 0.5, 0.5]]")) << r.out;
}

TEST_P(NearestCliTest, RayLines) {
  auto r = Query("--ray -1,0.5,0.5,2,0,0");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Has(r.out,
                  "{\"query\": 0, \"kind\": \"ray\", \"hits\": [0], \"t\": [1], \"points\": [[0, 0.5, "
                  "0.5]], \"normals\": [[-1, 0, 0]], "))
      << r.out;
  r = Query("--ray -1,0.5,0.5,1,0,0 --all-hits");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Has(r.out, "\"hits\": [0, 1], \"t\": [1, 3]")) << r.out;
  r = Query("--ray -1,0.5,0.5,1,0,0 --all-hits --max-distance 2");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Has(r.out, "\"hits\": [0], \"t\": [1]")) << r.out;
  r = Query("--ray -1,5,0.5,1,0,0");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Has(r.out, "\"hits\": [], \"t\": [], \"points\": [], \"normals\": []")) << r.out;
}

TEST_P(NearestCliTest, QueriesFileMixesKinds) {
  std::ofstream(P("q.txt"))
      << "nearest 1.5 0.5 0.5 2\n# a comment\nray -1 0.5 0.5 1 0 0\npoint 0.5 0.5 0.5\n";
  auto r = Query("--queries " + P("q.txt"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Has(r.out, "{\"query\": 0, \"kind\": \"nearest\", \"hits\": [0, 1]")) << r.out;
  EXPECT_TRUE(Has(r.out, "{\"query\": 1, \"kind\": \"ray\", \"hits\": [0], \"t\": [1]")) << r.out;
  EXPECT_TRUE(Has(r.out, "{\"query\": 2, \"kind\": \"point\", \"hits\": [0]")) << r.out;
  r = Query("--queries " + P("q.txt") + " --all-hits");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Has(r.out, "\"kind\": \"ray\", \"hits\": [0, 1]")) << r.out;
}

TEST_P(NearestCliTest, BadInputIsRefusedNamingTheQuery) {
  struct Bad {
    std::string args, says;
  };
  const Bad bad[] = {
      {"--nearest nan,0,0", "--nearest"},
      {"--nearest inf,0,0", "--nearest"},
      {"--nearest 0,0,0 --k 0", "--k must be at least 1"},
      {"--nearest 0,0,0 --max-distance -1", "--max-distance must be >= 0"},
      {"--nearest 0,0,0 --max-distance nan", "--max-distance must be >= 0"},
      {"--ray 0,0,0,0,0,0", "zero direction"},
      {"--ray 0,0,0,1,0", "a ray needs 6 numbers"},
      {"--ray 0,0,0,1,0,0 --max-distance -2", "--max-distance must be >= 0"},
  };
  for (const Bad& b : bad) {
    auto r = Query(b.args);
    EXPECT_NE(r.code, 0) << b.args;
    EXPECT_TRUE(Has(r.err, b.says)) << b.args << ": " << r.err;
    EXPECT_TRUE(r.out.empty()) << b.args << ": " << r.out;
  }
  const std::pair<std::string, std::string> lines[] = {
      {"nearest 0 0 0 1\nnearest 0 0 0 0\n", "q.txt:2: nearest query: k must be a whole number >= 1"},
      {"nearest 0 0 0 -3\n", "q.txt:1: nearest query: k must be"},
      {"nearest 0 0 0 1.5\n", "q.txt:1: nearest query: k must be"},
      {"nearest 0 0 0 2 -1\n", "q.txt:1: nearest query: max distance must be >= 0"},
      {"point 0 0 0\nray 0 0 0 0 0 0\n", "q.txt:2: ray query: zero direction"},
      {"ray nan 0 0 1 0 0\n", "q.txt:1: 'nan' is not a finite number"},
      {"ray 0 0 0 1 0 0 -1\n", "q.txt:1: ray query: max length must be >= 0"},
  };
  for (const auto& [text, says] : lines) {
    std::ofstream(P("q.txt")) << text;
    auto r = Query("--queries " + P("q.txt"));
    EXPECT_NE(r.code, 0) << text;
    EXPECT_TRUE(Has(r.err, says)) << text << ": " << r.err;
    EXPECT_TRUE(r.out.empty()) << text << ": " << r.out;
  }
  auto r = Query("--nearest 0,0,0 --summary");
  EXPECT_NE(r.code, 0);
}

INSTANTIATE_TEST_SUITE_P(Backends, NearestCliTest, ::testing::Values("hdf5", "pagefile"));

}  // namespace
