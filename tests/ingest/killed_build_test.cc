// A build killed before its commit leaves nothing that opens as a store, and the next build of the same
// store removes what the killed one left.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>

#include "engine/ingest/store_builder.h"
#include "engine/scene/vector_scene_source.h"
#include "mktree/database.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

std::vector<SceneObject> Cubes(int n) {
  std::vector<SceneObject> objs;
  for (int i = 0; i < n; ++i) {
    SceneObject o;
    o.id = static_cast<ObjectId>(i);
    o.name = "cube_" + std::to_string(i);
    const float x = static_cast<float>(i % 30), y = static_cast<float>(i / 30);
    for (int v = 0; v < 8; ++v)
      o.mesh.vertices.insert(o.mesh.vertices.end(), {x + (v & 1), y + ((v >> 1) & 1), float((v >> 2) & 1)});
    o.mesh.triangles = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                        2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
    objs.push_back(std::move(o));
  }
  return objs;
}

class KilledBuildTest : public ::testing::TestWithParam<Backend> {};

TEST_P(KilledBuildTest, LeavesNoStoreAndTheNextBuildCleansUp) {
  const testing::TempDir dir("mktree_killed");
  const std::string store = dir.file("scene.mkt");
  const auto objs = Cubes(3000);
  IngestOptions opts;
  opts.store.backend = GetParam();
  opts.store.params.block_size = 1024;
  opts.store.params.blocks_per_page = 1;
  auto input = [&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(new VectorSceneSource(&objs, first));
  };

  // The child dies abruptly while writing the object table: after the pages, before the commit.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    IngestOptions dying = opts;
    dying.progress = [](IngestStage s, uint64_t, uint64_t) {
      if (s == IngestStage::kWriteTable) ::_exit(9);
    };
    (void)BuildStore({input}, store, dying);
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 9) << "the build finished before it could be killed";

  EXPECT_FALSE(fs::exists(store));
  std::vector<fs::path> left;
  for (const auto& e : fs::directory_iterator(dir)) left.push_back(e.path());
  ASSERT_FALSE(left.empty()) << "the killed build should have left its temporary store";
  for (const fs::path& p : left) EXPECT_FALSE(Database::Open(p.string()).ok()) << p << " opens as a store";

  auto r = BuildStore({input}, store, opts);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  std::vector<std::string> now;
  for (const auto& e : fs::directory_iterator(dir)) now.push_back(e.path().filename().string());
  EXPECT_EQ(now, std::vector<std::string>{"scene.mkt"});
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_EQ((*db)->object_count(), objs.size());
}

INSTANTIATE_TEST_SUITE_P(Backends, KilledBuildTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
