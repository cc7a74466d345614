// AtomicFile: a commit puts the whole file in place; an abandoned file, and every failed write, fsync and
// rename, leaves the target as it was and no temporary; a failed fsync of the directory leaves the new file
// in place and says so. Stale temporaries of dead writers are removed, those of live writers kept.
#include "storage/atomic_file.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

// Fails the nth call (1-based) of one operation; counts every call.
class FaultyOps : public FileOps {
 public:
  enum class Op { kPwrite, kFsync, kRename, kNone };
  FaultyOps(Op op = Op::kNone, int nth = 0) : op_(op), nth_(nth) {}

  ssize_t Pwrite(int fd, const void* buf, size_t n, uint64_t offset) override {
    if (Hit(Op::kPwrite)) return Fail(ENOSPC);
    if (short_writes_ && n > 1) n /= 2;  // the rest is the caller's to retry
    return FileOps::Pwrite(fd, buf, n, offset);
  }
  int Fsync(int fd) override { return Hit(Op::kFsync) ? Fail(EIO) : FileOps::Fsync(fd); }
  int Rename(const std::string& from, const std::string& to) override {
    return Hit(Op::kRename) ? Fail(EXDEV) : FileOps::Rename(from, to);
  }

  int calls(Op op) const { return calls_[static_cast<int>(op)]; }
  void set_short_writes() { short_writes_ = true; }

 private:
  bool Hit(Op op) { return ++calls_[static_cast<int>(op)] == nth_ && op == op_; }
  static int Fail(int err) {
    errno = err;
    return -1;
  }
  Op op_;
  int nth_;
  int calls_[4] = {};
  bool short_writes_ = false;
};

std::string Read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void Put(const std::string& path, const std::string& content) {
  std::ofstream(path, std::ios::binary) << content;
}

std::vector<std::string> Names(const testing::TempDir& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir.path())) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// More than the file's buffer, so that writes reach the file before Commit.
std::string Big(char c) { return std::string((size_t{3} << 20) + 17, c); }

class AtomicFileTest : public ::testing::Test {
 protected:
  testing::TempDir dir_{"mktree_atomic_file"};
  const std::string target_ = dir_.file("out.bin");
};

TEST_F(AtomicFileTest, CommitPutsTheWholeFileInPlace) {
  auto f = AtomicFile::Create(target_);
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  EXPECT_EQ((*f)->temp_path(), target_ + ".tmp." + std::to_string(::getpid()));
  EXPECT_EQ(AtomicTempPath(target_), (*f)->temp_path());
  ASSERT_TRUE((*f)->Write("header:0000\n", 12).ok());
  const std::string big = Big('x');
  ASSERT_TRUE((*f)->Write(big.data(), big.size()).ok());
  ASSERT_TRUE((*f)->Write("end\n", 4).ok());
  ASSERT_TRUE((*f)->WriteAt(7, "1234", 4).ok());  // a header patched at the end
  EXPECT_EQ((*f)->size(), 16 + big.size());
  EXPECT_FALSE((*f)->WriteAt((*f)->size() - 2, "abc", 3).ok());  // past what was written
  EXPECT_FALSE(fs::exists(target_));                             // nothing at the target before the commit
  ASSERT_TRUE((*f)->Commit().ok());
  EXPECT_EQ(Read(target_), "header:1234\n" + big + "end\n");
  EXPECT_EQ(Names(dir_), std::vector<std::string>{"out.bin"});
  EXPECT_FALSE((*f)->Write("x", 1).ok());  // no calls after Commit
  EXPECT_FALSE((*f)->Commit().ok());
}

TEST_F(AtomicFileTest, CommitReplacesTheTarget) {
  Put(target_, "old");
  auto f = AtomicFile::Create(target_);
  ASSERT_TRUE(f.ok());
  ASSERT_TRUE((*f)->Write("new", 3).ok());
  EXPECT_EQ(Read(target_), "old");
  ASSERT_TRUE((*f)->Commit().ok());
  EXPECT_EQ(Read(target_), "new");
  EXPECT_EQ(Names(dir_), std::vector<std::string>{"out.bin"});
}

TEST_F(AtomicFileTest, AbandonedFileLeavesTheTargetAndNoTemporary) {
  Put(target_, "old");
  {
    auto f = AtomicFile::Create(target_);
    ASSERT_TRUE(f.ok());
    const std::string big = Big('y');
    ASSERT_TRUE((*f)->Write(big.data(), big.size()).ok());
    EXPECT_TRUE(fs::exists((*f)->temp_path()));
  }
  EXPECT_EQ(Read(target_), "old");
  EXPECT_EQ(Names(dir_), std::vector<std::string>{"out.bin"});
  {
    auto f = AtomicFile::Create(dir_.file("never.bin"));  // nothing written, nothing committed
    ASSERT_TRUE(f.ok());
  }
  EXPECT_EQ(Names(dir_), std::vector<std::string>{"out.bin"});
}

TEST_F(AtomicFileTest, ShortWritesAreCompleted) {
  FaultyOps ops;
  ops.set_short_writes();
  auto f = AtomicFile::Create(target_, ops);
  ASSERT_TRUE(f.ok());
  const std::string big = Big('z');
  ASSERT_TRUE((*f)->Write(big.data(), big.size()).ok());
  ASSERT_TRUE((*f)->Write("tail", 4).ok());
  ASSERT_TRUE((*f)->WriteAt(0, "HEAD", 4).ok());
  ASSERT_TRUE((*f)->Commit().ok());
  EXPECT_EQ(Read(target_), "HEAD" + big.substr(4) + "tail");
  EXPECT_GT(ops.calls(FaultyOps::Op::kPwrite), 4);
}

// Every failure before the rename: an IOError naming the target, the old file in place, no temporary.
TEST_F(AtomicFileTest, EveryFailureBeforeTheRenameLeavesTheTargetUntouched) {
  struct Case {
    FaultyOps::Op op;
    int nth;
    const char* says;
  };
  const Case cases[] = {
      {FaultyOps::Op::kPwrite, 1, "write failed"},  // a large write, straight to the file
      {FaultyOps::Op::kPwrite, 2, "write failed"},  // the buffered tail, at Commit
      {FaultyOps::Op::kFsync, 1, "fsync failed"},   // the file's fsync
      {FaultyOps::Op::kRename, 1, "rename from"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.says + std::string(" #") + std::to_string(c.nth));
    Put(target_, "old");
    FaultyOps ops(c.op, c.nth);
    Status st;
    {
      auto f = AtomicFile::Create(target_, ops);
      ASSERT_TRUE(f.ok());
      const std::string big = Big('n');
      st = (*f)->Write(big.data(), big.size());
      if (st.ok()) st = (*f)->Write("tail", 4);
      if (st.ok()) st = (*f)->Commit();
    }
    EXPECT_EQ(st.code(), Status::Code::kIOError) << st.ToString();
    EXPECT_EQ(st.message().rfind(target_, 0), 0u) << st.message();
    EXPECT_NE(st.message().find(c.says), std::string::npos) << st.message();
    EXPECT_EQ(Read(target_), "old");
    EXPECT_EQ(Names(dir_), std::vector<std::string>{"out.bin"});
  }
}

TEST_F(AtomicFileTest, FailedCommitRemovesTheTemporaryAtOnce) {
  FaultyOps ops(FaultyOps::Op::kRename, 1);
  auto f = AtomicFile::Create(target_, ops);
  ASSERT_TRUE(f.ok());
  ASSERT_TRUE((*f)->Write("data", 4).ok());
  EXPECT_FALSE((*f)->Commit().ok());
  EXPECT_TRUE(fs::is_empty(dir_.path()));  // not only once the object is destroyed
  EXPECT_FALSE((*f)->Commit().ok());
}

// After the rename only the directory's fsync can fail: the new file is in place, whole, and the error
// says that it may not survive a power loss.
TEST_F(AtomicFileTest, FailedDirectoryFsyncLeavesTheNewFileAndSaysSo) {
  Put(target_, "old");
  FaultyOps ops(FaultyOps::Op::kFsync, 2);
  auto f = AtomicFile::Create(target_, ops);
  ASSERT_TRUE(f.ok());
  ASSERT_TRUE((*f)->Write("new", 3).ok());
  const Status st = (*f)->Commit();
  EXPECT_EQ(ops.calls(FaultyOps::Op::kFsync), 2);
  EXPECT_EQ(st.code(), Status::Code::kIOError);
  EXPECT_NE(st.message().find("fsync directory"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find(target_ + " is in place but may not survive a power loss"), std::string::npos)
      << st.message();
  EXPECT_EQ(Read(target_), "new");
  EXPECT_EQ(Names(dir_), std::vector<std::string>{"out.bin"});
}

TEST_F(AtomicFileTest, ErrorsNameTheTarget) {
  const std::string missing = dir_.file("no_such_dir/out.bin");
  auto f = AtomicFile::Create(missing);
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.status().message(), missing + ": cannot create file: " + std::strerror(ENOENT));
  EXPECT_EQ(AtomicFile::Create("").status().code(), Status::Code::kInvalidArgument);
}

// The pieces the store uses: a failed rename leaves both files; a failed directory fsync names `what`.
TEST_F(AtomicFileTest, RenameOverTargetReportsWhichStepFailed) {
  const std::string temp = AtomicTempPath(target_);
  Put(target_, "old");
  Put(temp, "new");
  bool renamed = true;
  FaultyOps no_rename(FaultyOps::Op::kRename, 1);
  Status st = RenameOverTarget(temp, target_, no_rename, "the new store", &renamed);
  EXPECT_FALSE(renamed);
  EXPECT_EQ(st.message(), target_ + ": rename from " + temp + ": " + std::strerror(EXDEV));
  EXPECT_EQ(Read(target_), "old");
  FaultyOps no_dir_sync(FaultyOps::Op::kFsync, 1);
  st = RenameOverTarget(temp, target_, no_dir_sync, "the new store", &renamed);
  EXPECT_TRUE(renamed);
  EXPECT_NE(st.message().find("(the new store is in place but may not survive a power loss)"),
            std::string::npos)
      << st.message();
  EXPECT_EQ(Read(target_), "new");
  EXPECT_FALSE(fs::exists(temp));
}

TEST_F(AtomicFileTest, StaleTemporariesOfTheTargetAreRemoved) {
  // Left by writers killed before their commit (no process holds them), and names that only look alike.
  const std::vector<std::string> stale = {"out.bin.tmp.99999999", "out.bin.tmp.1",
                                          "out.bin.tmp." + std::to_string(::getpid())};
  const std::vector<std::string> kept = {"other.bin.tmp.99999999", "out.bin.tmp.12x", "out.bin.tmp.",
                                         "out.bin.notes", "xout.bin.tmp.5"};
  for (const auto& n : stale) Put(dir_.file(n), "left by a killed writer");
  for (const auto& n : kept) Put(dir_.file(n), "not a temporary of out.bin");
  auto f = AtomicFile::Create(target_);
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  ASSERT_TRUE((*f)->Commit().ok());
  for (const auto& n : stale) EXPECT_FALSE(fs::exists(dir_.file(n))) << n;
  for (const auto& n : kept) EXPECT_TRUE(fs::exists(dir_.file(n))) << n;
}

// Two writers of one target in this process: the second fails at Create and leaves the first alone.
TEST_F(AtomicFileTest, ASecondWriterOfTheSameTargetFails) {
  auto first = AtomicFile::Create(target_);
  ASSERT_TRUE(first.ok());
  ASSERT_TRUE((*first)->Write("first", 5).ok());
  auto second = AtomicFile::Create(target_);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().message().rfind(target_ + ": cannot create file: ", 0), 0u)
      << second.status().message();
  ASSERT_TRUE((*first)->Commit().ok());
  EXPECT_EQ(Read(target_), "first");
}

// A writer in another process: its temporary is kept while it lives, and removed by the next writer once
// it has died without committing.
TEST_F(AtomicFileTest, TemporaryOfALiveWriterIsKeptAndOfADeadOneRemoved) {
  int ready[2], go[2];
  ASSERT_EQ(::pipe(ready), 0);
  ASSERT_EQ(::pipe(go), 0);
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    auto f = AtomicFile::Create(target_);
    char c = f.ok() && (*f)->Write("child", 5).ok() ? 'y' : 'n';
    if (::write(ready[1], &c, 1) != 1 || ::read(go[0], &c, 1) != 1) ::_exit(3);
    ::_exit(0);  // killed, in effect: no destructor, no commit
  }
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  ASSERT_EQ(c, 'y');
  const std::string child_temp = target_ + ".tmp." + std::to_string(pid);
  {
    auto f = AtomicFile::Create(target_);
    ASSERT_TRUE(f.ok()) << f.status().ToString();
    EXPECT_TRUE(fs::exists(child_temp));  // the child still holds it
    ASSERT_TRUE((*f)->Write("parent", 6).ok());
    ASSERT_TRUE((*f)->Commit().ok());
  }
  ASSERT_EQ(::write(go[1], "x", 1), 1);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  for (int fd : {ready[0], ready[1], go[0], go[1]}) ::close(fd);
  EXPECT_TRUE(fs::exists(child_temp));  // what a killed writer leaves
  auto f = AtomicFile::Create(target_);
  ASSERT_TRUE(f.ok());
  EXPECT_FALSE(fs::exists(child_temp));
  ASSERT_TRUE((*f)->Commit().ok());
  EXPECT_EQ(Names(dir_), std::vector<std::string>{"out.bin"});
  // The store's cleanup (under its writer lock) is the same call.
  Put(child_temp, "left by a killed store writer");
  RemoveStaleTemps(target_);
  EXPECT_FALSE(fs::exists(child_temp));
}

}  // namespace
}  // namespace mktree
