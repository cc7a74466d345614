// Every query kind, in AABB and exact mode, against brute force: random clustered scenes and the real
// scenes of ../shared/data, both backends, codec on and off, cache sizes 0, 1, small and large.
#include "mktree/database.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <stdexcept>

#include "engine/geometry/exact_geometry.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/vector_scene_source.h"
#include "query/query_oracle.h"
#include "query/scene_fixtures.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::TempPath;

IngestOptions Options(Backend backend, Codec codec, uint32_t block, uint32_t d) {
  IngestOptions o;
  o.store.backend = backend;
  o.store.codec.codec = codec;
  o.store.params.block_size = block;
  o.store.params.blocks_per_page = d;
  return o;
}

using testing::BruteForce;

Status Build(const std::vector<SceneObject>& objs, const std::string& path, const IngestOptions& o) {
  return testing::BuildFromObjects(objs, path, o);
}

// Random queries around the scene: points on object corners and inside objects, boxes of mixed sizes.
std::vector<Query> RandomQueries(const std::vector<SceneObject>& objs, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  Box3f all;
  for (const SceneObject& o : objs) all.Extend(o.Aabb());
  std::vector<Query> qs;
  for (size_t i = 0; i < n; ++i) {
    Vec3d p;
    const int how = static_cast<int>(i % 4);
    if (how == 0 || objs.empty()) {
      for (int a = 0; a < 3; ++a) p[a] = all.min[a] + unit(rng) * (all.max[a] - all.min[a]);
    } else {
      const Box3f b = objs[rng() % objs.size()].Aabb();
      for (int a = 0; a < 3; ++a)
        p[a] = how == 1 ? (rng() % 2 ? b.min[a] : b.max[a]) : b.min[a] + unit(rng) * (b.max[a] - b.min[a]);
    }
    if (i % 2 == 0) {
      qs.push_back(Query::Point(p));
    } else {
      const double side = std::pow(10.0, -2 + 3 * unit(rng)) * (all.max[0] - all.min[0]) / 100;
      Box3d b;
      for (int a = 0; a < 3; ++a) {
        b.min[a] = p[a] - side * unit(rng);
        b.max[a] = p[a] + side * unit(rng);
      }
      qs.push_back(Query::Box(b));
    }
  }
  return qs;
}

void CheckStats(const QueryResult& r, bool cold) {
  EXPECT_EQ(r.stats.hits, r.hits.size());
  EXPECT_LE(r.stats.pages_read, r.stats.pages_touched);
  EXPECT_EQ(r.stats.cache_hits + r.stats.pages_read, r.stats.pages_touched);
  if (cold) {
    EXPECT_EQ(r.stats.pages_read, r.stats.pages_touched);
  }
  EXPECT_GE(r.stats.pages_touched, r.stats.leaves_visited);
  EXPECT_TRUE(std::is_sorted(r.hits.begin(), r.hits.end()));
}

void CheckAll(const Database& db, const std::vector<SceneObject>& objs, const std::vector<Query>& qs,
              QueryMode mode, bool cold) {
  QueryResult r;
  const BruteForce brute(objs);
  for (size_t i = 0; i < qs.size(); ++i) {
    if (cold) const_cast<Database&>(db).ClearCache();
    Query q = qs[i];
    q.mode = mode;
    ASSERT_TRUE(db.Run(q, &r).ok()) << "query " << i;
    const auto expected = brute.Answer(q);
    ASSERT_EQ(r.hits, expected) << "query " << i << (qs[i].kind == Query::Kind::kPoint ? " point" : " box");
    CheckStats(r, cold);
  }
}

struct Config {
  Backend backend;
  Codec codec;
};

class DatabaseTest : public ::testing::TestWithParam<Config> {};

TEST_P(DatabaseTest, ClusteredSceneMatchesBruteForceAtEveryCacheSize) {
  const auto objs = testing::ClusteredScene(3000, 42);
  const std::string path = TempPath("clustered.mkt");
  ASSERT_TRUE(Build(objs, path, Options(GetParam().backend, GetParam().codec, 1024, 2)).ok());
  const auto qs = RandomQueries(objs, 400, 7);
  for (uint64_t cache : {0u, 1u, 16u, 100000u}) {
    SCOPED_TRACE("cache " + std::to_string(cache));
    auto db = Database::Open(path, {.cache_pages = cache});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    EXPECT_EQ((*db)->object_count(), objs.size());
    CheckAll(**db, objs, qs, QueryMode::kAabb, /*cold=*/false);
    CheckAll(**db, objs, qs, QueryMode::kAabb, /*cold=*/true);
  }
  auto db = Database::Open(path, {.cache_pages = 64});
  ASSERT_TRUE(db.ok());
  CheckAll(**db, objs, qs, QueryMode::kExact, false);
  fs::remove(path);
}

TEST_P(DatabaseTest, BatchFromManyThreadsEqualsSingleQueries) {
  const auto objs = testing::ClusteredScene(2000, 3);
  const std::string path = TempPath("batch.mkt");
  ASSERT_TRUE(Build(objs, path, Options(GetParam().backend, GetParam().codec, 4096, 1)).ok());
  auto db = Database::Open(path, {.cache_pages = 8});
  ASSERT_TRUE(db.ok());
  const auto qs = RandomQueries(objs, 600, 11);
  std::vector<QueryResult> results;
  ASSERT_TRUE((*db)->RunBatch(qs, 4, &results).ok());
  ASSERT_EQ(results.size(), qs.size());
  const BruteForce brute(objs);
  for (size_t i = 0; i < qs.size(); ++i) EXPECT_EQ(results[i].hits, brute.Answer(qs[i])) << i;
  fs::remove(path);
}

// Visit is the primitive under Run: the same ids, each once, and the same statistics.
TEST_P(DatabaseTest, VisitStreamsRunsAnswerEachIdOnce) {
  const auto objs = testing::ClusteredScene(2000, 21);
  const std::string path = TempPath("visit.mkt");
  ASSERT_TRUE(Build(objs, path, Options(GetParam().backend, GetParam().codec, 1024, 2)).ok());
  auto db = Database::Open(path, {.cache_pages = 32});
  ASSERT_TRUE(db.ok());
  for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
    for (Query q : RandomQueries(objs, 200, 23)) {
      q.mode = mode;
      QueryResult run;
      (*db)->ClearCache();
      ASSERT_TRUE((*db)->Run(q, &run).ok());
      std::vector<ObjectId> visited;
      auto collect = [&](ObjectId id) { visited.push_back(id); };
      QueryStats stats;
      (*db)->ClearCache();
      ASSERT_TRUE((*db)->Visit(q, collect, &stats).ok());
      std::sort(visited.begin(), visited.end());
      EXPECT_EQ(std::adjacent_find(visited.begin(), visited.end()), visited.end());
      ASSERT_EQ(visited, run.hits);
      EXPECT_EQ(stats.ToJsonMembers(), run.stats.ToJsonMembers());
    }
  }
  fs::remove(path);
}

// `visit` runs once its leaf is released: it may query the same Database, and its exceptions become a
// Status.
TEST_P(DatabaseTest, AVisitorMayQueryTheDatabaseAndItsExceptionsAreAStatus) {
  const auto objs = testing::ClusteredScene(1500, 31);
  const std::string path = TempPath("nested.mkt");
  ASSERT_TRUE(Build(objs, path, Options(GetParam().backend, GetParam().codec, 1024, 2)).ok());
  auto db = Database::Open(path, {.cache_pages = 4});
  ASSERT_TRUE(db.ok());
  const BruteForce brute(objs);
  const Query whole = Query::Box((*db)->bounds());
  std::vector<ObjectId> visited;
  QueryResult inner;
  size_t nested = 0;
  auto visit = [&](ObjectId id) {
    visited.push_back(id);
    if (id % 100 != 0) return;
    // Queries around the object's first vertex, from inside the outer query: a point, and a box like it.
    const std::vector<double>& v = objs[id].mesh.vertices;
    Box3d near;
    for (int a = 0; a < 3; ++a) {
      near.min[a] = v[a] - 1;
      near.max[a] = v[a] + 1;
    }
    for (const Query& q : {Query::Point({v[0], v[1], v[2]}, QueryMode::kExact), Query::Box(near)}) {
      ASSERT_TRUE((*db)->Run(q, &inner).ok());
      ASSERT_EQ(inner.hits, brute.Answer(q));
    }
    ++nested;
  };
  const Status st = (*db)->Visit(whole, visit, nullptr);
  ASSERT_TRUE(st.ok()) << st.ToString();
  EXPECT_GT(nested, 10u);
  std::sort(visited.begin(), visited.end());
  EXPECT_EQ(visited, brute.Answer(whole));

  auto give_up = [](ObjectId) { throw std::runtime_error("visitor gave up"); };
  const Status thrown = (*db)->Visit(whole, give_up, nullptr);
  EXPECT_EQ(thrown.code(), Status::Code::kInternal);
  EXPECT_NE(thrown.message().find("visitor gave up"), std::string::npos) << thrown.message();
  EXPECT_NE(thrown.message().find(path), std::string::npos) << thrown.message();
  fs::remove(path);
}

TEST_P(DatabaseTest, OversizedObjectsSpanSeveralPages) {
  // Prisms with many sides are larger than a 1 KiB page: each is a leaf of several pages.
  std::vector<SceneObject> objs = testing::ClusteredScene(300, 5);
  for (int i = 0; i < 10; ++i) {
    SceneObject o;
    o.name = "big_" + std::to_string(i);
    o.mesh = testing::PrismMesh(i % 3, 5.0 * i, 3, 1.5, 0, 20, 400);
    objs.push_back(std::move(o));
  }
  for (size_t i = 0; i < objs.size(); ++i) objs[i].id = static_cast<ObjectId>(i);
  const std::string path = TempPath("big.mkt");
  ASSERT_TRUE(Build(objs, path, Options(GetParam().backend, Codec::kNone, 1024, 1)).ok());
  auto db = Database::Open(path, {.cache_pages = 4});
  ASSERT_TRUE(db.ok());
  CheckAll(**db, objs, RandomQueries(objs, 200, 9), QueryMode::kAabb, true);
  CheckAll(**db, objs, RandomQueries(objs, 100, 10), QueryMode::kExact, false);
  fs::remove(path);
}

TEST_P(DatabaseTest, LargeAnswersAndRepeatedQueriesKeepAnswersAndCounts) {
  const auto objs = testing::ClusteredScene(3000, 17);
  const std::string path = TempPath("large.mkt");
  ASSERT_TRUE(Build(objs, path, Options(GetParam().backend, GetParam().codec, 1024, 2)).ok());
  auto db = Database::Open(path, {.cache_pages = 100000});
  ASSERT_TRUE(db.ok());
  Box3f all;
  for (const SceneObject& o : objs) all.Extend(o.Aabb());
  // The whole scene, and its halves and quarters: answers of thousands of ids, sorted by radix.
  std::vector<Query> qs;
  for (int parts : {1, 2, 4}) {
    for (int k = 0; k < parts; ++k) {
      Box3d b;
      for (int a = 0; a < 3; ++a) {
        b.min[a] = all.min[a];
        b.max[a] = all.max[a];
      }
      const double step = (double{all.max[0]} - all.min[0]) / parts;
      b.min[0] = all.min[0] + k * step;
      b.max[0] = all.min[0] + (k + 1) * step;
      qs.push_back(Query::Box(b));
    }
  }
  const BruteForce brute(objs);
  for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
    QueryResult first, again;
    for (Query q : qs) {
      q.mode = mode;
      (*db)->ClearCache();
      ASSERT_TRUE((*db)->Run(q, &first).ok());
      ASSERT_EQ(first.hits, brute.Box(q.box, mode));
      CheckStats(first, /*cold=*/true);
      // Repeated with every page cached: the same answer and work, and every page a hit.
      ASSERT_TRUE((*db)->Run(q, &again).ok());
      EXPECT_EQ(again.hits, first.hits);
      EXPECT_EQ(again.stats.pages_touched, first.stats.pages_touched);
      EXPECT_EQ(again.stats.cache_hits, again.stats.pages_touched);
      EXPECT_EQ(again.stats.pages_read, 0u);
      EXPECT_EQ(again.stats.bytes_read, 0u);
      EXPECT_EQ(again.stats.leaves_visited, first.stats.leaves_visited);
      EXPECT_EQ(again.stats.candidates_tested, first.stats.candidates_tested);
    }
  }
  QueryResult r;
  ASSERT_TRUE((*db)->Run(qs[0], &r).ok());
  EXPECT_EQ(r.hits.size(), objs.size());
  fs::remove(path);
}

INSTANTIATE_TEST_SUITE_P(Backends, DatabaseTest,
                         ::testing::Values(Config{Backend::kHdf5, Codec::kZstd},
                                           Config{Backend::kHdf5, Codec::kNone},
                                           Config{Backend::kPagedFile, Codec::kZstd},
                                           Config{Backend::kPagedFile, Codec::kNone}),
                         [](const auto& info) {
                           return std::string(info.param.backend == Backend::kHdf5 ? "Hdf5" : "PagedFile") +
                                  (info.param.codec == Codec::kZstd ? "Zstd" : "Raw");
                         });

TEST(DatabaseErrors, BadQueriesAreRefused) {
  const auto objs = testing::ClusteredScene(50, 1);
  const std::string path = TempPath("errors.mkt");
  ASSERT_TRUE(Build(objs, path, Options(Backend::kPagedFile, Codec::kZstd, 4096, 3)).ok());
  auto db = Database::Open(path);
  ASSERT_TRUE(db.ok());
  QueryResult r;
  EXPECT_EQ((*db)->Run(Query::Point({NAN, 0, 0}), &r).code(), Status::Code::kInvalidArgument);
  Box3d inverted;
  inverted.min = {1, 1, 1};
  inverted.max = {0, 2, 2};
  EXPECT_EQ((*db)->Run(Query::Box(inverted), &r).code(), Status::Code::kInvalidArgument);
  auto ignore = [](ObjectId) {};
  EXPECT_EQ((*db)->Visit(Query::Box(inverted), ignore, nullptr).code(), Status::Code::kInvalidArgument);
  fs::remove(path);
}

TEST(DatabaseErrors, MissingAndForeignFilesAreRefused) {
  EXPECT_FALSE(Database::Open(TempPath("does_not_exist.mkt")).ok());
  const std::string junk = TempPath("junk.mkt");
  {
    FILE* f = std::fopen(junk.c_str(), "wb");
    std::fputs("this is not a store at all, just some text that is long enough to look like a header\n", f);
    std::fclose(f);
  }
  auto db = Database::Open(junk);
  ASSERT_FALSE(db.ok());
  EXPECT_NE(db.status().message().find(junk), std::string::npos) << db.status().ToString();
  fs::remove(junk);
}

}  // namespace
}  // namespace mktree
