// Bad command lines and bad files, every subcommand (docs/cli.md, "Exit codes and errors"): each is refused
// with exactly one "error: ..." line and its exit code (2: the command line does not parse, 1: a value or
// file is refused), nothing is written, and no input is touched. Files that are not regular (FIFOs,
// directories, devices) are refused without blocking, and an output never replaces one of the inputs.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "test_dirs.h"
#include "tool_runner.h"

namespace {

namespace fs = std::filesystem;
using mktree::testing::Slurp;
using mktree::testing::ToolRun;

// The tool under test: MKTREE_TOOL, or $MKTREE_TEST_TOOL (to run these cases against another build).
std::string Tool() {
  const char* other = std::getenv("MKTREE_TEST_TOOL");
  return other != nullptr && *other != '\0' ? other : MKTREE_TOOL;
}

// Like RunMktree, but a run that blocks (a FIFO opened for reading) is killed after 20 s (exit 124)
// instead of hanging the suite.
ToolRun RunTool(const std::string& args, const fs::path& scratch) {
  const fs::path out = scratch / "stdout.txt", err = scratch / "stderr.txt";
  const std::string cmd =
      "timeout 20 " + Tool() + " " + args + " </dev/null >" + out.string() + " 2>" + err.string();
  const int status = std::system(cmd.c_str());
  ToolRun r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = Slurp(out);
  r.err = Slurp(err);
  fs::remove(out);
  fs::remove(err);
  return r;
}

class CliArgsTest : public ::testing::Test {
 protected:
  // in/: a scene, a store built from it, a query file; scratch/: the runner's capture files; out/: where
  // each case may name its output, and which must stay empty.
  static void SetUpTestSuite() {
    root_ = new mktree::testing::TempDir("mktree_cli_args");
    fs::create_directories(*root_ / "in");
    fs::create_directories(*root_ / "scratch");
    std::ofstream(In("scene.obj"))
        << "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
        << "o b\nv 2 0 0\nv 3 0 0\nv 2 1 0\nf 5 6 7\n";
    std::ofstream(In("q.txt")) << "point 0.1 0.1 0.1\n";
    const ToolRun b = RunTool(
        "build " + In("scene.obj") + " -o " + In("store.mkt") + " --backend pagefile -q", *root_ / "scratch");
    ASSERT_EQ(b.code, 0) << b.err;
    ASSERT_EQ(::mkfifo(In("fifo.mkt").c_str(), 0644), 0);
    ASSERT_EQ(::mkfifo(In("fifo.obj").c_str(), 0644), 0);
    fs::create_directories(In("dir.mkt"));
    for (const auto& e : fs::directory_iterator(*root_ / "in"))
      if (e.is_regular_file()) (*inputs_)[e.path().filename().string()] = Slurp(e.path());
  }
  static void TearDownTestSuite() { delete root_; }
  void SetUp() override {
    fs::remove_all(*root_ / "out");
    fs::create_directories(*root_ / "out");
  }

  static std::string In(const std::string& name) { return (*root_ / "in" / name).string(); }
  static std::string Out(const std::string& name) { return (*root_ / "out" / name).string(); }

  // $STORE, $SCENE, $QUERIES, $IN/ and $OUT/ in `args` name the files above.
  static std::string Expand(std::string args) {
    const std::pair<std::string, std::string> vars[] = {{"$STORE", In("store.mkt")},
                                                        {"$SCENE", In("scene.obj")},
                                                        {"$QUERIES", In("q.txt")},
                                                        {"$IN/", (*root_ / "in").string() + "/"},
                                                        {"$OUT/", (*root_ / "out").string() + "/"}};
    for (const auto& [var, value] : vars)
      for (size_t at; (at = args.find(var)) != std::string::npos;) args.replace(at, var.size(), value);
    return args;
  }

  // The run fails with `code`, one "error: " line that contains `needle` (after Expand), writes nothing
  // in out/ and leaves every input as it was.
  static void ExpectRefused(const std::string& args, int code, const std::string& needle) {
    const std::string expanded = Expand(args);
    SCOPED_TRACE(expanded);
    const ToolRun r = RunTool(expanded, *root_ / "scratch");
    EXPECT_EQ(r.code, code) << r.err;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(Expand(needle)), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    std::vector<std::string> written;
    for (const auto& e : fs::directory_iterator(*root_ / "out"))
      written.push_back(e.path().filename().string());
    EXPECT_TRUE(written.empty()) << "written: " << written.front();
    std::map<std::string, std::string> now;
    for (const auto& e : fs::directory_iterator(*root_ / "in"))
      if (e.is_regular_file()) now[e.path().filename().string()] = Slurp(e.path());
    EXPECT_TRUE(now == *inputs_) << "an input was changed, or a file was left next to the inputs";
  }

  static mktree::testing::TempDir* root_;
  static std::map<std::string, std::string>* inputs_;
};

mktree::testing::TempDir* CliArgsTest::root_ = nullptr;
std::map<std::string, std::string>* CliArgsTest::inputs_ = new std::map<std::string, std::string>;

struct BadRun {
  const char* args;
  int code;
  const char* needle;  // in the error line
};

// Numbers: negative, zero where meaningless, overflow, junk after a number, empty, NaN/Inf, and
// tanker:N[:SEED] forms. Exit 2: the value is not a number of the option's kind; 1: out of its range.
const BadRun kBadNumbers[] = {
    {"generate tanker --objects -1 -o $OUT/t.obj", 2, "--objects: '-1'"},
    {"generate tanker --objects 0 -o $OUT/t.obj", 1, "--objects"},
    {"generate tanker --objects 4294967297 -o $OUT/t.obj", 1, "--objects"},
    {"generate tanker --objects 99999999999999999999 -o $OUT/t.obj", 2, "--objects"},
    {"generate tanker --objects 12abc -o $OUT/t.obj", 2, "'12abc'"},
    {"generate tanker --objects '' -o $OUT/t.obj", 2, "--objects: ''"},
    {"generate tanker --objects 1.5 -o $OUT/t.obj", 2, "--objects"},
    {"generate tanker --objects 0x10 -o $OUT/t.obj", 2, "--objects"},
    {"generate tanker --objects 10 --seed -1 -o $OUT/t.obj", 2, "--seed"},
    {"generate tanker --objects 10 --seed 18446744073709551616 -o $OUT/t.obj", 2, "--seed"},
    {"generate tanker --objects 10 -o ''", 1, "empty"},
    {"generate queries $STORE -o $OUT/q.txt --count -1", 2, "--count: '-1'"},
    {"generate queries $STORE -o $OUT/q.txt --count 0", 1, "--count"},
    {"generate queries $STORE -o $OUT/q.txt --count 99999999999999999999", 2, "--count"},
    {"generate queries $STORE -o $OUT/q.txt --count 12abc", 2, "--count"},
    {"generate queries $STORE -o $OUT/q.txt --count ''", 2, "--count"},
    {"generate queries $STORE -o $OUT/q.txt --seed -1", 2, "--seed"},
    {"generate queries $STORE -o $OUT/q.txt --sides ''", 1, "--sides"},
    {"generate queries $STORE -o $OUT/q.txt --sides 1,,2", 1, "--sides"},
    {"generate queries $STORE -o $OUT/q.txt --sides 0", 1, "--sides"},
    {"generate queries $STORE -o $OUT/q.txt --sides 2,-1", 1, "'-1'"},
    {"generate queries $STORE -o $OUT/q.txt --sides nan", 1, "'nan'"},
    {"generate queries $STORE -o $OUT/q.txt --sides inf", 1, "'inf'"},
    {"generate queries $STORE -o $OUT/q.txt --sides 1e999", 1, "'1e999'"},
    {"generate queries $STORE -o $OUT/q.txt --sides 2abc", 1, "'2abc'"},
    {"generate queries $STORE -o ''", 1, "empty"},
    {"build tanker:10:abc -o $OUT/s.mkt", 1, "tanker:10:abc"},
    {"build tanker:10: -o $OUT/s.mkt", 1, "tanker:10:"},
    {"build tanker: -o $OUT/s.mkt", 1, "tanker:"},
    {"build tanker:0 -o $OUT/s.mkt", 1, "tanker:0"},
    {"build tanker:-10 -o $OUT/s.mkt", 1, "tanker:-10"},
    {"build 'tanker: 10' -o $OUT/s.mkt", 1, "tanker: 10"},
    {"build tanker:10x -o $OUT/s.mkt", 1, "tanker:10x"},
    {"build tanker:10:1:2 -o $OUT/s.mkt", 1, "tanker:10:1:2"},
    {"build tanker:10:-1 -o $OUT/s.mkt", 1, "tanker:10:-1"},
    {"build tanker:4294967297 -o $OUT/s.mkt", 1, "tanker:4294967297"},
    {"build tanker:99999999999999999999 -o $OUT/s.mkt", 1, "tanker:99999999999999999999"},
    {"build tanker:10:18446744073709551616 -o $OUT/s.mkt", 1, "tanker:10:18446744073709551616"},
    {"build tanker:10 -o $OUT/s.mkt --block-size -1", 2, "--block-size"},
    {"build tanker:10 -o $OUT/s.mkt --block-size 0", 1, "--block-size"},
    {"build tanker:10 -o $OUT/s.mkt --block-size 16", 1, "--block-size"},
    {"build tanker:10 -o $OUT/s.mkt --block-size 99999999999", 2, "--block-size"},
    {"build tanker:10 -o $OUT/s.mkt --block-size 4096abc", 2, "--block-size"},
    {"build tanker:10 -o $OUT/s.mkt --block-size ''", 2, "--block-size"},
    {"build tanker:10 -o $OUT/s.mkt --blocks-per-page 0", 1, "--block-size"},
    {"build tanker:10 -o $OUT/s.mkt --blocks-per-page -3", 2, "--blocks-per-page"},
    {"build tanker:10 -o $OUT/s.mkt --blocks-per-page 1000000", 1, "1 GiB"},
    {"build tanker:10 -o $OUT/s.mkt --zstd-level 99", 1, "--zstd-level"},
    {"build tanker:10 -o $OUT/s.mkt --zstd-level -999999999", 1, "--zstd-level"},
    {"build tanker:10 -o $OUT/s.mkt --zstd-level 99999999999", 2, "--zstd-level"},
    {"build tanker:10 -o $OUT/s.mkt --zstd-level 3x", 2, "--zstd-level"},
    {"build tanker:10 -o $OUT/s.mkt --r -0.1", 1, "--r"},
    {"build tanker:10 -o $OUT/s.mkt --r 0.5", 1, "--r"},
    {"build tanker:10 -o $OUT/s.mkt --r nan", 1, "--r"},
    {"build tanker:10 -o $OUT/s.mkt --r inf", 1, "--r"},
    {"build tanker:10 -o $OUT/s.mkt --r ''", 2, "--r"},
    {"build tanker:10 -o $OUT/s.mkt --r 0.1x", 2, "--r"},
    {"build tanker:10 -o $OUT/s.mkt --split-budget -1", 2, "--split-budget"},
    {"build tanker:10 -o $OUT/s.mkt --split-budget 99999999999", 2, "--split-budget"},
    {"build tanker:10 -o $OUT/s.mkt --split-budget ''", 2, "--split-budget"},
    {"build tanker:10 -o $OUT/s.mkt --backend ''", 1, "--backend"},
    {"build tanker:10 -o $OUT/s.mkt --codec ''", 1, "--codec"},
    {"build tanker:10 -o $OUT/s.mkt --split-policy ''", 1, "--split-policy"},
    {"build tanker:10 -o ''", 1, "empty"},
    {"build '' -o $OUT/s.mkt", 1, "empty"},
    {"query $STORE --point ''", 1, "--point"},
    {"query $STORE --box ''", 1, "--box"},
    {"query $STORE --point 1,2", 1, "--point"},
    {"query $STORE --point 1,2,3,4", 1, "--point"},
    {"query $STORE --point 1,,2,3", 1, "--point"},
    {"query $STORE --point 1,2,3abc", 1, "3abc"},
    {"query $STORE --point nan,0,0", 1, "nan"},
    {"query $STORE --point 0,-inf,0", 1, "-inf"},
    {"query $STORE --point 0,0,1e999", 1, "1e999"},
    {"query $STORE --box 1,1,1,0,0,0", 1, "--box"},
    {"query $STORE --box 0,0,0,1,1", 1, "--box"},
    {"query $STORE --box 0,0,nan,1,1,1", 1, "nan"},
    {"query $STORE --point 0,0,0 --cache-pages -1", 2, "--cache-pages"},
    {"query $STORE --point 0,0,0 --cache-pages 99999999999999999999", 2, "--cache-pages"},
    {"query $STORE --point 0,0,0 --cache-pages 12abc", 2, "--cache-pages"},
    {"query $STORE --point 0,0,0 --cache-pages ''", 2, "--cache-pages"},
    {"query $STORE --queries ''", 1, "--queries"},
    {"query $STORE", 2, "--point"},
    {"query '' --point 0,0,0", 1, "empty"},
    {"info ''", 1, "empty"},
    {"export $STORE --level -1 -o $OUT/e.ply", 1, "--level"},
    {"export $STORE --level 99999999999 -o $OUT/e.ply", 2, "--level"},
    {"export $STORE --level '' -o $OUT/e.ply", 2, "--level"},
    {"export $STORE --level 1x -o $OUT/e.ply", 2, "--level"},
    {"export $STORE --level 0 -o ''", 1, "empty"},
    {"render $STORE --level -1 -o $OUT/r.png", 1, "--level"},
    {"render $STORE --level '' -o $OUT/r.png", 2, "--level"},
    {"render $STORE --level 0 -o $OUT/r.png --size ''", 1, "--size"},
    {"render $STORE --level 0 -o $OUT/r.png --size -64x64", 1, "--size"},
    {"render $STORE --level 0 -o $OUT/r.png --size 64x", 1, "--size"},
    {"render $STORE --level 0 -o $OUT/r.png --size x64", 1, "--size"},
    {"render $STORE --level 0 -o $OUT/r.png --size 64x64x", 1, "--size"},
    {"render $STORE --level 0 -o $OUT/r.png --size ' 64x64'", 1, "--size"},
    {"render $STORE --level 0 -o $OUT/r.png --size 10x10", 1, "--size"},
    {"render $STORE --level 0 -o $OUT/r.png --size 99999999999x64", 1, "--size"},
    {"render $STORE --level 0 -o $OUT/r.png --view ''", 1, "--view"},
};

TEST_F(CliArgsTest, BadNumbersAndValuesAreRefused) {
  for (const BadRun& c : kBadNumbers) ExpectRefused(c.args, c.code, c.needle);
}

// Inputs that are not regular files: a FIFO (reading it would block), a directory, a device.
const BadRun kNotRegularInputs[] = {
    {"info $IN/fifo.mkt", 1, "$IN/fifo.mkt: not a regular file"},
    {"info $IN/dir.mkt", 1, "$IN/dir.mkt: not a regular file"},
    {"info /dev/null", 1, "/dev/null: not a regular file"},
    {"query $IN/fifo.mkt --point 0,0,0", 1, "$IN/fifo.mkt: not a regular file"},
    {"query /dev/null --point 0,0,0", 1, "/dev/null: not a regular file"},
    {"query $STORE --queries $IN/fifo.obj", 1, "$IN/fifo.obj: not a regular file"},
    {"query $STORE --queries $IN/dir.mkt", 1, "$IN/dir.mkt: not a regular file"},
    {"query $STORE --queries /dev/null", 1, "/dev/null: not a regular file"},
    {"generate queries $IN/fifo.mkt -o $OUT/q.txt", 1, "$IN/fifo.mkt: not a regular file"},
    {"export $IN/fifo.mkt --level 0 -o $OUT/e.ply", 1, "$IN/fifo.mkt: not a regular file"},
    {"render $IN/fifo.mkt --level 0 -o $OUT/r.png", 1, "$IN/fifo.mkt: not a regular file"},
    {"render $IN/dir.mkt --level 0 -o $OUT/r.png", 1, "$IN/dir.mkt: not a regular file"},
    {"build $IN/fifo.obj -o $OUT/s.mkt", 1, "$IN/fifo.obj: not a regular file"},
    {"build $SCENE $IN/dir.mkt -o $OUT/s.mkt", 1, "$IN/dir.mkt: not a regular file"},
    {"build /dev/null -o $OUT/s.mkt", 1, "/dev/null: not a regular file"},
};

TEST_F(CliArgsTest, InputsThatAreNotRegularFilesAreRefusedWithoutBlocking) {
  for (const BadRun& c : kNotRegularInputs) ExpectRefused(c.args, c.code, c.needle);
}

// The output names an input (the same path written differently, a hard link, a symbolic link), or is
// something a store must not replace.
TEST_F(CliArgsTest, AnOutputThatIsAnInputOrNotARegularFileIsRefused) {
  const BadRun cases[] = {
      {"build $SCENE -o $SCENE", 1, "$SCENE: the output is the input"},
      {"build $SCENE -o $IN/./scene.obj", 1, "the output is the input $SCENE"},
      {"build tanker:10 $SCENE -o $SCENE --backend pagefile", 1, "the output is the input"},
      {"build $SCENE -o $IN/scene-hardlink.obj", 1, "the output is the input $SCENE"},
      {"build $SCENE -o $IN/scene-symlink.obj", 1, "the output is the input $SCENE"},
      {"generate queries $STORE -o $STORE", 1, "the output is the input $STORE"},
      {"export $IN/store.ply --level 0 -o $IN/store.ply", 1, "the output is the input"},
      {"render $IN/store.png --level 0 -o $IN/store.png", 1, "the output is the input"},
      {"build $SCENE -o $IN/dir.mkt", 1, "$IN/dir.mkt: the output exists and is a directory"},
      {"build $SCENE -o $IN/fifo.mkt", 1, "$IN/fifo.mkt: the output exists and is a FIFO"},
      {"build $SCENE -o /dev/null", 1, "/dev/null: the output exists and is a character device"},
      {"generate tanker --objects 10 -o $IN/fifo.obj", 1, "the output exists and is a FIFO"},
      {"generate queries $STORE -o $IN/dir.mkt", 1, "the output exists and is a directory"},
  };
  fs::create_hard_link(In("scene.obj"), In("scene-hardlink.obj"));
  fs::create_symlink(In("scene.obj"), In("scene-symlink.obj"));
  fs::copy_file(In("store.mkt"), In("store.ply"));
  fs::copy_file(In("store.mkt"), In("store.png"));
  for (const char* name : {"scene-hardlink.obj", "scene-symlink.obj", "store.ply", "store.png"})
    (*inputs_)[name] = Slurp(In(name));
  for (const BadRun& c : cases) ExpectRefused(c.args, c.code, c.needle);
  for (const char* name : {"scene-hardlink.obj", "scene-symlink.obj", "store.ply", "store.png"}) {
    fs::remove(In(name));
    inputs_->erase(name);
  }
  EXPECT_TRUE(fs::is_fifo(In("fifo.mkt")));
  EXPECT_TRUE(fs::is_directory(In("dir.mkt")));
}

}  // namespace
