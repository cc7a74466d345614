// `mktree generate` end to end through the built tool (MKTREE_TOOL). test_generator does not depend on the
// tool target, so these tests skip when the tool has not been built yet.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "engine/scene/mkscene_format.h"
#include "generator/mesh_checks.h"
#include "test_dirs.h"
#include "tool_runner.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;
using testing::Slurp;

class GenerateCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(MKTREE_TOOL)) GTEST_SKIP() << "tool not built: " << MKTREE_TOOL;
  }

  testing::ToolRun Mktree(const std::string& args) { return testing::RunMktree(args, dir_); }

  testing::TempDir dir_{"mktree_generate_command"};
};

TEST_F(GenerateCommandTest, WritesMksAndObjWithASummary) {
  const std::string mks = dir_ / "t.mks", obj = dir_ / "t.obj";
  testing::ToolRun r = Mktree("generate tanker --objects 1000 --seed 4 -o " + mks);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("1000 objects (600 pipes, 300 plates, 100 equipment)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("objects/s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("MB/s"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  auto source = OpenMkSceneFile(mks);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EXPECT_EQ(testing::Drain(source->get()).size(), 1000u);

  r = Mktree("generate tanker --objects 1000 --seed 4 -o " + obj);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string text = Slurp(obj);
  size_t objects = 0;
  for (size_t at = 0; (at = text.find("\no ", at)) != std::string::npos; ++at) ++objects;
  EXPECT_EQ(objects, 1000u);

  // The same seed gives the same file.
  const std::string again = dir_ / "again.mks";
  ASSERT_EQ(Mktree("generate tanker --objects 1000 --seed 4 -o " + again).code, 0);
  EXPECT_EQ(Slurp(mks), Slurp(again));
}

TEST_F(GenerateCommandTest, ErrorsExitNonZeroAndWriteNothing) {
  const std::string bad_args[] = {
      "generate tanker --objects 0 -o " + (dir_ / "a.obj").string(),
      "generate tanker --objects -3 -o " + (dir_ / "a.obj").string(),
      "generate tanker --objects 10 -o " + (dir_ / "a.ply").string(),
      "generate tanker --objects 10 -o " + (dir_ / "missing_dir" / "a.mks").string(),
      "generate boat --objects 10 -o " + (dir_ / "a.obj").string(),
  };
  for (const std::string& args : bad_args) {
    const testing::ToolRun r = Mktree(args);
    EXPECT_NE(r.code, 0) << args;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << args << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_TRUE(fs::is_empty(dir_));
}

}  // namespace
}  // namespace mktree
