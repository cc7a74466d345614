// Nearest and ray queries on sharded stores (docs/nearest_and_ray.md, docs/shards.md): the same distances
// and hits as the unsharded store of the same scene and as brute force, nearest shard first (one search
// over every shard's tree: no shard's leaf is read unless nearer than the k-th answer).
#include <gtest/gtest.h>

#include <random>

#include "engine/ingest/store_builder.h"
#include "mktree/build.h"
#include "mktree/database.h"
#include "query/nearest_oracle.h"
#include "test_dirs.h"

namespace mktree {
namespace {

class NearestShardTest : public ::testing::TestWithParam<BuildOptions::Backend> {};

TEST_P(NearestShardTest, SameAnswersAsTheUnshardedStoreAndBruteForce) {
  testing::TempDir dir("mktree_nearest_shard");
  const std::vector<SceneObject> objs = testing::MixedScene(1500, 77);
  BuildOptions o;
  o.backend = GetParam();
  o.block_size = 1024;
  o.blocks_per_page = 2;
  o.threads = 2;
  ASSERT_TRUE(BuildFromObjects(objs, dir.path() / "plain.mkt", o).ok());
  o.shards = 3;
  ASSERT_TRUE(BuildFromObjects(objs, dir.path() / "s.mkts", o).ok());
  for (uint64_t cache : {0, 64}) {
    auto sharded = Database::Open(dir.path() / "s.mkts", {.cache_pages = cache});
    auto plain = Database::Open(dir.path() / "plain.mkt", {.cache_pages = cache});
    ASSERT_TRUE(sharded.ok() && plain.ok());
    ASSERT_EQ((*sharded)->shard_count(), 3u);
    const testing::NearestBruteForce brute(objs, ChooseStoreOrigin(objs[0].mesh.Bounds()));
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-0.1, 1.1);
    const Box3d b = (*plain)->bounds();
    for (int i = 0; i < 25; ++i) {
      Vec3d p;
      for (int a = 0; a < 3; ++a) p[a] = b.min[a] + u(rng) * (b.max[a] - b.min[a]);
      const uint64_t k = i % 3 == 0 ? 1 : (i % 3 == 1 ? 10 : 100);
      std::vector<NearestHit> s, q;
      QueryStats ss, qs;
      ASSERT_TRUE((*sharded)->Nearest(Query::Nearest(p, k), &s, &ss).ok());
      ASSERT_TRUE((*plain)->Nearest(Query::Nearest(p, k), &q, &qs).ok());
      testing::ExpectNearestAnswer(s, brute.Nearest(p), k, brute, p, 200);
      ASSERT_EQ(s.size(), q.size());
      for (size_t j = 0; j < s.size(); ++j) EXPECT_EQ(s[j].distance, q[j].distance);
      EXPECT_EQ(ss.hits, s.size());
      if (cache == 0) {
        EXPECT_EQ(ss.pages_read, ss.pages_touched);
      }
      // Rays: the first hit and every hit, as the plain store and brute force.
      RayQuery r = Query::Ray(p, {u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5}, INFINITY, i % 2 == 0);
      std::vector<RayHit> sh, ph;
      ASSERT_TRUE((*sharded)->Ray(r, &sh, nullptr).ok());
      ASSERT_TRUE((*plain)->Ray(r, &ph, nullptr).ok());
      auto want = brute.Hits(RayQuery{r.origin, r.direction, r.max_length, true});
      if (!r.all_hits && want.size() > 1) want.resize(1);
      ASSERT_EQ(sh.size(), want.size());
      ASSERT_EQ(ph.size(), want.size());
      for (size_t j = 0; j < sh.size(); ++j) {
        EXPECT_EQ(sh[j].t, want[j].second);
        EXPECT_EQ(sh[j].id, ph[j].id);
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, NearestShardTest,
                         ::testing::Values(BuildOptions::Backend::kHdf5, BuildOptions::Backend::kPagedFile),
                         [](const auto& info) {
                           return info.param == BuildOptions::Backend::kHdf5 ? "Hdf5" : "PagedFile";
                         });

}  // namespace
}  // namespace mktree
