// The HDF5 backend's own failure modes: HDF5 errors reach the user as one line and HDF5 prints nothing
// itself, from any thread.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "storage/store_file.h"
#include "storage_test_util.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::BuiltStore;
using testing::TempDir;

Status WriteHdf5(const std::string& path, const std::vector<SceneObject>& objects) {
  StoreOptions o;
  o.backend = Backend::kHdf5;
  auto w = StoreWriter::Create(path, o);
  if (!w.ok()) return w.status();
  BuiltStore built;
  MKTREE_RETURN_IF_ERROR(testing::BuildTestStore(objects, o.codec, o.params, &(*w)->pages(), &built));
  for (const SceneObject& o2 : objects)
    MKTREE_RETURN_IF_ERROR((*w)->AppendObject(o2.id, built.object_leaf[o2.id], o2.name));
  return (*w)->Commit(built.tree, "{\"test\": 1}");
}

// Redirects this process's stderr (fd 2) to a file while in scope; text() is what was written.
class CaptureStderr {
 public:
  explicit CaptureStderr(std::string path) : path_(std::move(path)) {
    std::fflush(stderr);
    saved_ = ::dup(2);
    const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 2);
    ::close(fd);
  }
  ~CaptureStderr() { Restore(); }
  std::string text() {
    Restore();
    return testing::Slurp(path_);
  }

 private:
  void Restore() {
    if (saved_ < 0) return;
    std::fflush(stderr);
    ::dup2(saved_, 2);
    ::close(saved_);
    saved_ = -1;
  }
  std::string path_;
  int saved_ = -1;
};

// The descriptor this process holds on `path` (HDF5's), or -1.
int DescriptorOf(const std::string& path) {
  const auto want = std::filesystem::canonical(path);
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) {
    std::error_code ec;
    const auto target = std::filesystem::read_symlink(e.path(), ec);
    if (!ec && target == want) return std::stoi(e.path().filename().string());
  }
  return -1;
}

// A page read that fails in HDF5's own file driver (its descriptor replaced by a write-only one, so pread
// fails with EBADF), in a thread that never opened anything: one line naming the file and the page, and
// HDF5 prints nothing. (HDF5 1.10's message for this holds a ctime() string, newline included; and
// Debian's HDF5 is built thread-safe, so its error printing is per thread.)
TEST(Hdf5StoreTest, ReadErrorsInAnyThreadAreOneLineAndHdf5PrintsNothing) {
  TempDir dir;
  const std::string path = dir.file("s.mkt");
  ASSERT_TRUE(WriteHdf5(path, testing::MakeObjects(200, 31)).ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const int fd = DescriptorOf(path);
  ASSERT_GE(fd, 0);
  const int wronly = ::open(dir.file("junk").c_str(), O_WRONLY | O_CREAT, 0644);
  ASSERT_EQ(::dup2(wronly, fd), fd);
  ::close(wronly);
  Status st;
  H5E_auto2_t printer = nullptr;
  {
    CaptureStderr capture(dir.file("stderr.txt"));
    std::thread reader([&] {
      std::vector<uint8_t> page((*r)->pages().page_bytes());
      st = (*r)->pages().ReadPage(3, page.data());
      void* data = nullptr;
      H5Eget_auto2(H5E_DEFAULT, &printer, &data);
    });
    reader.join();
    EXPECT_EQ(capture.text(), "");
  }
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
  EXPECT_EQ(st.message().rfind(path + ": page 3: ", 0), 0u) << st.message();
  EXPECT_NE(st.message().find(std::strerror(EBADF)), std::string::npos) << st.message();
  EXPECT_EQ(printer, nullptr) << "HDF5's automatic error printing is on in a reading thread";
}

// ---- The command line on damaged stores ----

// Truncated, zeroed and bit-flipped copies of a store, through `info` and `query`: an answer (exit 0,
// nothing on stderr) or one `error:` line naming the file (exit 1); never a crash or HDF5's own output.
TEST(Hdf5CliTest, DamagedStoresGiveOneErrorLine) {
  TempDir dir;
  auto run = [&](const std::string& args) { return mktree::testing::RunMktree(args, dir.path()); };
  const std::string good = dir.file("good.mkt"), bad = dir.file("bad.mkt");
  ASSERT_EQ(run("build tanker:1500:4 -q -o " + good).code, 0);
  std::ifstream in(good, std::ios::binary);
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  const size_t n = bytes.size();
  std::mt19937 g(5);
  int errors = 0, answers = 0;
  for (int i = 0; i < 60; ++i) {
    std::vector<uint8_t> b = bytes;
    // Half of the damage near the start and the end, where HDF5 keeps its superblock and our metadata.
    const size_t off = i % 2 ? g() % n : (i % 4 ? g() % 8192 : n - 1 - g() % std::min<size_t>(n, 40000));
    if (i % 3 == 0) {
      b.resize(off);
    } else if (i % 3 == 1) {
      std::fill(b.begin() + off, b.begin() + std::min(n, off + 512), 0);
    } else {
      b[off] ^= static_cast<uint8_t>(1u << (g() % 8));
    }
    std::ofstream(bad, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(b.data()), b.size());
    for (const std::string& args : {"info " + bad, "query " + bad + " --box 0,-30,0,300,30,40"}) {
      SCOPED_TRACE(args + " (damage " + std::to_string(i) + " at " + std::to_string(off) + ")");
      const auto r = run(args);
      ASSERT_TRUE(r.code == 0 || r.code == 1) << "exit " << r.code << "\n" << r.err;
      if (r.code == 0) {
        EXPECT_EQ(r.err, "");
        ++answers;
      } else {
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
        EXPECT_NE(r.err.find("bad.mkt"), std::string::npos) << r.err;
        ++errors;
      }
    }
  }
  std::printf("[damaged stores] %d errors, %d answers\n", errors, answers);
  EXPECT_GT(errors, 40);
}

}  // namespace
}  // namespace mktree
