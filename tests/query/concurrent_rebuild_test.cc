// Readers on other threads open and query a store while this process rebuilds it again and again: every
// open succeeds and every answer is that of one whole version (the old or the new), never a mix. CI runs
// it under ThreadSanitizer (ctest label concurrency, scripts/sanitize.sh thread).
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <mutex>
#include <random>
#include <thread>

#include "engine/ingest/store_builder.h"
#include "engine/scene/vector_scene_source.h"
#include "mktree/database.h"
#include "query/scene_fixtures.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

struct Version {
  std::vector<SceneObject> objects;
  std::vector<std::vector<ObjectId>> answers;  // per query, AABB mode, brute force
};

Status BuildSmallBlocks(const std::vector<SceneObject>& objs, const std::string& path, Backend backend) {
  IngestOptions o;
  o.store.backend = backend;
  o.store.params.block_size = 1024;  // small pages: many leaves, so queries read several pages
  o.threads = 2;
  std::vector<SceneOpener> in{[&objs](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(new VectorSceneSource(&objs, first));
  }};
  auto r = BuildStore(in, path, o);
  return r.ok() ? Status::Ok() : r.status();
}

class ConcurrentRebuildTest : public ::testing::TestWithParam<Backend> {};

TEST_P(ConcurrentRebuildTest, ReadersSeeOneWholeVersionWhileTheStoreIsRebuilt) {
  constexpr int kReaders = 3, kRebuilds = 4, kQueries = 40;
  // Two versions told apart by their object counts.
  Version versions[2] = {{testing::ClusteredScene(300, 1), {}}, {testing::ClusteredScene(500, 2), {}}};
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<Box3d> queries;
  for (int i = 0; i < kQueries; ++i) {
    Box3d b;
    for (int a = 0; a < 3; ++a) {
      b.min[a] = unit(rng) * (a == 0 ? 100 : a == 1 ? 40 : 20);
      b.max[a] = b.min[a] + unit(rng) * 6;
    }
    queries.push_back(b);
  }
  for (Version& v : versions)
    for (const Box3d& q : queries) {
      std::vector<ObjectId> hits;
      for (const SceneObject& o : v.objects)
        if (o.Aabb().Intersects(q)) hits.push_back(o.id);
      v.answers.push_back(hits);
    }

  const testing::TempDir dir("mktree_rebuild");
  const std::string path = dir.file(std::string(BackendName(GetParam())) + ".mkt");
  ASSERT_TRUE(BuildSmallBlocks(versions[0].objects, path, GetParam()).ok());

  std::atomic<bool> done{false};
  std::atomic<int> opens{0};
  std::mutex mu;
  std::vector<std::string> failures;
  auto fail = [&](const std::string& what) {
    std::lock_guard<std::mutex> lock(mu);
    failures.push_back(what);
  };
  std::vector<std::thread> readers;
  for (int t = 0; t < kReaders; ++t)
    readers.emplace_back([&, t] {
      // At least two rounds each, so that every reader overlaps some rebuild however threads are scheduled.
      for (int round = 0; !done.load() || round < 2; ++round) {
        auto db = Database::Open(path, {.cache_pages = 8});
        if (!db.ok()) return fail("open: " + db.status().ToString());
        ++opens;
        const uint64_t n = (*db)->object_count();
        if (n != versions[0].objects.size() && n != versions[1].objects.size())
          return fail("a store of " + std::to_string(n) + " objects");
        const Version& v = versions[n == versions[0].objects.size() ? 0 : 1];
        QueryResult r;
        for (int i = 0; i < kQueries; ++i) {
          const int q = (i + t * 7) % kQueries;
          Status st = (*db)->Run(Query::Box(queries[q]), &r);
          if (!st.ok()) return fail("query: " + st.ToString());
          if (r.hits != v.answers[q]) return fail("query " + std::to_string(q) + ": wrong answer");
        }
      }
    });
  for (int i = 1; i <= kRebuilds; ++i) {
    Status st = BuildSmallBlocks(versions[i % 2].objects, path, GetParam());
    EXPECT_TRUE(st.ok()) << "rebuild " << i << ": " << st.ToString();
  }
  done = true;
  for (std::thread& r : readers) r.join();
  for (const std::string& f : failures) ADD_FAILURE() << f;
  EXPECT_GE(opens.load(), 2 * kReaders);
  auto last = Database::Open(path);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  EXPECT_EQ((*last)->object_count(), versions[kRebuilds % 2].objects.size());
}

INSTANTIATE_TEST_SUITE_P(Backends, ConcurrentRebuildTest,
                         ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
