// Streamed batches, early stop and result limits (database.h: RunBatchStreamed, VisitUntil, Any,
// Query::limit) against brute force and against per-query Run, on both backends.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <random>

#include "engine/ingest/store_builder.h"
#include "engine/query/store_database.h"
#include "engine/scene/vector_scene_source.h"
#include "mktree/database.h"
#include "query/query_oracle.h"
#include "query/scene_fixtures.h"
#include "storage/memory_page_store.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::TempPath;

Status BuildSmallPages(const std::vector<SceneObject>& objs, const std::string& path, Backend backend) {
  IngestOptions o;
  o.store.backend = backend;
  o.store.params.block_size = 1024;
  o.store.params.blocks_per_page = 2;
  return testing::BuildFromObjects(objs, path, o);
}

// Points inside and beside objects, and boxes from tiny to a fifth of the scene.
std::vector<Query> MixedQueries(const std::vector<SceneObject>& objs, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  Box3f all;
  for (const SceneObject& o : objs) all.Extend(o.Aabb());
  std::vector<Query> qs;
  for (size_t i = 0; i < n; ++i) {
    const Box3f ob = objs[rng() % objs.size()].Aabb();
    Vec3d p;
    for (int a = 0; a < 3; ++a) p[a] = ob.min[a] + (unit(rng) * 1.2 - 0.1) * (ob.max[a] - ob.min[a]);
    if (rng() % 3 == 0) {
      qs.push_back(Query::Point(p));
      continue;
    }
    const double side = std::pow(10.0, -2 + 3 * unit(rng)) * (all.max[0] - all.min[0]) / 50;
    Box3d b;
    for (int a = 0; a < 3; ++a) {
      b.min[a] = p[a] - side * unit(rng);
      b.max[a] = p[a] + side * unit(rng);
    }
    qs.push_back(Query::Box(b));
  }
  return qs;
}

class StreamingTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    objs_ = testing::ClusteredScene(2500, 77);
    path_ = TempPath(std::string("scene_") + (GetParam() == Backend::kHdf5 ? "h5" : "pf") + ".mkt");
    ASSERT_TRUE(BuildSmallPages(objs_, path_, GetParam()).ok());
  }
  void TearDown() override { fs::remove(path_); }

  std::vector<SceneObject> objs_;
  std::string path_;
};

// RunBatchStreamed == RunBatch == Run per query (ids, truncation and, cold, every count), in query order,
// on 1, 2 and 4 threads, for random query sets, in both modes and with and without ids.
TEST_P(StreamingTest, StreamedBatchEqualsRunBatchAndRunOnAnyThreads) {
  auto db = Database::Open(path_, {.cache_pages = 12});
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  const testing::BruteForce brute(objs_);
  for (uint64_t seed : {1u, 2u}) {
    std::vector<Query> qs = MixedQueries(objs_, 150, seed);
    for (size_t i = 0; i < qs.size(); i += 7) qs[i].limit = i % 5;  // some limited
    for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
      for (Query& q : qs) q.mode = mode;
      std::vector<QueryResult> singles(qs.size());
      for (size_t i = 0; i < qs.size(); ++i) {
        (*db)->ClearCache();
        ASSERT_TRUE((*db)->Run(qs[i], &singles[i]).ok());
        if (qs[i].limit == Query::kNoLimit) {
          ASSERT_EQ(singles[i].hits, brute.Answer(qs[i])) << i;
        }
      }
      for (unsigned threads : {1u, 2u, 4u}) {
        SCOPED_TRACE("seed " + std::to_string(seed) + ", threads " + std::to_string(threads));
        std::vector<QueryResult> batch;
        ASSERT_TRUE((*db)->RunBatch(qs, threads, &batch).ok());
        for (bool ids : {true, false}) {
          uint64_t next = 0;
          BatchOptions o{.threads = threads, .cold = true, .ids = ids};
          const Status st = (*db)->RunBatchStreamed(qs, o, [&](uint64_t i, const QueryResult& r) {
            EXPECT_EQ(i, next++);
            EXPECT_EQ(r.hits, ids ? singles[i].hits : std::vector<ObjectId>()) << i;
            EXPECT_EQ(r.truncated, singles[i].truncated) << i;
            EXPECT_EQ(r.stats.ToJsonMembers(), singles[i].stats.ToJsonMembers()) << i;
            EXPECT_EQ(batch[i].hits, singles[i].hits) << i;
            EXPECT_EQ(batch[i].truncated, singles[i].truncated) << i;
            return Status::Ok();
          });
          ASSERT_TRUE(st.ok()) << st.ToString();
          EXPECT_EQ(next, qs.size());
        }
      }
    }
  }
}

// Never more than `window` queries between the source and delivery (read but not delivered), whatever
// the threads and the cost of each query; results come in order.
TEST_P(StreamingTest, TheWindowBoundsTheResultsHeld) {
  auto db = Database::Open(path_, {.cache_pages = 64});
  ASSERT_TRUE(db.ok());
  std::vector<Query> qs = MixedQueries(objs_, 300, 9);
  Box3d whole = (*db)->bounds();
  for (size_t i = 0; i < qs.size(); i += 37) qs[i] = Query::Box(whole);  // slow ones among quick ones
  for (unsigned threads : {1u, 2u, 4u}) {
    for (uint64_t window : {0u, 1u, 3u, 16u}) {
      SCOPED_TRACE("threads " + std::to_string(threads) + ", window " + std::to_string(window));
      const uint64_t bound = window ? window : 4 * threads;
      uint64_t read = 0, delivered = 0, most = 0;
      auto source = [&](Query* q) -> Result<bool> {
        if (read == qs.size()) return false;
        EXPECT_LT(read - delivered, bound);  // room for this one
        *q = qs[read++];
        most = std::max(most, read - delivered);
        return true;
      };
      auto deliver = [&](uint64_t i, const QueryResult& r) {
        EXPECT_EQ(i, delivered);
        EXPECT_LE(read - delivered, bound);
        EXPECT_EQ(r.hits.size(), r.stats.hits);
        ++delivered;
        return Status::Ok();
      };
      BatchOptions o{.threads = threads, .window = window};
      ASSERT_TRUE((*db)->RunBatchStreamed(source, o, deliver).ok());
      EXPECT_EQ(delivered, qs.size());
      EXPECT_LE(most, bound);
      if (threads > 1) {
        EXPECT_EQ(most, bound);  // the window is used: queries run ahead of delivery
      }
    }
  }
}

// An "is anything here?" check over a box meeting every leaf reads the pages of one leaf; the full answer
// reads them all. A visitor that stops reads no further leaf. Stats count what was done.
TEST_P(StreamingTest, EarlyStopReadsOnlyUpToTheFirstHits) {
  auto db = Database::Open(path_, {.cache_pages = 100000});
  ASSERT_TRUE(db.ok());
  const Query whole = Query::Box((*db)->bounds());
  QueryResult full;
  (*db)->ClearCache();
  ASSERT_TRUE((*db)->Run(whole, &full).ok());
  ASSERT_EQ(full.hits.size(), objs_.size());
  ASSERT_GT(full.stats.pages_read, 20u);

  QueryStats any_stats;
  (*db)->ClearCache();
  auto any = (*db)->Any(whole, &any_stats);
  ASSERT_TRUE(any.ok());
  EXPECT_TRUE(*any);
  EXPECT_LE(any_stats.pages_read, 2u);  // one leaf (a leaf of two pages at most in this scene)
  EXPECT_EQ(any_stats.leaves_visited, 1u);
  EXPECT_EQ(any_stats.hits, 0u);
  EXPECT_LE(any_stats.candidates_tested, full.stats.candidates_tested / full.stats.leaves_visited * 4);

  // Nothing there: false, whatever it had to read to know.
  Box3d away = (*db)->bounds();
  away.min[0] = away.max[0] + 10;
  away.max[0] = away.max[0] + 20;
  auto none = (*db)->Any(Query::Box(away), &any_stats);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(*none);

  for (uint64_t stop_after : {1u, 10u, 300u}) {
    std::vector<ObjectId> seen;
    QueryStats s;
    (*db)->ClearCache();
    auto complete = (*db)->VisitUntil(
        whole,
        [&](ObjectId id) {
          seen.push_back(id);
          return seen.size() < stop_after;
        },
        &s);
    ASSERT_TRUE(complete.ok());
    EXPECT_FALSE(*complete);
    EXPECT_EQ(seen.size(), stop_after);
    EXPECT_EQ(s.hits, stop_after);
    EXPECT_LT(s.pages_read, full.stats.pages_read);
    EXPECT_EQ(s.pages_touched, s.pages_read);
    EXPECT_EQ(s.leaves_with_hits, s.leaves_visited);  // every leaf of the whole box answers
  }
}

// Query::limit against brute force: the first `limit` ids in visiting order, sorted by Run; truncated
// exactly when the whole answer is longer; never more pages than the whole answer.
TEST_P(StreamingTest, LimitTruncatesAndSaysSo) {
  auto db = Database::Open(path_, {.cache_pages = 100000});
  ASSERT_TRUE(db.ok());
  const testing::BruteForce brute(objs_);
  std::vector<Query> qs = MixedQueries(objs_, 120, 5);
  qs.push_back(Query::Box((*db)->bounds()));
  size_t cut = 0;
  for (const Query& base : qs) {
    const std::vector<ObjectId> all = brute.Answer(base);
    std::vector<ObjectId> order;
    QueryStats full_stats;
    (*db)->ClearCache();
    ASSERT_TRUE((*db)
                    ->Visit(
                        base, [&](ObjectId id) { order.push_back(id); }, &full_stats)
                    .ok());
    for (uint64_t limit : {0u, 1u, 5u, 60u, 5000u}) {
      Query q = base;
      q.limit = limit;
      QueryResult r;
      (*db)->ClearCache();
      ASSERT_TRUE((*db)->Run(q, &r).ok());
      const size_t n = std::min<size_t>(limit, all.size());
      std::vector<ObjectId> first(order.begin(), order.begin() + static_cast<ptrdiff_t>(n));
      std::sort(first.begin(), first.end());
      ASSERT_EQ(r.hits, first) << "limit " << limit;
      EXPECT_EQ(r.truncated, all.size() > limit) << "limit " << limit;
      EXPECT_EQ(r.stats.hits, n);
      EXPECT_LE(r.stats.pages_read, full_stats.pages_read);
      EXPECT_TRUE(std::includes(all.begin(), all.end(), r.hits.begin(), r.hits.end()));
      cut += r.truncated;
      auto any = (*db)->Any(base, nullptr);
      ASSERT_TRUE(any.ok());
      EXPECT_EQ(*any, !all.empty());
    }
  }
  EXPECT_GT(cut, 100u);
}

// A corrupted leaf in the middle of a batch stops the stream with the error of the first failing query
// (naming the store); every result before it was delivered and is right; none after it is.
TEST_P(StreamingTest, ACorruptLeafStopsTheStreamAfterTheAnswersBeforeIt) {
  auto healthy = Database::Open(path_, {.cache_pages = 8});
  ASSERT_TRUE(healthy.ok());
  auto reader = StoreReader::Open(path_);
  ASSERT_TRUE(reader.ok());
  const LeafInfo leaf = (*reader)->tree().leaves[(*reader)->tree().leaves.size() / 2];
  FaultyPageStore* faulty = nullptr;
  (*reader)->WrapPages([&](std::unique_ptr<PageStore> pages) {
    auto f = std::make_unique<FaultyPageStore>(std::move(pages));
    faulty = f.get();
    return f;
  });
  faulty->FlipByte(leaf.first_page, 40, 0x40);
  auto db = OpenStoreDatabase(std::move(*reader), {.cache_pages = 8});

  // Queries that do not read the damaged page, then one that does, then more of both.
  const std::vector<Query> pool = MixedQueries(objs_, 400, 13);
  std::vector<Query> good, bad;
  QueryResult r;
  for (const Query& q : pool) {
    db->ClearCache();
    (db->Run(q, &r).ok() ? good : bad).push_back(q);
  }
  ASSERT_GE(good.size(), 60u);
  ASSERT_GE(bad.size(), 2u);
  std::vector<Query> qs(good.begin(), good.begin() + 40);
  qs.push_back(bad[0]);
  qs.insert(qs.end(), good.begin() + 40, good.begin() + 60);
  qs.push_back(bad[1]);
  std::vector<QueryResult> truth;
  ASSERT_TRUE((*healthy)->RunBatch(qs, 1, &truth).ok());

  for (unsigned threads : {1u, 2u, 4u}) {
    for (bool cold : {false, true}) {
      db->ClearCache();
      std::vector<QueryResult> got;
      BatchOptions o{.threads = threads, .cold = cold};
      const Status st = db->RunBatchStreamed(qs, o, [&](uint64_t i, const QueryResult& res) {
        EXPECT_EQ(i, got.size());
        got.push_back(res);
        return Status::Ok();
      });
      EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
      EXPECT_EQ(st.message().rfind("query 40: ", 0), 0u) << st.message();
      EXPECT_NE(st.message().find(path_), std::string::npos) << st.message();
      ASSERT_EQ(got.size(), 40u);
      for (size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].hits, truth[i].hits) << i;
    }
  }
}

// The source's and the receiver's errors stop the batch and come back as they are, after the results
// before them.
TEST_P(StreamingTest, SourceAndReceiverErrorsStopTheBatch) {
  auto db = Database::Open(path_);
  ASSERT_TRUE(db.ok());
  const std::vector<Query> qs = MixedQueries(objs_, 50, 3);
  for (unsigned threads : {1u, 3u}) {
    size_t read = 0, delivered = 0;
    auto source = [&](Query* q) -> Result<bool> {
      if (read == 25) return Status::InvalidArgument("queries.txt:26: broken");
      *q = qs[read++];
      return true;
    };
    auto count = [&](uint64_t, const QueryResult&) {
      ++delivered;
      return Status::Ok();
    };
    Status st = (*db)->RunBatchStreamed(source, {.threads = threads}, count);
    EXPECT_EQ(st.message(), "queries.txt:26: broken");
    EXPECT_EQ(delivered, 25u);

    delivered = 0;
    auto refuse = [&](uint64_t i, const QueryResult&) {
      ++delivered;
      return i == 10 ? Status::IOError("stdout closed") : Status::Ok();
    };
    st = (*db)->RunBatchStreamed(qs, {.threads = threads}, refuse);
    EXPECT_EQ(st.message(), "stdout closed");
    EXPECT_EQ(delivered, 11u);

    // A bad query in the batch is named by its index.
    std::vector<Query> with_bad = qs;
    with_bad[7].box.min[0] = with_bad[7].box.max[0] + 1;
    with_bad[7].kind = Query::Kind::kBox;
    delivered = 0;
    st = (*db)->RunBatchStreamed(with_bad, {.threads = threads}, count);
    EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
    EXPECT_EQ(st.message().rfind("query 7: ", 0), 0u) << st.message();
    EXPECT_EQ(delivered, 7u);
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, StreamingTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) {
                           return info.param == Backend::kHdf5 ? "Hdf5" : "PagedFile";
                         });

}  // namespace
}  // namespace mktree
