// Full disks: a build whose store cannot be written, at any phase (leaf pages, the metadata written at
// Commit, HDF5's flush and truncate at close), ends with one clean error naming the file, leaves no temporary
// or lock file, keeps the previous store intact and answering, releases every HDF5 identifier, and the
// process goes on: it builds again, and exits without a crash (HDF5 1.10 crashed at exit after a failed
// close). Writes fail through RLIMIT_FSIZE with SIGXFSZ ignored (EFBIG past the limit), so no mount is
// needed; one test also fills a real tmpfs where mounting is permitted.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <set>

#include "engine/store_format/leaf_source.h"
#include "engine/store_format/store_file.h"
#include "storage/page_cache.h"
#include "store_format/store_test_util.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::BuiltStore;
using testing::TempDir;

std::vector<uint8_t> ReadBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), {});
}

std::set<std::string> Listing(const std::filesystem::path& dir) {
  std::set<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir)) out.insert(e.path().filename().string());
  return out;
}

// While in scope, writes by this process past `bytes` fail with EFBIG (RLIMIT_FSIZE, SIGXFSZ ignored).
class FileSizeLimit {
 public:
  explicit FileSizeLimit(uint64_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &saved_);
    old_ = ::signal(SIGXFSZ, SIG_IGN);
    rlimit r = saved_;
    r.rlim_cur = std::min<rlim_t>(bytes, saved_.rlim_max);
    ::setrlimit(RLIMIT_FSIZE, &r);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &saved_);
    ::signal(SIGXFSZ, old_);
  }

 private:
  rlimit saved_{};
  sighandler_t old_ = SIG_DFL;
};

// Open HDF5 identifiers of every kind the store code creates, and the objects open in any file.
std::vector<int64_t> Hdf5IdsAndOpenObjects() {
  std::vector<int64_t> n;
  for (H5I_type_t t :
       {H5I_FILE, H5I_GROUP, H5I_DATATYPE, H5I_DATASPACE, H5I_DATASET, H5I_ATTR, H5I_GENPROP_LST}) {
    hsize_t c = 0;
    H5Inmembers(t, &c);
    n.push_back(static_cast<int64_t>(c));
  }
  n.push_back(H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL));
  return n;
}

enum class Phase { kNone, kCreate, kPages, kCommit };

class FullDiskTest : public ::testing::TestWithParam<Backend> {
 protected:
  StoreOptions Options() const {
    StoreOptions o;
    o.backend = GetParam();
    return o;
  }
  // Builds a store of `objects` at `path`; *phase says which step failed.
  Status Write(const std::string& path, const std::vector<SceneObject>& objects, Phase* phase = nullptr) {
    Phase ignored;
    Phase& at = phase ? *phase : ignored;
    at = Phase::kCreate;
    auto w = StoreWriter::Create(path, Options());
    if (!w.ok()) return w.status();
    BuiltStore built;
    at = Phase::kPages;
    MKTREE_RETURN_IF_ERROR(
        testing::BuildTestStore(objects, Options().codec, Options().params, &(*w)->pages(), &built));
    for (const SceneObject& o : objects)
      MKTREE_RETURN_IF_ERROR((*w)->AppendObject(o.id, built.object_leaf[o.id], o.name));
    at = Phase::kCommit;
    MKTREE_RETURN_IF_ERROR((*w)->Commit(built.tree, "{}"));
    at = Phase::kNone;
    return Status::Ok();
  }
  // Opens `path` and checks every object's name and geometry against `objects`.
  void ExpectStoreHolds(const std::string& path, const std::vector<SceneObject>& objects) {
    auto r = StoreReader::Open(path);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ASSERT_EQ((*r)->object_count(), objects.size());
    for (const SceneObject& o : objects) ASSERT_EQ(*(*r)->ObjectName(o.id), o.name);
    PageCache cache(&(*r)->pages(), 0);
    const LeafSource leaves(**r, cache, true);
    size_t seen = 0;
    for (uint32_t l = 0; l < (*r)->tree().leaves.size(); ++l) {
      auto v = leaves.Read(l, nullptr);
      ASSERT_TRUE(v.ok()) << v.status().ToString();
      for (const auto& e : v->view.entries()) {
        Mesh m;
        ASSERT_TRUE(DecodeObjectMesh(e, &m).ok());
        ASSERT_TRUE(testing::SameMesh(m, objects.at(e.id).mesh)) << "object " << e.id;
        ++seen;
      }
    }
    EXPECT_EQ(seen, objects.size());
  }

  TempDir dir_;
};

// Every limit below the new store's size fails the build; the sweep crosses every phase of the write.
TEST_P(FullDiskTest, EveryPhaseFailsCleanlyAndThePreviousStoreSurvives) {
  const std::string path = dir_.file("s.mkt"), probe = dir_.file("probe.mkt");
  const std::vector<SceneObject> old_objects = testing::MakeObjects(150, 21);
  const std::vector<SceneObject> new_objects = testing::MakeObjects(300, 22);
  ASSERT_TRUE(Write(path, old_objects).ok());
  const std::vector<uint8_t> old_bytes = ReadBytes(path);
  ASSERT_TRUE(Write(probe, new_objects).ok());  // the size the new store needs
  const uint64_t full = std::filesystem::file_size(probe);
  const std::set<std::string> listing = Listing(dir_.path());
  const std::vector<int64_t> ids = Hdf5IdsAndOpenObjects();

  std::set<uint64_t> limits = {0, 1, 100, 4096, BuildParams().mem_page() + 1};
  for (uint64_t l = 0; l < full; l += full / 48) limits.insert(l);
  for (uint64_t back = 1; back <= 24576 && back < full; back += back < 512 ? 61 : 509)
    limits.insert(full - back);
  int failed_at[4] = {};
  for (uint64_t limit : limits) {
    SCOPED_TRACE("file size limit " + std::to_string(limit) + " of " + std::to_string(full));
    Phase phase = Phase::kNone;
    Status st;
    {
      FileSizeLimit lim(limit);
      st = Write(path, new_objects, &phase);
    }
    ASSERT_FALSE(st.ok());
    ++failed_at[static_cast<int>(phase)];
    EXPECT_EQ(st.code(), Status::Code::kIOError) << st.ToString();
    EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
    EXPECT_EQ(st.message().rfind(path, 0), 0u) << st.message();  // starts with the store's (temp) path
    EXPECT_NE(st.message().find(std::strerror(EFBIG)), std::string::npos) << st.message();
    EXPECT_EQ(Listing(dir_.path()), listing) << "temporary or lock file left behind";
    ASSERT_EQ(ReadBytes(path), old_bytes) << "the previous store changed";
    ASSERT_EQ(Hdf5IdsAndOpenObjects(), ids) << "HDF5 identifiers left open";
  }
  std::printf("[full disk, %s] %zu limits: failed at create %d, pages %d, commit %d\n",
              BackendName(GetParam()), limits.size(), failed_at[1], failed_at[2], failed_at[3]);
  EXPECT_GT(failed_at[static_cast<int>(Phase::kPages)], 0);
  EXPECT_GT(failed_at[static_cast<int>(Phase::kCommit)], 10);
  ExpectStoreHolds(path, old_objects);

  // The process goes on: the same build, without the limit, succeeds and replaces the store.
  ASSERT_TRUE(Write(path, new_objects).ok());
  ExpectStoreHolds(path, new_objects);
  EXPECT_EQ(Hdf5IdsAndOpenObjects(), ids);
}

// A writer destroyed before Commit, and one that fails at Commit, release every HDF5 identifier.
TEST_P(FullDiskTest, AbortAndFailedCommitReleaseEveryHdf5Id) {
  const std::string path = dir_.file("a.mkt");
  const std::vector<SceneObject> objects = testing::MakeObjects(120, 23);
  ASSERT_TRUE(Write(dir_.file("warm.mkt"), objects).ok());  // HDF5's lazily created ids exist from here
  const std::vector<int64_t> ids = Hdf5IdsAndOpenObjects();
  {
    auto w = StoreWriter::Create(path, Options());
    ASSERT_TRUE(w.ok());
    BuiltStore built;
    ASSERT_TRUE(
        testing::BuildTestStore(objects, Options().codec, Options().params, &(*w)->pages(), &built).ok());
    if (GetParam() == Backend::kHdf5) {
      EXPECT_NE(Hdf5IdsAndOpenObjects(), ids);  // (an HDF5 writer holds its file open)
    }
  }
  EXPECT_EQ(Hdf5IdsAndOpenObjects(), ids);
  {
    auto w = StoreWriter::Create(path, Options());
    ASSERT_TRUE(w.ok());
    BuiltStore built;
    ASSERT_TRUE(
        testing::BuildTestStore(objects, Options().codec, Options().params, &(*w)->pages(), &built).ok());
    MKTree tree = built.tree;
    tree.leaves.back().page_count += 1;  // refused before the backend writes
    EXPECT_FALSE((*w)->Commit(tree, "").ok());
  }
  EXPECT_EQ(Hdf5IdsAndOpenObjects(), ids);
  EXPECT_FALSE(std::filesystem::exists(path));
  ASSERT_TRUE(Write(path, objects).ok());
  ExpectStoreHolds(path, objects);
}

// In a child process, so that exit runs HDF5's atexit cleanup: after a failed build the process exits
// normally with the error, at limits that fail the pages, the metadata and the close.
TEST_P(FullDiskTest, TheProcessExitsNormallyAfterAFailedBuild) {
  const std::string path = dir_.file("x.mkt");
  const std::vector<SceneObject> objects = testing::MakeObjects(200, 24);
  ASSERT_TRUE(Write(dir_.file("probe.mkt"), objects).ok());
  const uint64_t full = std::filesystem::file_size(dir_.file("probe.mkt"));
  for (uint64_t limit : {full / 3, full - 6000, full - 1500, full - 300, full - 1}) {
    SCOPED_TRACE("limit " + std::to_string(limit));
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    std::fflush(nullptr);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::close(fds[0]);
      Status st;
      {
        FileSizeLimit lim(limit);
        st = Write(path, objects);
      }
      const std::string msg = st.message();
      if (::write(fds[1], msg.data(), msg.size()) < 0) std::_Exit(3);
      ::close(fds[1]);
      std::exit(st.ok() ? 0 : 1);  // atexit handlers run, HDF5's among them
    }
    ::close(fds[1]);
    std::string msg;
    char buf[512];
    for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;) msg.append(buf, static_cast<size_t>(n));
    ::close(fds[0]);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    EXPECT_TRUE(WIFEXITED(status)) << "child killed by signal "
                                   << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    if (WIFEXITED(status)) {
      EXPECT_EQ(WEXITSTATUS(status), 1) << msg;
    }
    EXPECT_NE(msg.find(std::strerror(EFBIG)), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_EQ(Listing(dir_.path()), std::set<std::string>{"probe.mkt"});
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, FullDiskTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

// ---- The command line ----

// `mktree ARGS` with writes past `limit` bytes failing (EFBIG), output captured.
mktree::testing::ToolRun RunLimited(const std::string& args, uint64_t limit,
                                    const std::filesystem::path& scratch) {
  const std::string out = (scratch / "stdout.txt").string(), err = (scratch / "stderr.txt").string();
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::signal(SIGXFSZ, SIG_IGN);  // (an ignored signal stays ignored across exec)
    const rlimit r{static_cast<rlim_t>(limit), RLIM_INFINITY};
    ::setrlimit(RLIMIT_FSIZE, &r);
    const std::string cmd = std::string(MKTREE_TOOL) + " " + args + " >" + out + " 2>" + err;
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    std::_Exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  mktree::testing::ToolRun r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = mktree::testing::Slurp(out);
  r.err = mktree::testing::Slurp(err);
  std::filesystem::remove(out);
  std::filesystem::remove(err);
  return r;
}

// stdout/stderr files of the runner live in `scratch`, outside the store's directory; the limit does not
// reach them (they stay far below it).
class CliFullDiskTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override { std::filesystem::create_directories(dir_.path() / "store"); }
  std::string StoreDir() const { return (dir_.path() / "store").string(); }
  mktree::testing::ToolRun Run(const std::string& args) {
    return mktree::testing::RunMktree(args, dir_.path());
  }
  TempDir dir_;
};

TEST_P(CliFullDiskTest, BuildFailsWithOneLineAndKeepsThePreviousStore) {
  const std::string backend = std::string(" --backend ") + BackendName(GetParam());
  const std::string path = StoreDir() + "/s.mkt", probe = StoreDir() + "/probe.mkt";
  ASSERT_EQ(Run("build tanker:1500:1 -q -o " + path + backend).code, 0);
  const auto info = Run("info " + path), query = Run("query " + path + " --box 0,-30,0,150,30,40");
  ASSERT_EQ(info.code, 0);
  ASSERT_EQ(query.code, 0);
  ASSERT_EQ(Run("build tanker:3000:2 -q -o " + probe + backend).code, 0);
  const uint64_t full = std::filesystem::file_size(probe);
  for (uint64_t limit : {uint64_t{5000}, full / 2, full - 4096, full - 700, full - 1}) {
    SCOPED_TRACE("limit " + std::to_string(limit) + " of " + std::to_string(full));
    auto r = RunLimited("build tanker:3000:2 -q -o " + path + backend, limit, dir_.path());
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find("s.mkt"), std::string::npos) << r.err;
    EXPECT_EQ(Listing(StoreDir()), (std::set<std::string>{"s.mkt", "probe.mkt"}));
    EXPECT_EQ(Run("info " + path).out, info.out);
    EXPECT_EQ(Run("query " + path + " --box 0,-30,0,150,30,40").out, query.out);
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, CliFullDiskTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

// A real full disk: a 20 MiB tmpfs (skipped where mounting is not permitted, as in most containers).
TEST(TmpfsFullDiskTest, BuildOnAFullTmpfsFailsCleanly) {
  TempDir dir;
  const std::string mnt = (dir.path() / "tmpfs").string();
  std::filesystem::create_directories(mnt);
  if (::mount("tmpfs", mnt.c_str(), "tmpfs", 0, "size=20m") != 0) {
    GTEST_SKIP() << "cannot mount a tmpfs here: " << std::strerror(errno);
  }
  struct Unmount {
    std::string dir;
    ~Unmount() { ::umount2(dir.c_str(), MNT_DETACH); }
  } unmount{mnt};
  const std::string path = mnt + "/s.mkt";
  for (const char* backend : {"hdf5", "pagefile"}) {
    SCOPED_TRACE(backend);
    auto run = [&](const std::string& args) { return mktree::testing::RunMktree(args, dir.path()); };
    ASSERT_EQ(run("build tanker:2000:1 -q -o " + path + " --backend " + backend).code, 0);
    const auto info = run("info " + path);
    ASSERT_EQ(info.code, 0);
    auto r = run("build tanker:50000:2 -q -o " + path + " --backend " + backend);
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(std::strerror(ENOSPC)), std::string::npos) << r.err;
    EXPECT_EQ(Listing(mnt), std::set<std::string>{"s.mkt"});
    EXPECT_EQ(run("info " + path).out, info.out);
    std::filesystem::remove(path);
  }
}

}  // namespace
}  // namespace mktree
