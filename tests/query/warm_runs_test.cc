// The warm window over leaves of several pages (PageCache::VisitCachedRuns through Run): on random scenes
// whose big objects make leaves span several pages, in both backends, with and without checksums, at
// cache sizes 0, one page, a few pages, a few leaves and the whole store, Run gives brute force's answers
// and, query after query, the statistics of reading one leaf at a time (VisitUntil): the same pages read,
// hit and evicted in the same order.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "engine/ingest/store_builder.h"
#include "engine/store_format/store_file.h"
#include "mktree/database.h"
#include "query/query_oracle.h"
#include "query/run_matches_visit.h"
#include "query/scene_fixtures.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::TempPath;

// ClusteredScene with every seventh object a pipe of many sides: entries of several KiB, leaves of
// several 2 KiB pages.
std::vector<SceneObject> ScenesWithBigObjects(size_t n, uint64_t seed) {
  std::vector<SceneObject> objs = testing::ClusteredScene(n, seed);
  std::mt19937_64 rng(seed + 1);
  std::uniform_real_distribution<double> unit(0, 1);
  for (size_t i = 0; i < objs.size(); i += 7) {
    const Box3f b = objs[i].Aabb();
    const int axis = static_cast<int>(rng() % 3);
    objs[i].mesh =
        testing::PrismMesh(axis, b.min[(axis + 1) % 3], b.min[(axis + 2) % 3], 0.1 + unit(rng), b.min[axis],
                           b.min[axis] + 1 + 8 * unit(rng), 100 + static_cast<int>(rng() % 300));
  }
  return objs;
}

std::vector<Query> Queries(const std::vector<SceneObject>& objs, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  Box3f scene;
  for (const SceneObject& o : objs) scene.Extend(o.Aabb());
  std::vector<Query> qs;
  for (size_t i = 0; i < n; ++i) {
    const Box3f b = objs[rng() % objs.size()].Aabb();
    Vec3d p;
    for (int a = 0; a < 3; ++a) p[a] = (i % 4 == 0) ? b.max[a] : b.min[a] + unit(rng) * (b.max[a] - b.min[a]);
    if (i % 3 == 0) {
      qs.push_back(Query::Point(p));
      continue;
    }
    const double side = std::pow(10.0, -1.5 + 3 * unit(rng));
    Box3d box;
    for (int a = 0; a < 3; ++a) {
      box.min[a] = i % 5 == 1 ? static_cast<double>(b.min[a]) : p[a] - side * unit(rng);
      box.max[a] = i % 5 == 1 ? static_cast<double>(b.max[a]) : p[a] + side * unit(rng);
    }
    if (i % 23 == 0)
      for (int a = 0; a < 3; ++a) {
        box.min[a] = scene.min[a];
        box.max[a] = scene.max[a];
      }
    qs.push_back(Query::Box(box));
  }
  return qs;
}

class WarmRunsTest : public ::testing::TestWithParam<Backend> {};

TEST_P(WarmRunsTest, MultiPageLeavesKeepAnswersAndCountsOfOneLeafAtATime) {
  const Backend backend = GetParam();
  for (uint64_t seed : {3u, 11u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const std::vector<SceneObject> objs = ScenesWithBigObjects(900, seed);
    const std::string path =
        TempPath(std::string(backend == Backend::kHdf5 ? "h5_" : "pf_") + std::to_string(seed) + ".mkt");
    IngestOptions o;
    o.store.backend = backend;
    o.store.params.block_size = 1024;
    o.store.params.blocks_per_page = 2;
    ASSERT_TRUE(testing::BuildFromObjects(objs, path, o).ok());
    uint64_t multi = 0, pages = 0;
    {
      auto reader = StoreReader::Open(path);
      ASSERT_TRUE(reader.ok());
      for (const LeafInfo& l : (*reader)->tree().leaves) {
        multi += l.page_count > 1;
        pages += l.page_count;
      }
    }
    ASSERT_GE(multi, 10u);  // leaves of several pages, the case under test
    const testing::BruteForce brute(objs);
    const std::vector<Query> qs = Queries(objs, 240, seed * 5);
    std::vector<std::vector<ObjectId>> expected;
    for (const Query& q : qs) expected.push_back(brute.Answer(q));
    for (bool verify : {true, false}) {
      for (uint64_t cache : {uint64_t{0}, uint64_t{1}, uint64_t{5}, uint64_t{24}, pages / 3, pages + 10}) {
        SCOPED_TRACE("cache " + std::to_string(cache) + (verify ? " verified" : ""));
        const OpenOptions oo{.cache_pages = cache, .verify_checksums = verify};
        auto windowed = Database::Open(path, oo);
        auto single = Database::Open(path, oo);
        ASSERT_TRUE(windowed.ok() && single.ok());
        for (int pass = 0; pass < 3; ++pass) {
          for (size_t i = 0; i < qs.size(); ++i) {
            testing::ExpectRunMatchesVisitUntil(
                **windowed, **single, qs[i], expected[i],
                "pass " + std::to_string(pass) + " query " + std::to_string(i));
            if (::testing::Test::HasFatalFailure()) return;
          }
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, WarmRunsTest, ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const auto& info) {
                           return info.param == Backend::kHdf5 ? "Hdf5" : "PagedFile";
                         });

}  // namespace
}  // namespace mktree
