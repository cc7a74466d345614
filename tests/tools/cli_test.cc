// The mktree command line (docs/cli.md): good runs print what the contract says; bad arguments and bad
// files give one "error: ..." line naming the file (and line), a non-zero exit, and nothing half-written.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "test_dirs.h"
#include "tool_runner.h"

namespace {

namespace fs = std::filesystem;

using RunResult = mktree::testing::ToolRun;

class CliTest : public ::testing::Test {
 protected:
  std::string P(const std::string& name) const { return (dir_ / name).string(); }

  RunResult Mktree(const std::string& args) const { return mktree::testing::RunMktree(args, dir_); }

  void Write(const std::string& name, const std::string& text) const { std::ofstream(P(name)) << text; }

  // Every file in the test folder (to check that nothing half-written is left).
  std::vector<std::string> Files() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  mktree::testing::TempDir dir_{"mktree_cli"};
};

const char* kCube =
    "o cube\n"
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n"
    "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n"
    "o cube2\n"
    "v 2 0 0\nv 3 0 0\nv 2 1 0\nv 3 1 0\nv 2 0 1\nv 3 0 1\nv 2 1 1\nv 3 1 1\n"
    "f -8 -6 -5 -7\nf -4 -3 -1 -2\nf -8 -7 -3 -4\nf -6 -2 -1 -5\nf -8 -4 -2 -6\nf -7 -5 -1 -3\n";

TEST_F(CliTest, NoSubcommandIsAnError) {
  RunResult r = Mktree("");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("error:"), std::string::npos) << r.err;
}

TEST_F(CliTest, BuildInfoQueryOnASmallScene) {
  Write("two.obj", kCube);
  for (const char* backend : {"hdf5", "pagefile"}) {
    SCOPED_TRACE(backend);
    RunResult b =
        Mktree("build " + P("two.obj") + " -o " + P("two.mkt") + " --backend " + backend + " --quiet");
    ASSERT_EQ(b.code, 0) << b.err;
    RunResult info = Mktree("info " + P("two.mkt") + " --json");
    ASSERT_EQ(info.code, 0) << info.err;
    EXPECT_NE(info.out.find("\"objects\": 2"), std::string::npos) << info.out;
    EXPECT_NE(info.out.find(std::string("\"backend\": \"") + backend + "\""), std::string::npos) << info.out;
    RunResult q = Mktree("query " + P("two.mkt") + " --point 0.5,0.5,0.5 --cold");
    ASSERT_EQ(q.code, 0) << q.err;
    EXPECT_NE(q.out.find("{\"query\": 0, \"kind\": \"point\", \"hits\": [0], \"pages_read\": 1"),
              std::string::npos)
        << q.out;
    RunResult qb = Mktree("query " + P("two.mkt") + " --box 0.5,0.5,0.5,2.5,0.6,0.6 --exact");
    ASSERT_EQ(qb.code, 0) << qb.err;
    EXPECT_NE(qb.out.find("\"hits\": [0, 1]"), std::string::npos) << qb.out;
    Write("q.txt", "# a comment\npoint 2.5 0.5 0.5\n\nbox -1 -1 -1 -0.5 -0.5 -0.5  # nothing there\n");
    RunResult qf = Mktree("query " + P("two.mkt") + " --queries " + P("q.txt"));
    ASSERT_EQ(qf.code, 0) << qf.err;
    EXPECT_NE(qf.out.find("{\"query\": 0, \"kind\": \"point\", \"hits\": [1]"), std::string::npos) << qf.out;
    EXPECT_NE(qf.out.find("{\"query\": 1, \"kind\": \"box\", \"hits\": []"), std::string::npos) << qf.out;
  }
}

// The lines of `text`.
std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

// The ids of a query line's "hits" array.
size_t HitCount(const std::string& line) {
  const std::string key = "\"hits\": [";
  const size_t open = line.find(key);
  const size_t close = line.find(']', open);
  if (open == std::string::npos || close == std::string::npos) return SIZE_MAX;
  const std::string ids = line.substr(open + key.size(), close - open - key.size());
  return ids.empty() ? 0 : static_cast<size_t>(std::count(ids.begin(), ids.end(), ',')) + 1;
}

// Issue 21/22: answers streamed in query order on any number of threads (the same bytes), and the
// counted, limited and any-hit forms agree with the full answers.
TEST_F(CliTest, QueryThreadsLimitAnyAndCountAgreeWithTheFullAnswers) {
  ASSERT_EQ(Mktree("build tanker:3000:1 -o " + P("t.mkt") + " --backend pagefile -q").code, 0);
  ASSERT_EQ(Mktree("generate queries " + P("t.mkt") + " --count 40 --seed 3 -o " + P("q.txt")).code, 0);
  const std::string base = "query " + P("t.mkt") + " --queries " + P("q.txt") + " --cold";
  const RunResult full = Mktree(base);
  ASSERT_EQ(full.code, 0) << full.err;
  const std::vector<std::string> lines = Lines(full.out);
  ASSERT_EQ(lines.size(), 160u);
  for (const char* threads : {" --threads 2", " --threads 5"}) {
    EXPECT_EQ(Mktree(base + threads).out, full.out) << threads;
    EXPECT_EQ(Mktree(base + " --summary" + threads).out, Mktree(base + " --summary").out) << threads;
  }
  const std::vector<std::string> count = Lines(Mktree(base + " --count --threads 2").out);
  const std::vector<std::string> limit = Lines(Mktree(base + " --limit 3").out);
  const std::vector<std::string> any = Lines(Mktree(base + " --any --threads 3").out);
  ASSERT_EQ(count.size(), lines.size());
  ASSERT_EQ(limit.size(), lines.size());
  ASSERT_EQ(any.size(), lines.size());
  size_t truncated = 0, empty = 0;
  for (size_t i = 0; i < lines.size(); ++i) {
    const size_t n = HitCount(lines[i]);
    ASSERT_NE(n, SIZE_MAX) << lines[i];
    EXPECT_EQ(count[i].find("\"hits\""), std::string::npos) << count[i];
    EXPECT_NE(count[i].find("\"hit_count\": " + std::to_string(n) + ","), std::string::npos) << count[i];
    EXPECT_EQ(HitCount(limit[i]), std::min<size_t>(n, 3)) << limit[i];
    const bool cut = limit[i].find("\"truncated\": true}") != std::string::npos;
    EXPECT_EQ(cut, n > 3) << limit[i];
    EXPECT_NE(any[i].find(n ? "\"any\": true" : "\"any\": false"), std::string::npos) << any[i];
    truncated += cut;
    empty += n == 0;
  }
  EXPECT_GT(truncated, 20u);
  EXPECT_GT(empty, 5u);

  RunResult both = Mktree(base + " --any --limit 2");
  EXPECT_NE(both.code, 0);
  EXPECT_NE(both.err.find("--any"), std::string::npos) << both.err;
  // A bad line is refused before any answer is printed.
  std::ofstream(P("q.txt"), std::ios::app) << "box 1 2 3\n";
  RunResult bad = Mktree(base + " --threads 2");
  EXPECT_NE(bad.code, 0);
  EXPECT_EQ(bad.out, "");
  EXPECT_NE(bad.err.find("q.txt:162:"), std::string::npos) << bad.err;
}

// Issue 18, item 1: a 0.2 m cube at UTM-like coordinates is found at its centre through the tool, and the
// store reports the frame it keeps the geometry in (an axis within 2^16 of 0 keeps origin 0).
TEST_F(CliTest, UtmCoordinatesAreAnsweredAndTheOriginIsShown) {
  std::string obj = "o cube\n";
  for (int i = 0; i < 8; ++i)
    obj += "v " + std::to_string(500000.0 + 0.2 * (i & 1)) + " " +
           std::to_string(5000000.0 + 0.2 * (i >> 1 & 1)) + " " + std::to_string(100.0 + 0.2 * (i >> 2)) +
           "\n";
  obj +=
      "f 1 2 4\nf 1 4 3\nf 5 6 8\nf 5 8 7\nf 1 2 6\nf 1 6 5\nf 3 4 8\nf 3 8 7\nf 1 3 7\nf 1 7 5\nf 2 4 8\nf "
      "2 8 6\n";
  Write("utm.obj", obj);
  for (const char* backend : {"hdf5", "pagefile"}) {
    SCOPED_TRACE(backend);
    RunResult b = Mktree("build " + P("utm.obj") + " -o " + P("utm.mkt") + " --backend " + backend);
    ASSERT_EQ(b.code, 0) << b.err;
    EXPECT_NE(b.out.find("store frame: origin (500000, 5000000, 0)"), std::string::npos) << b.out;
    RunResult info = Mktree("info " + P("utm.mkt") + " --json");
    ASSERT_EQ(info.code, 0) << info.err;
    EXPECT_NE(info.out.find("\"origin\": [500000, 5000000, 0]"), std::string::npos) << info.out;
    for (const char* mode : {"", " --exact"}) {
      RunResult q = Mktree("query " + P("utm.mkt") + " --point 500000.1,5000000.1,100.1" + mode);
      ASSERT_EQ(q.code, 0) << q.err;
      EXPECT_NE(q.out.find("\"hits\": [0]"), std::string::npos) << mode << q.out;
      RunResult miss = Mktree("query " + P("utm.mkt") + " --point 500000.3,5000000.1,100.1" + mode);
      ASSERT_EQ(miss.code, 0) << miss.err;
      EXPECT_NE(miss.out.find("\"hits\": []"), std::string::npos) << mode << miss.out;
    }
  }
}

TEST_F(CliTest, MissingInputLeavesNothing) {
  RunResult r = Mktree("build " + P("nope.obj") + " -o " + P("out.mkt"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("nope.obj"), std::string::npos) << r.err;
  EXPECT_TRUE(Files().empty());
}

TEST_F(CliTest, MalformedObjNamesFileAndLineAndLeavesNothing) {
  Write("bad.obj", "o a\nv 0 0 0\nv 1 0 0\nv 0 1 zero\nf 1 2 3\n");
  RunResult r = Mktree("build " + P("bad.obj") + " -o " + P("out.mkt"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("bad.obj:4"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
  EXPECT_EQ(Files(), std::vector<std::string>{"bad.obj"});
}

TEST_F(CliTest, NanCoordinateIsRefused) {
  Write("nan.obj", "o a\nv 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n");
  RunResult r = Mktree("build " + P("nan.obj") + " -o " + P("out.mkt"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("nan.obj:3"), std::string::npos) << r.err;
  EXPECT_EQ(Files(), std::vector<std::string>{"nan.obj"});
}

TEST_F(CliTest, EmptySceneIsRefused) {
  Write("empty.obj", "# nothing but a comment\nv 0 0 0\n");
  RunResult r = Mktree("build " + P("empty.obj") + " -o " + P("out.mkt"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find(P("empty.obj") + ": " + P("out.mkt") + " not built: empty scene"), std::string::npos)
      << r.err;
  EXPECT_EQ(Files(), std::vector<std::string>{"empty.obj"});
}

TEST_F(CliTest, BadBuildArgumentsAreRefused) {
  Write("two.obj", kCube);
  EXPECT_NE(Mktree("build " + P("two.obj") + " -o " + P("o.mkt") + " --backend sqlite").code, 0);
  EXPECT_NE(Mktree("build " + P("two.obj") + " -o " + P("o.mkt") + " --codec lz4").code, 0);
  EXPECT_NE(Mktree("build " + P("two.obj") + " -o " + P("o.mkt") + " --r 0.5").code, 0);
  EXPECT_NE(Mktree("build " + P("two.obj") + " -o " + P("o.mkt") + " --block-size 16").code, 0);
  EXPECT_NE(Mktree("build " + P("two.obj")).code, 0);  // no -o
  EXPECT_EQ(Files(), std::vector<std::string>{"two.obj"});
}

// --spill-dir takes the build's temporary files elsewhere: the same store, nothing left in the folder; a
// folder that is not one is refused before anything is read.
TEST_F(CliTest, SpillDirHoldsTheBuildsTemporaryFiles) {
  Write("two.obj", kCube);
  fs::create_directory(P("spills"));
  for (const char* backend : {"hdf5", "pagefile"}) {
    SCOPED_TRACE(backend);
    const std::string common = "build " + P("two.obj") + " --quiet --backend " + backend;
    ASSERT_EQ(Mktree(common + " -o " + P("here.mkt")).code, 0);
    RunResult r = Mktree(common + " -o " + P("there.mkt") + " --spill-dir " + P("spills"));
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::is_empty(P("spills")));
    if (std::string(backend) == "pagefile")
      EXPECT_EQ(mktree::testing::Slurp(P("here.mkt")), mktree::testing::Slurp(P("there.mkt")));
    fs::remove(P("here.mkt"));
    fs::remove(P("there.mkt"));
  }
  for (const std::string& bad : {P("missing"), P("two.obj")}) {
    RunResult r = Mktree("build " + P("two.obj") + " -o " + P("o.mkt") + " --spill-dir " + bad);
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.err.find("--spill-dir " + bad + ": not a directory"), std::string::npos) << r.err;
  }
  EXPECT_EQ(Files(), (std::vector<std::string>{"spills", "two.obj"}));
}

TEST_F(CliTest, BadQueriesNameFileAndLine) {
  Write("two.obj", kCube);
  ASSERT_EQ(Mktree("build " + P("two.obj") + " -o " + P("two.mkt") + " --quiet").code, 0);
  Write("q.txt", "point 1 2 3\nbox 1 2 3 4 5\n");
  RunResult r = Mktree("query " + P("two.mkt") + " --queries " + P("q.txt"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("q.txt:2"), std::string::npos) << r.err;
  Write("q2.txt", "point 1 nan 3\n");
  r = Mktree("query " + P("two.mkt") + " --queries " + P("q2.txt"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("q2.txt:1"), std::string::npos) << r.err;
  Write("q3.txt", "sphere 1 2 3 4\n");
  r = Mktree("query " + P("two.mkt") + " --queries " + P("q3.txt"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("q3.txt:1"), std::string::npos) << r.err;
  EXPECT_NE(Mktree("query " + P("two.mkt") + " --point 1,2").code, 0);
  EXPECT_NE(Mktree("query " + P("two.mkt") + " --box 1,1,1,0,0,0").code, 0);
  EXPECT_NE(Mktree("query " + P("two.mkt")).code, 0);
}

TEST_F(CliTest, TruncatedOrForeignStoreIsRefused) {
  Write("two.obj", kCube);
  for (const char* backend : {"hdf5", "pagefile"}) {
    SCOPED_TRACE(backend);
    ASSERT_EQ(Mktree("build " + P("two.obj") + " -o " + P("two.mkt") + " --quiet --backend " + backend).code,
              0);
    const auto size = fs::file_size(P("two.mkt"));
    for (uintmax_t keep : {uintmax_t{0}, uintmax_t{7}, size / 2, size - 1}) {
      fs::copy_file(P("two.mkt"), P("cut.mkt"), fs::copy_options::overwrite_existing);
      fs::resize_file(P("cut.mkt"), keep);
      RunResult info = Mktree("info " + P("cut.mkt"));
      EXPECT_NE(info.code, 0) << "kept " << keep;
      EXPECT_NE(info.err.find("cut.mkt"), std::string::npos) << info.err;
      RunResult q = Mktree("query " + P("cut.mkt") + " --point 0.5,0.5,0.5");
      EXPECT_NE(q.code, 0) << "kept " << keep;
    }
  }
  RunResult r = Mktree("info " + P("two.obj"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("two.obj"), std::string::npos) << r.err;
}

}  // namespace
