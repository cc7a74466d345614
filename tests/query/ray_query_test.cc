// Ray queries (docs/nearest_and_ray.md) against brute force (every triangle of every object along every
// ray) on random scenes of rotated boxes, prisms and open surfaces, both backends, caches 0 / small /
// large: first hits, all hits in order, rays along shared edges and through vertices, rays starting inside
// a solid, the pages a first-hit ray reads, bad rays.
#include <gtest/gtest.h>

#include <random>

#include "engine/ingest/store_builder.h"
#include "engine/query/ray_search.h"
#include "engine/query/store_database.h"
#include "query/nearest_oracle.h"
#include "query/query_oracle.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::StoreSetup;

class RayQueryTest : public ::testing::TestWithParam<StoreSetup> {
 protected:
  void SetUp() override {
    objs_ = testing::MixedScene(1500, 43);
    IngestOptions o;
    o.store.backend = GetParam().backend;
    o.store.params.block_size = 1024;
    o.store.params.blocks_per_page = 2;
    ASSERT_TRUE(testing::BuildFromObjects(objs_, dir_.file("scene.mkt"), o).ok());
    auto db = Database::Open(dir_.file("scene.mkt"), {.cache_pages = GetParam().cache_pages});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    db_ = std::move(*db);
    origin_ = ChooseStoreOrigin(objs_[0].mesh.Bounds());
    brute_ = std::make_unique<testing::NearestBruteForce>(objs_, origin_);
  }

  std::vector<RayQuery> RandomRays(size_t n, uint64_t seed) const {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> unit(0, 1), dir(-1, 1);
    const Box3d b = db_->bounds();
    std::vector<RayQuery> out;
    for (size_t i = 0; i < n; ++i) {
      RayQuery q;
      for (int a = 0; a < 3; ++a) q.origin[a] = b.min[a] + unit(rng) * (b.max[a] - b.min[a]);
      // Some rays along the axes (along the boxes' faces), some scaled far from unit length.
      if (i % 2 == 1) {  // at an object's centre
        const Box3d ob = objs_[rng() % objs_.size()].mesh.Bounds();
        for (int a = 0; a < 3; ++a) q.direction[a] = (ob.min[a] + ob.max[a]) / 2 - q.origin[a];
      } else if (i % 4 == 0) {
        q.direction[static_cast<int>(rng() % 3)] = (rng() % 2 ? 1 : -1) * 7.0;
      } else {
        for (int a = 0; a < 3; ++a) q.direction[a] = dir(rng) * (i % 3 == 0 ? 1e-3 : 1);
      }
      q.max_length = i % 5 == 0 ? 10 : INFINITY;
      out.push_back(q);
    }
    return out;
  }

  // got matches brute force: the same t in order, each id's t its own, points on the ray.
  void ExpectHits(const RayQuery& q, const std::vector<RayHit>& got) const {
    auto want = brute_->Hits(q);
    if (!q.all_hits && want.size() > 1) want.resize(1);
    ASSERT_EQ(got.size(), want.size());
    for (size_t i = 0; i < got.size(); ++i) {
      EXPECT_DOUBLE_EQ(got[i].t, want[i].second) << "hit " << i;
      if (got[i].t != want[i].second) continue;
      EXPECT_EQ(got[i].id, want[i].first) << "ties by id";
      const double n = std::sqrt(got[i].normal.x * got[i].normal.x + got[i].normal.y * got[i].normal.y +
                                 got[i].normal.z * got[i].normal.z);
      EXPECT_NEAR(n, 1.0, 1e-12);
      const double len = std::sqrt(q.direction.x * q.direction.x + q.direction.y * q.direction.y +
                                   q.direction.z * q.direction.z);
      for (int a = 0; a < 3; ++a)
        EXPECT_NEAR(got[i].point[a], q.origin[a] + got[i].t * q.direction[a] / len, 1e-9);
    }
  }

  testing::TempDir dir_{"mktree_ray"};
  std::vector<SceneObject> objs_;
  std::unique_ptr<Database> db_;
  Vec3d origin_;
  std::unique_ptr<testing::NearestBruteForce> brute_;
};

TEST_P(RayQueryTest, FirstAndAllHitsMatchBruteForce) {
  size_t hit = 0;
  for (RayQuery q : RandomRays(40, 21)) {
    for (bool all : {false, true}) {
      q.all_hits = all;
      std::vector<RayHit> got;
      QueryStats s;
      ASSERT_TRUE(db_->Ray(q, &got, &s).ok());
      ExpectHits(q, got);
      EXPECT_EQ(s.hits, got.size());
      hit += !got.empty();
    }
  }
  EXPECT_GT(hit, 30u);
}

// Rays along a box's edge, through its corner, through the diagonal its two face triangles share, and
// from inside it: each hits the object once, where brute force says.
TEST_P(RayQueryTest, EdgesVerticesAndInsideHitOnce) {
  size_t tested = 0;
  for (size_t i = 0; i < objs_.size() && tested < 12; ++i) {
    auto mesh = db_->ObjectGeometry(static_cast<ObjectId>(i));
    ASSERT_TRUE(mesh.ok());
    if (mesh->triangle_count() != 12 || i % 5 == 1) continue;  // axis-aligned boxes only
    const Box3d b = mesh->Bounds();
    if (b.max[0] - b.min[0] < 0.1 || b.max[1] - b.min[1] < 0.1 || b.max[2] - b.min[2] < 0.1) continue;
    ++tested;
    const Vec3d lo{b.min[0], b.min[1], b.min[2]};
    const Vec3d c{(b.min[0] + b.max[0]) / 2, (b.min[1] + b.max[1]) / 2, (b.min[2] + b.max[2]) / 2};
    const std::vector<RayQuery> rays = {
        {{lo.x - 1, lo.y, lo.z}, {1, 0, 0}, INFINITY, true},                // along an edge
        {{lo.x - 0.5, lo.y - 0.5, lo.z - 0.5}, {1, 1, 1}, INFINITY, true},  // through a corner
        {{c.x, c.y, b.max[2] + 1}, {0, 0, -1}, INFINITY, true},             // the faces' shared diagonals
        {{2 * b.min[0] - b.max[0], 2 * b.min[1] - b.max[1], c.z},           // through two vertical edges
         {b.max[0] - b.min[0], b.max[1] - b.min[1], 0},
         INFINITY,
         true},
        {c, {1, 0, 0}, INFINITY, true},  // from inside
    };
    for (size_t r = 0; r < rays.size(); ++r) {
      const RayQuery& q = rays[r];
      SCOPED_TRACE("ray " + std::to_string(r));
      std::vector<RayHit> got;
      ASSERT_TRUE(db_->Ray(q, &got, nullptr).ok());
      ExpectHits(q, got);
      size_t mine = 0;
      for (const RayHit& h : got) mine += h.id == i;
      EXPECT_EQ(mine, 1u) << "object " << i << " hit once";
    }
    // From inside, the hit is where the ray leaves, on the +x face, whose normal points out.
    std::vector<RayHit> got;
    ASSERT_TRUE(db_->Ray(Query::Ray(c, {1, 0, 0}, INFINITY, true), &got, nullptr).ok());
    for (const RayHit& h : got) {
      if (h.id != i) continue;
      EXPECT_NEAR(h.t, (b.max[0] - b.min[0]) / 2, 1e-6);
      EXPECT_NEAR(h.normal.x, 1.0, 1e-9);
    }
  }
  EXPECT_EQ(tested, 12u);
}

// A first-hit ray reads at most the leaves whose region the ray enters before its hit, and every one of
// them: with no cache, pages_touched is RayPageFloor(t of the hit).
TEST_P(RayQueryTest, FirstHitReadsTheFloor) {
  if (GetParam().cache_pages != 0) GTEST_SKIP() << "counted without a cache";
  const auto* store = dynamic_cast<const StoreDatabase*>(db_.get());
  ASSERT_NE(store, nullptr);
  for (const RayQuery& q : RandomRays(40, 22)) {
    std::vector<RayHit> got;
    QueryStats s;
    ASSERT_TRUE(db_->Ray(q, &got, &s).ok());
    const double t = got.empty() ? q.max_length : got[0].t;
    EXPECT_EQ(s.pages_touched, RayPageFloor({SearchPart{store}}, q, t));
  }
}

TEST_P(RayQueryTest, BadRaysAreRefusedNamingTheQuery) {
  std::vector<RayHit> got;
  const double nan = std::nan("");
  for (const RayQuery& q : {Query::Ray({0, 0, 0}, {0, 0, 0}), Query::Ray({nan, 0, 0}, {1, 0, 0}),
                            Query::Ray({0, 0, 0}, {INFINITY, 0, 0}), Query::Ray({0, 0, 0}, {1, 0, 0}, -1),
                            Query::Ray({0, 0, 0}, {1, 0, 0}, nan)}) {
    const Status st = db_->Ray(q, &got, nullptr);
    EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
    EXPECT_NE(st.message().find("ray query"), std::string::npos) << st.message();
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, RayQueryTest,
                         ::testing::Values(StoreSetup{Backend::kHdf5, 0}, StoreSetup{Backend::kPagedFile, 0},
                                           StoreSetup{Backend::kHdf5, 16},
                                           StoreSetup{Backend::kPagedFile, 4096}),
                         [](const auto& info) {
                           return std::string(info.param.backend == Backend::kHdf5 ? "Hdf5" : "PagedFile") +
                                  "Cache" + std::to_string(info.param.cache_pages);
                         });

}  // namespace
}  // namespace mktree
