// Nearest and ray queries on revisions of a store with changes (docs/nearest_and_ray.md, docs/changes.md):
// one search over the base and delta stores, removed and superseded objects hidden, answers as brute force
// over the live objects, at the newest revision and at an older one kept.
#include <gtest/gtest.h>

#include <random>

#include "changes/change_fixtures.h"
#include "query/nearest_oracle.h"

namespace mktree {
namespace {

void ExpectNearestAsLive(const Database& db, const testing::LiveSet& live, const Vec3d& origin,
                         uint64_t seed) {
  std::vector<SceneObject> objs;
  for (const auto& [id, o] : live) objs.push_back(o);
  std::vector<testing::StoredObject> stored = testing::StoredScene(objs, origin);
  const testing::NearestBruteForce brute(std::move(stored), origin);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> x(-10, 110), y(-5, 45), z(-3, 23), d(-1, 1);
  for (int i = 0; i < 20; ++i) {
    const Vec3d p{x(rng), y(rng), z(rng)};
    const uint64_t k = i % 2 ? 1 : 25;
    std::vector<NearestHit> got;
    const Status st = db.Nearest(Query::Nearest(p, k), &got, nullptr);
    ASSERT_TRUE(st.ok()) << st.ToString();
    testing::ExpectNearestAnswer(got, brute.Nearest(p), k, brute, p, 200);
    for (const NearestHit& h : got) EXPECT_TRUE(live.count(h.id)) << "id " << h.id << " is not live";
    const RayQuery r = Query::Ray(p, {d(rng), d(rng), d(rng)}, INFINITY, true);
    std::vector<RayHit> hits;
    ASSERT_TRUE(db.Ray(r, &hits, nullptr).ok());
    const auto want = brute.Hits(r);
    ASSERT_EQ(hits.size(), want.size());
    for (size_t j = 0; j < hits.size(); ++j) {
      EXPECT_EQ(hits[j].t, want[j].second);
      EXPECT_EQ(hits[j].id, want[j].first);
    }
  }
}

TEST(NearestRevisions, AnswersAreThoseOfTheLiveObjects) {
  testing::TempDir dir("mktree_nearest_rev");
  const std::string store = dir.file("s.mkt");
  const std::vector<SceneObject> objs = testing::MixedScene(800, 91);
  ASSERT_TRUE(testing::BuildFromObjects(objs, store, testing::SmallPages(Backend::kPagedFile)).ok());
  testing::LiveSet live;
  for (const SceneObject& o : objs) live[o.id] = o;
  const Vec3d origin = ChooseStoreOrigin(objs[0].mesh.Bounds());
  auto writer = ChangeWriter::Open(store, {.compact_threshold = 10});
  ASSERT_TRUE(writer.ok());
  std::mt19937_64 rng(4);
  uint64_t counter = 0;
  std::vector<testing::LiveSet> kept;
  for (int c = 0; c < 2; ++c) {
    const ChangeBatch batch = testing::RandomBatch(live, 60, rng, &counter);
    auto report = (*writer)->Commit(batch);
    ASSERT_TRUE(report.ok()) << report.status().ToString();
    testing::Apply(batch, *report, &live);
    kept.push_back(live);
  }
  auto newest = Database::Open(store, {.cache_pages = 32});
  ASSERT_TRUE(newest.ok());
  ExpectNearestAsLive(**newest, live, origin, 1);
  auto older = Database::Open(store, {.cache_pages = 0, .revision = 1});
  ASSERT_TRUE(older.ok()) << older.status().ToString();
  ExpectNearestAsLive(**older, kept[0], origin, 2);
}

}  // namespace
}  // namespace mktree
