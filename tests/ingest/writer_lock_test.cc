// BuildStore takes the store's writer lock before it does anything else (docs/cli.md: "a concurrent build
// of the same path fails"): a second build of the same store fails at once while the first is still
// reading its scene, the first then succeeds, builds of other stores in the same folder are not held up,
// and what killed builds left (temporary stores, named spills) is removed before the new build writes.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/store_builder.h"
#include "mktree/database.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

SceneOpener Tanker(uint64_t n) {
  return
      [n](ObjectId first) -> Result<std::unique_ptr<SceneSource>> { return MakeTankerSource(n, 3, first); };
}

class WriterLockTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override { opts_.store.backend = GetParam(); }

  std::string P(const std::string& name) const { return (dir_ / name).string(); }

  testing::TempDir dir_{"mktree_writer_lock"};
  IngestOptions opts_;
};

TEST_P(WriterLockTest, ASecondBuildOfTheSameStoreFailsAtOnceAndTheFirstSucceeds) {
  const std::string store = P("scene.mkt");
  int started[2], release[2];
  ASSERT_EQ(::pipe(started), 0);
  ASSERT_EQ(::pipe(release), 0);
  // The first build (a child process) stops in its read stage, before its tree and pages, until released.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    IngestOptions paused = opts_;
    bool waited = false;
    paused.progress = [&](IngestStage s, uint64_t, uint64_t) {
      if (s != IngestStage::kRead || waited) return;
      waited = true;
      char c = 's';
      if (::write(started[1], &c, 1) != 1 || ::read(release[0], &c, 1) != 1) ::_exit(3);
    };
    auto r = BuildStore({Tanker(500)}, store, paused);
    ::_exit(r.ok() ? 0 : 4);
  }
  char c = 0;
  ASSERT_EQ(::read(started[0], &c, 1), 1) << "the first build did not start";

  auto second = BuildStore({Tanker(200)}, store, opts_);
  EXPECT_FALSE(second.ok()) << "two builds of one store both ran";
  if (!second.ok()) {
    EXPECT_NE(second.status().message().find("another writer"), std::string::npos)
        << second.status().ToString();
  }
  // Another store in the same folder is built meanwhile without trouble.
  auto other = BuildStore({Tanker(200)}, P("other.mkt"), opts_);
  EXPECT_TRUE(other.ok()) << other.status().ToString();

  c = 'r';
  ASSERT_EQ(::write(release[1], &c, 1), 1);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "the first build failed";
  for (int fd : {started[0], started[1], release[0], release[1]}) ::close(fd);

  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_EQ((*db)->object_count(), 500u);  // the first build's store, not the second's
  auto db2 = Database::Open(P("other.mkt"));
  ASSERT_TRUE(db2.ok()) << db2.status().ToString();
  EXPECT_EQ((*db2)->object_count(), 200u);
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(dir_)) left.push_back(e.path().filename().string());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"other.mkt", "scene.mkt"}));
}

TEST_P(WriterLockTest, LeftoversOfKilledBuildsAreRemovedOnlyForTheirStore) {
  const std::string store = P("scene.mkt");
  // What builds of scene.mkt killed at the wrong moment leave: a temporary store and spills still named
  // (spill_file.h); and the same for another store of the folder, which must stay.
  const char* stale[] = {"scene.mkt.tmp.99999999", ".scene.mkt.geometry-spill.AbC123",
                         ".scene.mkt.name-spill.x0Y9zZ"};
  const char* kept[] = {"other.mkt.tmp.99999999", ".other.mkt.geometry-spill.AbC123", "scene.mkt.notes",
                        ".scene.mkt.geometry-spill.toolong1"};
  for (const char* name : stale) std::ofstream(P(name)) << "left by a killed build";
  for (const char* name : kept) std::ofstream(P(name)) << "not this build's";
  // The observer sees the folder when the build first reports progress: the cleanup came first.
  bool clean_at_start = false;
  opts_.progress = [&](IngestStage, uint64_t, uint64_t) {
    if (clean_at_start) return;
    clean_at_start = true;
    for (const char* name : stale) clean_at_start &= !fs::exists(P(name));
  };
  auto r = BuildStore({Tanker(100)}, store, opts_);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(clean_at_start);
  for (const char* name : stale) EXPECT_FALSE(fs::exists(P(name))) << name;
  for (const char* name : kept) EXPECT_TRUE(fs::exists(P(name))) << name;
}

INSTANTIATE_TEST_SUITE_P(Backends, WriterLockTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
