// mktree export and mktree render from the command line (docs/design.md §9, docs/cli.md): good runs write
// the file with the right magic and size and print a summary; bad arguments and files give one
// "error: ..." line naming the file, a non-zero exit, and leave nothing behind.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "test_dirs.h"
#include "tool_runner.h"

namespace {

namespace fs = std::filesystem;

using RunResult = mktree::testing::ToolRun;
using mktree::testing::Slurp;

class ExportRenderCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new mktree::testing::TempDir("mktree_viz_cli");
    fs::create_directories(*dir_ / "store");
    store_ = new std::string((*dir_ / "store" / "ship.mkt").string());
    // A small tanker straight from the generator: a real tree with all three groups at level 1.
    const RunResult b = Run("build tanker:3000:1 -o " + *store_ + " --backend pagefile --quiet");
    ASSERT_EQ(b.code, 0) << b.err;
  }
  static void TearDownTestSuite() {
    delete store_;
    delete dir_;
  }
  void SetUp() override {
    out_ = *dir_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(out_);
  }
  void TearDown() override { fs::remove_all(out_); }

  std::string P(const std::string& name) const { return (out_ / name).string(); }

  static RunResult Run(const std::string& args) { return mktree::testing::RunMktree(args, *dir_); }
  std::vector<std::string> Files() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(out_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }
  // A failed run: non-zero exit, one "error: " line mentioning `needle`, nothing written.
  void ExpectFailure(const std::string& args, const std::string& needle) const {
    SCOPED_TRACE(args);
    const RunResult r = Run(args);
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
    EXPECT_TRUE(Files().empty());
  }

  static mktree::testing::TempDir* dir_;
  static std::string* store_;
  fs::path out_;
};

mktree::testing::TempDir* ExportRenderCliTest::dir_ = nullptr;
std::string* ExportRenderCliTest::store_ = nullptr;

uint32_t BigEndian32(const std::string& s, size_t at) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) v = v << 8 | static_cast<uint8_t>(s[at + i]);
  return v;
}

TEST_F(ExportRenderCliTest, ExportWritesPlyAndGlb) {
  RunResult r = Run("export " + *store_ + " --level 1 -o " + P("ship.ply"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("exported " + P("ship.ply") + ": level 1 geometry, 3000 objects"), std::string::npos)
      << r.out;
  const std::string ply = Slurp(P("ship.ply"));
  EXPECT_EQ(ply.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(ply.find("property uchar red"), std::string::npos);

  r = Run("export " + *store_ + " --level 0 --boxes -o " + P("ship.glb") + " --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  const std::string glb = Slurp(P("ship.glb"));
  ASSERT_GE(glb.size(), 20u);
  EXPECT_EQ(glb.substr(0, 4), "glTF");
  EXPECT_EQ(glb.substr(16, 4), "JSON");
  // Boxes: 3000 objects x 8 vertices, split over the groups' position accessors.
  EXPECT_NE(glb.find("\"baseColorFactor\""), std::string::npos);
  const std::regex position("\"componentType\":5126,\"count\":([0-9]+)");
  uint64_t vertices = 0;
  for (auto it = std::sregex_iterator(glb.begin(), glb.end(), position); it != std::sregex_iterator(); ++it)
    vertices += std::stoull((*it)[1].str());
  EXPECT_EQ(vertices, 3000u * 8);
  EXPECT_EQ(Files(),
            (std::vector<std::string>{"ship.glb", "ship.ply"}));  // no temporary or scratch file left
}

TEST_F(ExportRenderCliTest, RenderWritesAPngOfTheRequestedSize) {
  RunResult r = Run("render " + *store_ + " --level 1 -o " + P("top.png") + " --size 640x200 --overlay");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("rendered " + P("top.png") + ": 640x200, level 1, top view, 3000 objects"),
            std::string::npos)
      << r.out;
  std::string png = Slurp(P("top.png"));
  ASSERT_GE(png.size(), 24u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  EXPECT_EQ(png.substr(12, 4), "IHDR");
  EXPECT_EQ(BigEndian32(png, 16), 640u);
  EXPECT_EQ(BigEndian32(png, 20), 200u);

  r = Run("render " + *store_ + " --level 2 -o " + P("side.png") + " --view side --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  png = Slurp(P("side.png"));
  ASSERT_GE(png.size(), 24u);
  EXPECT_EQ(BigEndian32(png, 16), 1600u);  // the default size
  EXPECT_EQ(BigEndian32(png, 20), 400u);
  EXPECT_EQ(Files(), (std::vector<std::string>{"side.png", "top.png"}));
}

TEST_F(ExportRenderCliTest, BadArgumentsAndFilesAreRefused) {
  ExpectFailure("export " + *store_ + " --level -1 -o " + P("a.ply"), "--level");
  ExpectFailure("export " + *store_ + " --level 1 -o " + P("a.obj"), P("a.obj"));
  ExpectFailure("export " + P("missing.mkt") + " --level 1 -o " + P("a.ply"), "missing.mkt");
  ExpectFailure("export " + *store_ + " --level 1 -o " + P("no/such/dir/a.glb"), P("no/such/dir/a.glb"));
  ExpectFailure("export " + *store_ + " -o " + P("a.ply"), "--level");  // --level is required
  ExpectFailure("render " + *store_ + " --level -2 -o " + P("a.png"), "--level");
  ExpectFailure("render " + *store_ + " --level 1 -o " + P("a.png") + " --view diagonal", "diagonal");
  ExpectFailure("render " + *store_ + " --level 1 -o " + P("a.png") + " --size 800", "--size");
  ExpectFailure("render " + *store_ + " --level 1 -o " + P("a.png") + " --size 10x10", "--size");
  ExpectFailure("render " + *store_ + " --level 1 -o " + P("a.jpg"), P("a.jpg"));
  ExpectFailure("render " + *store_ + " --level 1 -o " + P("no/dir/a.png"), P("no/dir/a.png"));

  // A file that is not a store is refused, naming it.
  std::ofstream(P("fake.mkt")) << "not a store at all";
  const RunResult r = Run("render " + P("fake.mkt") + " --level 1 -o " + P("a.png"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("fake.mkt"), std::string::npos) << r.err;
  EXPECT_EQ(Files(), std::vector<std::string>{"fake.mkt"});
}

}  // namespace
