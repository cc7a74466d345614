// OpenRevisionParts with the parts to open chosen (mktree-mpi's ranks each open some, tools/mpi/mpi_parts.h):
// every part opened gives what it gives when all are open (ids, hidden marks), a delta left closed still
// hides what the parts before it hold, and the parts of any split of the indices over ranks hold the
// revision's live objects once.
#include <gtest/gtest.h>

#include "change_fixtures.h"
#include "engine/query/revision_database.h"
#include "engine/revision/change_folder.h"

namespace mktree {
namespace {

TEST(RevisionPartsChosen, EachOpenedPartIsAsWhenAllAreOpen) {
  testing::TempDir dir("mktree_revision_parts");
  std::mt19937_64 rng(52);
  const std::vector<SceneObject> scene = testing::ClusteredScene(300, 8);
  const std::string store = dir.file("s.mkts");
  ASSERT_TRUE(
      testing::BuildShardedFromObjects(scene, store, testing::SmallPages(Backend::kPagedFile), 3).ok());
  testing::LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  {
    auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    uint64_t counter = 0;
    for (size_t n : {40, 25, 0, 30}) {  // adds, removes and replaces, of base objects and delta objects
      const ChangeBatch batch = testing::RandomBatch(live, n, rng, &counter);
      auto done = (*w)->Commit(batch);
      ASSERT_TRUE(done.ok()) << done.status().ToString();
      testing::Apply(batch, *done, &live);
    }
  }
  auto at = OpenStoreRevision(store, std::nullopt);
  ASSERT_TRUE(at.ok()) << at.status().ToString();
  ASSERT_TRUE(at->hold);
  const RevisionManifest& m = at->hold->manifest();
  ASSERT_EQ(m.live, live.size());
  auto all = OpenRevisionParts(store, m, {});
  ASSERT_TRUE(all.ok()) << all.status().ToString();
  const size_t count = RevisionPartCount(m, 3);
  ASSERT_EQ(all->size(), count);
  ASSERT_GE(m.deltas.size(), 2u);  // a closed delta between two parts
  for (size_t i = 0; i < count; ++i) ASSERT_EQ((*all)[i].index, i);

  // The live objects of the parts `open` chooses; failures are EXPECTs (a lambda cannot ASSERT a value).
  auto check = [&](const std::vector<uint8_t>& open, const std::string& what) -> uint64_t {
    auto some = OpenRevisionParts(store, m, {}, nullptr, true, &open);
    EXPECT_TRUE(some.ok()) << what << ": " << some.status().ToString();
    if (!some.ok()) return 0;
    size_t opened = 0;
    for (uint8_t o : open) opened += o;
    EXPECT_EQ(some->size(), opened) << what;
    uint64_t live_here = 0;
    for (const RevisionPartDb& p : *some) {
      const bool known = p.index < count && open[p.index];
      EXPECT_TRUE(known) << what << ": part " << p.index << " was not chosen";
      if (!known) continue;
      const RevisionPartDb& full = (*all)[p.index];
      EXPECT_EQ(p.base, full.base) << what;
      EXPECT_EQ(p.ids, full.ids) << what << ", part " << p.index;
      EXPECT_EQ(p.hidden, full.hidden) << what << ", part " << p.index;
      EXPECT_EQ(p.hidden_count, full.hidden_count) << what << ", part " << p.index;
      live_here += p.db->object_count() - p.hidden_count;
    }
    return live_here;
  };
  for (int ranks = 1; ranks <= 4; ++ranks) {
    uint64_t sum = 0;
    for (int r = 0; r < ranks; ++r) {
      std::vector<uint8_t> open(count, 0);
      for (size_t i = 0; i < count; ++i) open[i] = static_cast<int>(i % ranks) == r;
      sum += check(open, std::to_string(ranks) + " ranks, rank " + std::to_string(r));
    }
    EXPECT_EQ(sum, m.live) << ranks << " ranks";
  }
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<uint8_t> open(count);
    for (uint8_t& o : open) o = rng() % 2;
    check(open, "random choice " + std::to_string(trial));
  }
  // Only the oldest shard: every delta closed, their id files still read.
  std::vector<uint8_t> first(count, 0);
  first[0] = 1;
  check(first, "shard 0 alone");
  const std::vector<uint8_t> wrong(count + 1, 1);
  auto refused = OpenRevisionParts(store, m, {}, nullptr, true, &wrong);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), Status::Code::kInvalidArgument) << refused.status().ToString();
}

}  // namespace
}  // namespace mktree
