// OpenUnnamedFile: a scratch file that works like any other, in the folder asked for ($TMPDIR when none),
// that never shows in the folder, and a clear error when the folder cannot take it.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "storage/file_util.h"
#include "test_dirs.h"

namespace mktree::storage_internal {
namespace {

namespace fs = std::filesystem;

TEST(OpenUnnamedFileTest, WritesAndReadsBackAndLeavesNothingInTheFolder) {
  testing::TempDir dir("mktree_unnamed");
  auto file = OpenUnnamedFile(dir.path().string(), ".scratch", "a test's scratch file");
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  ASSERT_GE(file->fd, 0);
  EXPECT_EQ(file->where.rfind(dir.path().string() + "/.scratch.", 0), 0u) << file->where;
  const std::string text = "spilled bytes";
  ASSERT_TRUE(PwriteFull(file->fd, text.data(), text.size(), 4096, file->where).ok());
  std::string back(text.size(), '\0');
  ASSERT_TRUE(PreadFull(file->fd, back.data(), back.size(), 4096, file->where).ok());
  EXPECT_EQ(back, text);
  EXPECT_TRUE(fs::is_empty(dir.path()));
  // Close-on-exec: a child the process starts does not inherit the spill.
  EXPECT_NE(::fcntl(file->fd, F_GETFD) & FD_CLOEXEC, 0);
  ::close(file->fd);
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

TEST(OpenUnnamedFileTest, NoFolderMeansTmpdir) {
  testing::TempDir dir("mktree_unnamed_tmpdir");
  const char* old = std::getenv("TMPDIR");
  const std::string saved = old != nullptr ? old : "";
  ::setenv("TMPDIR", dir.path().c_str(), 1);
  auto file = OpenUnnamedFile("", ".scratch", "a test's scratch file");
  if (old != nullptr)
    ::setenv("TMPDIR", saved.c_str(), 1);
  else
    ::unsetenv("TMPDIR");
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  EXPECT_EQ(file->where.rfind(dir.path().string() + "/", 0), 0u) << file->where;
  ::close(file->fd);
}

TEST(OpenUnnamedFileTest, AFolderThatCannotTakeItIsAnIoErrorNamingIt) {
  testing::TempDir dir("mktree_unnamed_missing");
  const std::string missing = (dir.path() / "missing").string();
  auto file = OpenUnnamedFile(missing, ".scratch", "the spill of a test");
  ASSERT_FALSE(file.ok());
  EXPECT_EQ(file.status().code(), Status::Code::kIOError);
  EXPECT_EQ(file.status().message().rfind(missing + ": cannot create the spill of a test: ", 0), 0u)
      << file.status().ToString();
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

}  // namespace
}  // namespace mktree::storage_internal
