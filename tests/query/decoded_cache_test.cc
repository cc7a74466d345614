// The decoded-leaf cache (engine/store_format/leaf_reader.h DecodedLeaf, attached to cached pages): warm
// answers against brute force at cache sizes 0, one leaf, small and the whole store, in AABB and exact mode;
// page counts as without it; attachments dropped with their pages; corruption refused on every read, never
// cached; many threads sharing one Database (DecodedCache.Concurrent*, label concurrency); the warm
// window of leaves (Run) against one leaf at a time (VisitUntil): same answers and same counts.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <random>
#include <span>
#include <thread>

#include "engine/geometry/exact_geometry.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/vector_scene_source.h"
#include "mktree/database.h"
#include "query/query_oracle.h"
#include "query/run_matches_visit.h"
#include "query/scene_fixtures.h"
#include "storage/memory_page_store.h"
#include "storage/page_cache.h"
#include "store_format/crafted_store.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::TempPath;

Status BuildPagedFile(const std::vector<SceneObject>& objs, const std::string& path) {
  IngestOptions o;
  o.store.backend = Backend::kPagedFile;
  o.store.params.block_size = 1024;
  o.store.params.blocks_per_page = 2;
  return testing::BuildFromObjects(objs, path, o);
}

using Brute = testing::BruteForce;

// Points (on box corners, so that float rounding of the query matters) and boxes of mixed sizes, some
// with faces exactly on object faces and some with coordinates between two floats.
std::vector<Query> BoundaryQueries(const std::vector<SceneObject>& objs, size_t n, uint64_t seed,
                                   QueryMode mode) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<Query> qs;
  for (size_t i = 0; i < n; ++i) {
    const Box3f b = objs[rng() % objs.size()].Aabb();
    Vec3d p;
    for (int a = 0; a < 3; ++a) p[a] = (i % 3 == 0) ? b.max[a] : b.min[a] + unit(rng) * (b.max[a] - b.min[a]);
    Query q;
    if (i % 2 == 0) {
      q = Query::Point(p);
    } else {
      const double side = std::pow(10.0, -1 + 2.5 * unit(rng));
      Box3d box;
      for (int a = 0; a < 3; ++a) {
        box.min[a] = i % 5 == 1 ? static_cast<double>(b.max[a]) : p[a] - side * unit(rng);
        box.max[a] = p[a] + side * unit(rng);
        if (i % 7 == 3) box.max[a] = std::nextafter(static_cast<double>(b.min[a]), -1e300);  // just short
        if (box.max[a] < box.min[a]) std::swap(box.min[a], box.max[a]);
      }
      q = Query::Box(box);
    }
    q.mode = mode;
    qs.push_back(q);
  }
  return qs;
}

class DecodedCacheTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    objs_ = new std::vector<SceneObject>(testing::ClusteredScene(2500, 17));
    ASSERT_TRUE(BuildPagedFile(*objs_, TempPath("scene.mkt")).ok());
    brute_ = new Brute(*objs_);
  }
  static void TearDownTestSuite() {
    delete brute_;
    delete objs_;
  }
  static std::vector<SceneObject>* objs_;
  static Brute* brute_;
};
std::vector<SceneObject>* DecodedCacheTest::objs_ = nullptr;
Brute* DecodedCacheTest::brute_ = nullptr;

// Three passes over the same queries: the first builds decoded leaves, the later ones answer from them
// (or, in a small cache, from a mix of rebuilt and kept ones). Page counts per query are those of the
// first pass for the pages touched, and a whole-store cache reads nothing after the first pass.
TEST_F(DecodedCacheTest, WarmAnswersMatchBruteForceAtEveryCacheSize) {
  for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
    const auto qs = BoundaryQueries(*objs_, mode == QueryMode::kAabb ? 600 : 200, 5, mode);
    std::vector<std::vector<ObjectId>> expected;
    size_t answered = 0;
    for (const Query& q : qs) {
      expected.push_back(brute_->Answer(q));
      answered += !expected.back().empty();
    }
    ASSERT_GT(answered, qs.size() / 2);  // the queries meet objects
    for (uint64_t cache : {0u, 1u, 12u, 1000000u}) {
      SCOPED_TRACE("cache " + std::to_string(cache) + (mode == QueryMode::kExact ? " exact" : " aabb"));
      auto db = Database::Open(TempPath("scene.mkt"), {.cache_pages = cache});
      ASSERT_TRUE(db.ok()) << db.status().ToString();
      std::vector<uint64_t> touched;
      for (int pass = 0; pass < 3; ++pass) {
        for (size_t i = 0; i < qs.size(); ++i) {
          QueryResult r;
          ASSERT_TRUE((*db)->Run(qs[i], &r).ok());
          ASSERT_EQ(r.hits, expected[i]) << "pass " << pass << " query " << i;
          EXPECT_EQ(r.stats.hits, r.hits.size());
          if (pass == 0) touched.push_back(r.stats.pages_touched);
          EXPECT_EQ(r.stats.pages_touched, touched[i]);
          EXPECT_EQ(r.stats.cache_hits + r.stats.pages_read, r.stats.pages_touched);
          if (cache == 0) {
            EXPECT_EQ(r.stats.pages_read, r.stats.pages_touched);
          }
          if (cache == 1000000u && pass > 0) {
            EXPECT_EQ(r.stats.pages_read, 0u);
          }
        }
      }
    }
  }
}

// A limit stops inside a leaf: the decoded scan stops at the same entry as the parsed one did.
TEST_F(DecodedCacheTest, LimitedQueriesFromDecodedLeavesAreTheAnswersPrefix) {
  auto db = Database::Open(TempPath("scene.mkt"), {.cache_pages = 100000});
  ASSERT_TRUE(db.ok());
  for (const Query& base : BoundaryQueries(*objs_, 200, 9, QueryMode::kAabb)) {
    std::vector<ObjectId> all;
    ASSERT_TRUE((*db)
                    ->Visit(
                        base, [&](ObjectId id) { all.push_back(id); }, nullptr)
                    .ok());
    for (uint64_t limit : {0u, 1u, 3u, 17u}) {
      Query q = base;
      q.limit = limit;
      std::vector<ObjectId> got;
      auto complete = (*db)->VisitUntil(
          q,
          [&](ObjectId id) {
            got.push_back(id);
            return true;
          },
          nullptr);
      ASSERT_TRUE(complete.ok());
      const size_t n = std::min<size_t>(limit, all.size());
      EXPECT_EQ(got, std::vector<ObjectId>(all.begin(), all.begin() + static_cast<ptrdiff_t>(n)));
      EXPECT_EQ(*complete, all.size() <= limit);
    }
  }
}

// A page's attachment goes with its copy: on eviction, on Clear, and on a reload; never while pinned.
class CountedAttachment : public PageAttachment {
 public:
  explicit CountedAttachment(std::atomic<int>* live) : live_(live) { ++*live_; }
  ~CountedAttachment() override { --*live_; }

 private:
  std::atomic<int>* live_;
};

TEST(DecodedCachePages, AttachmentsLeaveWithTheirPagesNeverWhilePinned) {
  MemoryPageStore store(64);
  std::vector<uint8_t> page(64, 7);
  for (uint64_t p = 0; p < 6; ++p) ASSERT_TRUE(store.WritePage(p, page.data()).ok());
  PageCache cache(&store, 2);
  std::atomic<int> live{0};
  auto h0 = cache.Pin(0, nullptr);
  ASSERT_TRUE(h0.ok());
  const uint64_t load0 = h0->load_id();
  EXPECT_EQ(h0->attachment(), nullptr);
  const PageAttachment* a = h0->Attach(std::make_unique<CountedAttachment>(&live));
  EXPECT_EQ(h0->attachment(), a);
  // A second Attach keeps the first.
  EXPECT_EQ(h0->Attach(std::make_unique<CountedAttachment>(&live)), a);
  EXPECT_EQ(live.load(), 1);
  // Misses on other pages while page 0 is pinned: it stays, with its attachment.
  for (uint64_t p = 1; p < 6; ++p) ASSERT_TRUE(cache.Pin(p, nullptr).ok());
  EXPECT_EQ(live.load(), 1);
  EXPECT_EQ(h0->attachment(), a);
  h0->Release();
  {  // a hit: the same copy and attachment
    auto again = cache.Pin(0, nullptr);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(again->load_id(), load0);
    EXPECT_EQ(again->attachment(), a);
  }
  // Evicted by two other pages: the attachment is deleted, and a reload starts without one.
  ASSERT_TRUE(cache.Pin(4, nullptr).ok());
  ASSERT_TRUE(cache.Pin(5, nullptr).ok());
  EXPECT_EQ(live.load(), 0);
  auto reloaded = cache.Pin(0, nullptr);
  ASSERT_TRUE(reloaded.ok());
  EXPECT_NE(reloaded->load_id(), load0);
  EXPECT_EQ(reloaded->attachment(), nullptr);
  reloaded->Attach(std::make_unique<CountedAttachment>(&live));
  reloaded->Release();
  cache.Clear();
  EXPECT_EQ(live.load(), 0);
  {  // the cache's destructor deletes what it still holds
    PageCache other(&store, 4);
    auto h = other.Pin(3, nullptr);
    ASSERT_TRUE(h.ok());
    h->Attach(std::make_unique<CountedAttachment>(&live));
    h->Release();
    EXPECT_EQ(live.load(), 1);
  }
  EXPECT_EQ(live.load(), 0);
}

// A tampered leaf (valid checksum, an id twice) is found when the leaf is first decoded, and, never
// being cached, on every later read too, in both modes, whatever the cache holds.
TEST(DecodedCacheCorruption, FoundOnFirstDecodeAndNeverCached) {
  auto img = testing::MakeTestImage(300, 11);
  ASSERT_TRUE(img.ok());
  testing::StoreImage image = std::move(img).value();
  const uint32_t l = testing::LeafWithObjects(image.tree(), 3);
  std::vector<uint8_t>& page = image.pages[image.tree().leaves[l].first_page];
  const std::vector<size_t> at = testing::EntryOffsets(page);
  storage_internal::Put<uint32_t>(page.data() + at[1], storage_internal::Get<uint32_t>(page.data() + at[0]));
  testing::ResealPage(&page);
  const std::string path = TempPath("tampered.mkt");
  ASSERT_TRUE(testing::WriteStoreImage(image, path, Backend::kPagedFile).ok());
  Box3d all;
  for (int i = 0; i < 3; ++i) {
    all.min[i] = image.tree().nodes[0].box.min[i] - 1.0;
    all.max[i] = image.tree().nodes[0].box.max[i] + 1.0;
  }
  for (uint64_t cache : {0u, 1000u}) {
    auto db = Database::Open(path, {.cache_pages = cache});
    ASSERT_TRUE(db.ok());
    for (int pass = 0; pass < 3; ++pass) {
      for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
        QueryResult r;
        const Status st = (*db)->Run(Query::Box(all, mode), &r);
        EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
        EXPECT_NE(st.message().find(path), std::string::npos) << st.message();
        EXPECT_NE(st.message().find("appears twice"), std::string::npos) << st.message();
      }
    }
  }
}

// Threads share one Database: decoded leaves built, used, evicted and rebuilt concurrently (a small
// cache churns; a large one is shared by all), answers always brute force's, in both modes.
TEST_F(DecodedCacheTest, ConcurrentQueriesShareDecodedLeaves) {
  for (uint64_t cache : {6u, 1000000u}) {
    SCOPED_TRACE("cache " + std::to_string(cache));
    auto db = Database::Open(TempPath("scene.mkt"), {.cache_pages = cache});
    ASSERT_TRUE(db.ok());
    std::vector<Query> qs = BoundaryQueries(*objs_, 160, 31, QueryMode::kAabb);
    for (Query q : BoundaryQueries(*objs_, 40, 37, QueryMode::kExact)) qs.push_back(q);
    std::vector<std::vector<ObjectId>> expected;
    for (const Query& q : qs) expected.push_back(brute_->Answer(q));
    std::atomic<int> wrong{0}, failed{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([&, t] {
        for (int round = 0; round < 3; ++round) {
          for (size_t k = 0; k < qs.size(); ++k) {
            const size_t i = (k * 7 + static_cast<size_t>(t) * 13 + static_cast<size_t>(round)) % qs.size();
            QueryResult r;
            if (!(*db)->Run(qs[i], &r).ok())
              ++failed;
            else if (r.hits != expected[i])
              ++wrong;
          }
        }
      });
    }
    for (auto& th : threads) th.join();
    EXPECT_EQ(failed.load(), 0);
    EXPECT_EQ(wrong.load(), 0);
    // And the batch path, which shares the cache the same way.
    std::vector<QueryResult> results;
    ASSERT_TRUE((*db)->RunBatch(qs, 4, &results).ok());
    for (size_t i = 0; i < qs.size(); ++i) EXPECT_EQ(results[i].hits, expected[i]) << i;
  }
}

// Boxes from unions of nearby objects' boxes (so that some equal a leaf's box, whose objects then answer
// untested), the same boxes shrunk by one double step or grown, and scene-sized boxes; points too.
std::vector<Query> LargeQueries(const std::vector<SceneObject>& objs, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Query> qs;
  Box3f scene;
  for (const SceneObject& o : objs) scene.Extend(o.Aabb());
  for (size_t i = 0; i < n; ++i) {
    Box3d box;
    const size_t first = rng() % objs.size(), count = 1 + rng() % 60;
    for (int a = 0; a < 3; ++a) {
      box.min[a] = objs[first].Aabb().min[a];
      box.max[a] = objs[first].Aabb().max[a];
    }
    for (size_t k = 1; k < count && first + k < objs.size(); ++k)
      for (int a = 0; a < 3; ++a) {
        box.min[a] = std::min<double>(box.min[a], objs[first + k].Aabb().min[a]);
        box.max[a] = std::max<double>(box.max[a], objs[first + k].Aabb().max[a]);
      }
    if (i % 4 == 1)
      for (int a = 0; a < 3; ++a) {
        box.min[a] = std::nextafter(box.min[a], 1e300);
        box.max[a] = std::nextafter(box.max[a], -1e300);
      }
    if (i % 4 == 2)
      for (int a = 0; a < 3; ++a) {
        const double grow = (scene.max[a] - scene.min[a]) * 0.1 * static_cast<double>(rng() % 4);
        box.min[a] -= grow;
        box.max[a] += grow;
      }
    if (i % 9 == 0)
      for (int a = 0; a < 3; ++a) {
        box.min[a] = scene.min[a];
        box.max[a] = scene.max[a];
      }
    qs.push_back(i % 11 == 5 ? Query::Point(Vec3d{box.min[0], box.min[1], box.min[2]}) : Query::Box(box));
  }
  return qs;
}

// The windowed warm path (Run: no limit, no stop) gives brute force's answers and, query after query,
// the very statistics of reading one leaf at a time (VisitUntil), page counts and cache hits included, at
// cache sizes 0, one page, small and the whole store: the same pages read, hit and evicted in the same
// order. VisitSpans hands over Visit's ids in Visit's order.
TEST_F(DecodedCacheTest, WindowedLeavesKeepAnswersAndCountsOfOneLeafAtATime) {
  std::vector<Query> qs = LargeQueries(*objs_, 300, 41);
  for (const Query& q : BoundaryQueries(*objs_, 200, 43, QueryMode::kAabb)) qs.push_back(q);
  std::vector<std::vector<ObjectId>> expected;
  size_t big = 0;
  for (const Query& q : qs) {
    expected.push_back(brute_->Answer(q));
    big += expected.back().size() > 100;
  }
  ASSERT_GT(big, 30u);  // answers spanning many leaves
  for (uint64_t cache : {0u, 1u, 12u, 60u, 1000000u}) {
    SCOPED_TRACE("cache " + std::to_string(cache));
    auto windowed = Database::Open(TempPath("scene.mkt"), {.cache_pages = cache});
    auto single = Database::Open(TempPath("scene.mkt"), {.cache_pages = cache});
    ASSERT_TRUE(windowed.ok() && single.ok());
    for (int pass = 0; pass < 2; ++pass) {
      for (size_t i = 0; i < qs.size(); ++i) {
        testing::ExpectRunMatchesVisitUntil(**windowed, **single, qs[i], expected[i],
                                            "pass " + std::to_string(pass) + " query " + std::to_string(i));
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
    for (size_t i = 0; i < qs.size(); i += 7) {
      std::vector<ObjectId> by_id, by_span;
      QueryStats a, b;
      ASSERT_TRUE((*single)
                      ->Visit(
                          qs[i], [&](ObjectId id) { by_id.push_back(id); }, &a)
                      .ok());
      size_t calls = 0;
      ASSERT_TRUE((*single)
                      ->VisitSpans(
                          qs[i],
                          [&](std::span<const ObjectId> ids) {
                            ++calls;
                            EXPECT_FALSE(ids.empty());
                            by_span.insert(by_span.end(), ids.begin(), ids.end());
                          },
                          &b)
                      .ok());
      EXPECT_EQ(by_span, by_id) << i;
      EXPECT_EQ(b.hits, a.hits) << i;
      EXPECT_LE(calls, b.leaves_with_hits) << i;  // one call per leaf or fewer
    }
  }
}

// A visitor may query the Database from inside a span: the window's pages are released by then.
TEST_F(DecodedCacheTest, SpanVisitorMayQueryTheDatabase) {
  auto db = Database::Open(TempPath("scene.mkt"), {.cache_pages = 1000000});
  ASSERT_TRUE(db.ok());
  const std::vector<Query> qs = LargeQueries(*objs_, 20, 47);
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t i = 0; i < qs.size(); ++i) {
      std::vector<ObjectId> got;
      ASSERT_TRUE((*db)
                      ->VisitSpans(
                          qs[i],
                          [&](std::span<const ObjectId> ids) {
                            got.insert(got.end(), ids.begin(), ids.end());
                            QueryResult inner;
                            EXPECT_TRUE((*db)->Run(qs[(i + 1) % qs.size()], &inner).ok());
                            EXPECT_EQ(inner.hits, brute_->Answer(qs[(i + 1) % qs.size()]));
                          },
                          nullptr)
                      .ok());
      std::sort(got.begin(), got.end());
      EXPECT_EQ(got, brute_->Answer(qs[i])) << i;
    }
  }
}

// Threads run large boxes through the windowed path (Run, RunBatch) and the one-leaf path (VisitUntil)
// on one Database, small caches churning: answers always brute force's.
TEST_F(DecodedCacheTest, ConcurrentWindowedLargeBoxes) {
  const std::vector<Query> qs = LargeQueries(*objs_, 80, 53);
  std::vector<std::vector<ObjectId>> expected;
  for (const Query& q : qs) expected.push_back(brute_->Answer(q));
  for (uint64_t cache : {1u, 6u, 1000000u}) {
    SCOPED_TRACE("cache " + std::to_string(cache));
    auto db = Database::Open(TempPath("scene.mkt"), {.cache_pages = cache});
    ASSERT_TRUE(db.ok());
    std::atomic<int> wrong{0}, failed{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([&, t] {
        for (int round = 0; round < 2; ++round) {
          for (size_t k = 0; k < qs.size(); ++k) {
            const size_t i = (k * 5 + static_cast<size_t>(t) * 11 + static_cast<size_t>(round)) % qs.size();
            std::vector<ObjectId> got;
            if (t == 3) {
              auto st = (*db)->VisitUntil(
                  qs[i],
                  [&](ObjectId id) {
                    got.push_back(id);
                    return true;
                  },
                  nullptr);
              if (!st.ok()) ++failed;
              std::sort(got.begin(), got.end());
            } else {
              QueryResult r;
              if (!(*db)->Run(qs[i], &r).ok()) ++failed;
              got = std::move(r.hits);
            }
            if (got != expected[i]) ++wrong;
          }
        }
      });
    }
    for (auto& th : threads) th.join();
    EXPECT_EQ(failed.load(), 0);
    EXPECT_EQ(wrong.load(), 0);
    std::vector<QueryResult> results;
    ASSERT_TRUE((*db)->RunBatch(qs, 3, &results).ok());
    for (size_t i = 0; i < qs.size(); ++i) EXPECT_EQ(results[i].hits, expected[i]) << i;
  }
}

}  // namespace
}  // namespace mktree
