// Incremental clash: the pairs ClashSince reports as new and resolved, applied to the full self-clash at
// the older revision, give the full self-clash at the newer one exactly (by id pair), on both backends.
#include <gtest/gtest.h>

#include <set>

#include "change_fixtures.h"

namespace mktree {
namespace {

using IdPairs = std::set<std::pair<ObjectId, ObjectId>>;

IdPairs Ids(const std::vector<ClashPair>& pairs) {
  IdPairs out;
  for (const ClashPair& p : pairs) out.insert({p.a, p.b});
  return out;
}

class ClashSinceTest : public ::testing::TestWithParam<Backend> {};

TEST_P(ClashSinceTest, NewAndResolvedTurnTheOldClashIntoTheNew) {
  testing::TempDir dir("mktree_since");
  std::mt19937_64 rng(41);
  std::vector<SceneObject> scene = testing::ClusteredScene(400, 13);
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(GetParam())).ok());
  testing::LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0;
  ClashOptions o;
  o.clearance = 0.05;
  for (int round = 0; round < 3; ++round) {
    auto then = Database::Open(store);
    ASSERT_TRUE(then.ok());
    const IdPairs before = Ids(testing::SelfClashPairs(**then, o));
    for (int b = 0; b < 3; ++b) {
      const ChangeBatch batch = testing::RandomBatch(live, 12, rng, &counter);
      auto done = (*w)->Commit(batch);
      ASSERT_TRUE(done.ok()) << done.status().ToString();
      testing::Apply(batch, *done, &live);
    }
    if (round == 1) {  // across a compaction too
      ASSERT_TRUE((*w)->Compact().ok());
    }
    auto now = Database::Open(store);
    ASSERT_TRUE(now.ok());
    const IdPairs after = Ids(testing::SelfClashPairs(**now, o));
    IdPairs added, resolved;
    ClashStats stats;
    ClashStats full;
    ASSERT_TRUE((*now)->SelfClash(o, nullptr, &full).ok());
    const Status st = ClashSince(
        **now, **then, o,
        [&](const ClashPair& p, ClashChange c) {
          (c == ClashChange::kNew ? added : resolved).insert({p.a, p.b});
        },
        &stats);
    ASSERT_TRUE(st.ok()) << st.ToString();
    IdPairs rebuilt = before;
    for (const auto& p : resolved) {
      EXPECT_TRUE(before.count(p)) << "resolved pair that did not clash before";
      rebuilt.erase(p);
    }
    for (const auto& p : added) {
      EXPECT_FALSE(before.count(p)) << "new pair that clashed before";
      rebuilt.insert(p);
    }
    EXPECT_EQ(rebuilt, after) << "round " << round;
    EXPECT_GT(added.size() + resolved.size(), 0u);
    // The cost is the changed objects': fewer leaf pairs than one full self-clash.
    EXPECT_LT(stats.leaf_pairs_visited, full.leaf_pairs_visited);
  }
}

TEST_P(ClashSinceTest, RefusesANewerOrForeignRevision) {
  testing::TempDir dir("mktree_since");
  std::vector<SceneObject> scene = testing::ClusteredScene(50, 2);
  const std::string a = dir.file("a.mkt"), b = dir.file("b.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, a, testing::SmallPages(GetParam())).ok());
  ASSERT_TRUE(testing::BuildFromObjects(scene, b, testing::SmallPages(GetParam())).ok());
  for (const std::string& s : {a, b}) {
    auto w = ChangeWriter::Open(s);
    ASSERT_TRUE(w.ok());
    ChangeBatch batch;
    batch.remove = {3};
    ASSERT_TRUE((*w)->Commit(batch).ok());
  }
  auto a0 = Database::Open(a, {.revision = 0});
  auto a1 = Database::Open(a);
  auto b0 = Database::Open(b, {.revision = 0});
  ASSERT_TRUE(a0.ok() && a1.ok() && b0.ok());
  EXPECT_FALSE(ClashSince(**a0, **a1, {}, nullptr, nullptr).ok());
  EXPECT_FALSE(ClashSince(**a1, **b0, {}, nullptr, nullptr).ok());
}

INSTANTIATE_TEST_SUITE_P(Backends, ClashSinceTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
