// Nearest and within-distance queries (docs/nearest_and_ray.md) against brute force on random scenes of
// rotated boxes, prisms and open surfaces, both backends, caches 0 / small / large: distances, order, ties,
// closest points, resumed cursors, k beyond the scene, points inside solids, the I/O floor, bad queries.
#include <gtest/gtest.h>

#include <random>

#include "engine/ingest/store_builder.h"
#include "engine/query/nearest_search.h"
#include "engine/query/store_database.h"
#include "engine/scene/scene_source.h"
#include "query/nearest_oracle.h"
#include "query/query_oracle.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::StoreSetup;

class NearestQueryTest : public ::testing::TestWithParam<StoreSetup> {
 protected:
  static constexpr size_t kObjects = 1500;

  void SetUp() override {
    objs_ = testing::MixedScene(kObjects, 41);
    IngestOptions o;
    o.store.backend = GetParam().backend;
    o.store.params.block_size = 1024;
    o.store.params.blocks_per_page = 2;
    path_ = dir_.file("scene.mkt");
    ASSERT_TRUE(testing::BuildFromObjects(objs_, path_, o).ok());
    auto db = Database::Open(path_, {.cache_pages = GetParam().cache_pages});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    db_ = std::move(*db);
    brute_ = std::make_unique<testing::NearestBruteForce>(objs_, ChooseStoreOrigin(objs_[0].mesh.Bounds()));
  }

  std::vector<Vec3d> RandomPoints(size_t n, uint64_t seed) const {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> unit(-0.1, 1.1);
    const Box3d b = db_->bounds();
    std::vector<Vec3d> out;
    for (size_t i = 0; i < n; ++i) {
      Vec3d p;
      for (int a = 0; a < 3; ++a) p[a] = b.min[a] + unit(rng) * (b.max[a] - b.min[a]);
      out.push_back(p);
    }
    return out;
  }

  testing::TempDir dir_{"mktree_nearest"};
  std::string path_;
  std::vector<SceneObject> objs_;
  std::unique_ptr<Database> db_;
  std::unique_ptr<testing::NearestBruteForce> brute_;
};

TEST_P(NearestQueryTest, KNearestMatchesBruteForce) {
  const std::vector<Vec3d> points = RandomPoints(40, 7);
  for (size_t i = 0; i < points.size(); ++i) {
    const uint64_t k = i % 4 == 0 ? 1 : (i % 4 == 1 ? 5 : (i % 4 == 2 ? 20 : 100));
    SCOPED_TRACE("point " + std::to_string(i) + " k " + std::to_string(k));
    std::vector<NearestHit> got;
    QueryStats stats;
    const Status st = db_->Nearest(Query::Nearest(points[i], k), &got, &stats);
    ASSERT_TRUE(st.ok()) << st.ToString();
    testing::ExpectNearestAnswer(got, brute_->Nearest(points[i]), k, *brute_, points[i], 200);
    EXPECT_EQ(stats.hits, got.size());
    EXPECT_GT(stats.leaves_visited, 0u);
    EXPECT_EQ(stats.cache_hits + stats.pages_read, stats.pages_touched);
  }
}

TEST_P(NearestQueryTest, WithinDistanceOfAPointMatchesBruteForce) {
  for (const Vec3d& p : RandomPoints(20, 8)) {
    for (double d : {0.0, 0.5, 3.0}) {
      std::vector<NearestHit> got;
      ASSERT_TRUE(db_->Nearest(DistanceQuery::Within(p, d), &got, nullptr).ok());
      std::vector<testing::ExpectedNearest> want;
      for (const auto& e : brute_->Nearest(p))
        if (e.distance <= d) want.push_back(e);
      // Objects within rounding of the limit may fall either side.
      while (!want.empty() && got.size() < want.size() && want.back().distance > d - 1e-9) want.pop_back();
      testing::ExpectNearestAnswer(got, want, want.size(), *brute_, p, 200);
      for (const NearestHit& h : got) EXPECT_LE(h.distance, d);
    }
  }
}

TEST_P(NearestQueryTest, PointsInsideSolidsAreAtZeroAndSurfacesAreSurfaces) {
  size_t solids = 0, surfaces = 0;
  for (size_t i = 0; i < objs_.size() && solids + surfaces < 60; i += 13) {
    const Box3d b = objs_[i].mesh.Bounds();
    const Vec3d c{(b.min[0] + b.max[0]) / 2, (b.min[1] + b.max[1]) / 2, (b.min[2] + b.max[2]) / 2};
    const double want = brute_->PointDistance(i, c);
    std::vector<NearestHit> got;
    ASSERT_TRUE(db_->Nearest(Query::Nearest(c, 3), &got, nullptr).ok());
    ASSERT_FALSE(got.empty());
    EXPECT_NEAR(got[0].distance, std::min(want, brute_->Nearest(c)[0].distance), 1e-9);
    if (CheckEdges(objs_[i].mesh).closed && b.max[0] - b.min[0] > 0.05 && b.max[1] - b.min[1] > 0.05 &&
        b.max[2] - b.min[2] > 0.05 && want == 0) {
      ++solids;
      EXPECT_EQ(got[0].distance, 0.0);
      EXPECT_EQ(got[0].point.x, c.x);
    } else if (!CheckEdges(objs_[i].mesh).closed) {
      ++surfaces;
      EXPECT_GT(want, 0.0) << "an open surface has no inside";
    }
  }
  EXPECT_GT(solids, 5u);
  EXPECT_GT(surfaces, 0u);
}

TEST_P(NearestQueryTest, ResumedCursorGivesTheSameSequenceAsTheVisitor) {
  for (const Vec3d& p : RandomPoints(6, 9)) {
    const DistanceQuery q = Query::Nearest(p, 60);
    std::vector<NearestHit> all;
    ASSERT_TRUE(db_->Nearest(q, &all, nullptr).ok());
    auto a = db_->OpenNearest(q);
    auto b = db_->OpenNearest(q);
    ASSERT_TRUE(a.ok() && b.ok());
    std::vector<NearestHit> got;
    NearestHit h;
    // Two cursors interleaved, one stopping now and then: each gives the whole sequence.
    for (size_t i = 0; i < all.size(); ++i) {
      Result<bool> more = (*a)->Next(&h);
      ASSERT_TRUE(more.ok() && *more);
      EXPECT_EQ(h.id, all[i].id);
      EXPECT_EQ(h.distance, all[i].distance);
      if (i % 3 == 0) {
        ASSERT_TRUE((*b)->Next(&h).ok());
        got.push_back(h);
      }
    }
    Result<bool> end = (*a)->Next(&h);
    ASSERT_TRUE(end.ok());
    EXPECT_FALSE(*end);
    for (size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].id, all[i].id);
    // A visitor that stops after 7 saw the first 7.
    std::vector<ObjectId> seen;
    auto stopped = db_->VisitNearest(
        q,
        [&](const NearestHit& x) {
          seen.push_back(x.id);
          return seen.size() < 7;
        },
        nullptr);
    ASSERT_TRUE(stopped.ok());
    EXPECT_FALSE(*stopped);
    ASSERT_EQ(seen.size(), 7u);
    for (size_t i = 0; i < 7; ++i) EXPECT_EQ(seen[i], all[i].id);
  }
}

TEST_P(NearestQueryTest, KBeyondTheSceneGivesEveryObjectInOrder) {
  const Vec3d p = RandomPoints(1, 10)[0];
  std::vector<NearestHit> got;
  ASSERT_TRUE(db_->Nearest(Query::Nearest(p, 100000), &got, nullptr).ok());
  testing::ExpectNearestAnswer(got, brute_->Nearest(p), 100000, *brute_, p, 200);
  std::vector<bool> seen(objs_.size());
  for (const NearestHit& h : got) {
    ASSERT_LT(h.id, seen.size());
    EXPECT_FALSE(seen[h.id]) << "id " << h.id << " twice";
    seen[h.id] = true;
  }
}

TEST_P(NearestQueryTest, WithinDistanceOfABoxMatchesBruteForce) {
  std::mt19937_64 rng(11);
  for (const Vec3d& p : RandomPoints(8, 12)) {
    Box3d b;
    for (int a = 0; a < 3; ++a) b.min[a] = p[a], b.max[a] = p[a] + 0.5 + (rng() % 100) / 50.0;
    std::vector<NearestHit> got;
    ASSERT_TRUE(db_->Nearest(DistanceQuery::WithinBox(b, 1.0), &got, nullptr).ok());
    const auto want = brute_->NearBox(b, 1.0);
    ASSERT_EQ(got.size(), want.size());
    for (size_t i = 0; i < got.size(); ++i) EXPECT_NEAR(got[i].distance, want[i].distance, 1e-9);
  }
}

// With no cache every page looked up is read: a best-first search reads exactly the pages of the leaves
// whose region is nearer than the k-th answer (NearestPageFloor).
TEST_P(NearestQueryTest, PagesReadAreTheFloor) {
  if (GetParam().cache_pages != 0) GTEST_SKIP() << "counted without a cache";
  const auto* store = dynamic_cast<const StoreDatabase*>(db_.get());
  ASSERT_NE(store, nullptr);
  for (const Vec3d& p : RandomPoints(20, 13)) {
    for (uint64_t k : {1, 10, 100}) {
      const DistanceQuery q = Query::Nearest(p, k);
      std::vector<NearestHit> got;
      QueryStats s;
      ASSERT_TRUE(db_->Nearest(q, &got, &s).ok());
      ASSERT_EQ(got.size(), k);
      const uint64_t floor = NearestPageFloor({SearchPart{store}}, q, got.back().distance);
      EXPECT_EQ(s.pages_touched, floor) << "k " << k;
      EXPECT_EQ(s.pages_read, floor);
    }
  }
}

TEST_P(NearestQueryTest, BadQueriesAreRefusedNamingTheQuery) {
  std::vector<NearestHit> got;
  const double nan = std::nan(""), inf = INFINITY;
  for (const DistanceQuery& q :
       {Query::Nearest({nan, 0, 0}, 1), Query::Nearest({0, inf, 0}, 1), Query::Nearest({0, 0, 0}, 0),
        Query::Nearest({0, 0, 0}, 1, -1), Query::Nearest({0, 0, 0}, 1, nan)}) {
    const Status st = db_->Nearest(q, &got, nullptr);
    EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
    EXPECT_NE(st.message().find("nearest query"), std::string::npos) << st.message();
  }
  Box3d inverted;
  inverted.min = {1, 1, 1};
  inverted.max = {0, 2, 2};
  EXPECT_EQ(db_->Nearest(DistanceQuery::WithinBox(inverted, 1), &got, nullptr).code(),
            Status::Code::kInvalidArgument);
  EXPECT_EQ(db_->Nearest(DistanceQuery::WithinMesh(Mesh{}, 1), &got, nullptr).code(),
            Status::Code::kInvalidArgument);
}

INSTANTIATE_TEST_SUITE_P(Backends, NearestQueryTest,
                         ::testing::Values(StoreSetup{Backend::kHdf5, 0}, StoreSetup{Backend::kPagedFile, 0},
                                           StoreSetup{Backend::kHdf5, 16},
                                           StoreSetup{Backend::kPagedFile, 4096}),
                         [](const auto& info) {
                           return std::string(info.param.backend == Backend::kHdf5 ? "Hdf5" : "PagedFile") +
                                  "Cache" + std::to_string(info.param.cache_pages);
                         });

// A scene far from 0 (store origin not zero) answers with world coordinates.
TEST(NearestFarScene, DistancesAndPointsAreInWorldCoordinates) {
  const std::vector<SceneObject> objs = testing::MixedScene(300, 5, 1e6);
  testing::TempDir dir("mktree_nearest_far");
  IngestOptions o;
  ASSERT_TRUE(testing::BuildFromObjects(objs, dir.file("far.mkt"), o).ok());
  auto db = Database::Open(dir.file("far.mkt"));
  ASSERT_TRUE(db.ok());
  const testing::NearestBruteForce brute(objs, ChooseStoreOrigin(objs[0].mesh.Bounds()));
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  const Box3d b = (*db)->bounds();
  for (int i = 0; i < 10; ++i) {
    Vec3d p;
    for (int a = 0; a < 3; ++a) p[a] = b.min[a] + u(rng) * (b.max[a] - b.min[a]);
    std::vector<NearestHit> got;
    ASSERT_TRUE((*db)->Nearest(Query::Nearest(p, 5), &got, nullptr).ok());
    testing::ExpectNearestAnswer(got, brute.Nearest(p), 5, brute, p, 1e6);
  }
}

// The small real scenes of ../shared/data (a ship in AC3D, a building in OBJ): nearest and rays against brute
// force over the stored geometry.
class NearestRealScene : public ::testing::TestWithParam<const char*> {};

TEST_P(NearestRealScene, NearestAndRaysMatchBruteForce) {
  const std::string file = std::string(MKTREE_SHARED_DATA) + "/" + GetParam();
  std::vector<SceneObject> objs;
  {
    auto src = OpenSceneFile(file, 0);
    ASSERT_TRUE(src.ok()) << src.status().ToString();
    SceneObject o;
    while (true) {
      auto more = (*src)->Next(&o);
      ASSERT_TRUE(more.ok()) << more.status().ToString();
      if (!*more) break;
      objs.push_back(o);
    }
  }
  ASSERT_FALSE(objs.empty());
  testing::TempDir dir("mktree_nearest_real");
  IngestOptions o;
  o.store.backend = Backend::kPagedFile;
  auto report =
      BuildStore({[&](ObjectId first) { return OpenSceneFile(file, first); }}, dir.file("s.mkt"), o);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  auto db = Database::Open(dir.file("s.mkt"), {.cache_pages = 64});
  ASSERT_TRUE(db.ok());
  const testing::NearestBruteForce brute(objs, report->origin);
  const Box3d b = (*db)->bounds();
  double scale = 1;
  for (int a = 0; a < 3; ++a) scale = std::max({scale, std::fabs(b.min[a]), std::fabs(b.max[a])});
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0, 1), d(-1, 1);
  for (int i = 0; i < 15; ++i) {
    Vec3d p;
    for (int a = 0; a < 3; ++a) p[a] = b.min[a] + u(rng) * (b.max[a] - b.min[a]);
    std::vector<NearestHit> got;
    ASSERT_TRUE((*db)->Nearest(Query::Nearest(p, 5), &got, nullptr).ok());
    testing::ExpectNearestAnswer(got, brute.Nearest(p), 5, brute, p, scale);
    const RayQuery r = Query::Ray(p, {d(rng), d(rng), d(rng)}, INFINITY, true);
    std::vector<RayHit> hits;
    ASSERT_TRUE((*db)->Ray(r, &hits, nullptr).ok());
    const auto want = brute.Hits(r);
    ASSERT_EQ(hits.size(), want.size());
    for (size_t j = 0; j < hits.size(); ++j) EXPECT_EQ(hits[j].t, want[j].second);
  }
}

INSTANTIATE_TEST_SUITE_P(Files, NearestRealScene,
                         ::testing::Values("ships/ContainerShip.ac", "buildings/duplex.obj"),
                         [](const auto& info) {
                           return std::string(info.param).find("ship") != std::string::npos ? "ContainerShip"
                                                                                            : "Duplex";
                         });

}  // namespace
}  // namespace mktree
