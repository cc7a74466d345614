// A sharded store takes changes as a store file does (docs/changes.md, "Sharded stores"): after every batch
// and after compaction, every query kind, the objects' records and the self-clash equal brute force over
// the live set; a compaction is a sharded build of the live objects, ids kept; older revisions keep
// answering; one writer at a time, and no sharded build of the path while it writes.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "change_fixtures.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;
using testing::LiveSet;

class ShardedChanges : public ::testing::TestWithParam<Backend> {};

// The number of stores a revision of `db` answers from (its stats_json "parts").
size_t PartCount(const Database& db) {
  const std::string s = db.stats_json();
  size_t n = 0;
  for (size_t at = s.find("\"leaves\""); at != std::string::npos; at = s.find("\"leaves\"", at + 1)) ++n;
  return n;
}

// The files beside the store named "<store>.shard-...".
std::set<std::string> ShardFilesBeside(const std::string& store) {
  std::set<std::string> out;
  const std::string stem = fs::path(store).filename().string() + ".shard-";
  for (const auto& e : fs::directory_iterator(fs::path(store).parent_path()))
    if (e.path().filename().string().rfind(stem, 0) == 0) out.insert(e.path().filename().string());
  return out;
}

TEST_P(ShardedChanges, EveryBatchAndEveryCompactionAnswersAsBruteForce) {
  testing::TempDir dir("mktree_sharded_changes");
  std::mt19937_64 rng(138);
  const std::vector<SceneObject> scene = testing::ClusteredScene(400, 21);
  const std::string store = dir.file("s.mkts");
  const IngestOptions opts = testing::SmallPages(GetParam());
  ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, opts, 3).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  ASSERT_EQ(ShardFilesBeside(store).size(), 6u);

  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0;
  const size_t sizes[] = {1, 30, 0, 7, 90, 3};
  uint64_t compactions = 0, revision_before_compaction = 0;
  for (int step = 0; step < 18; ++step) {
    const ChangeBatch batch = testing::RandomBatch(live, sizes[step % 6], rng, &counter);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    testing::Apply(batch, *done, &live);
    ASSERT_EQ(done->objects, live.size());
    if (step % 6 == 5) {
      revision_before_compaction = done->revision;
      auto c = (*w)->Compact();
      ASSERT_TRUE(c.ok()) << c.status().ToString();
      ASSERT_GT(c->folded, 0u);
      ++compactions;
      // The build's shard files beside the manifest went with the first compaction.
      EXPECT_EQ(ShardFilesBeside(store), std::set<std::string>{});
    }
    auto db = Database::Open(store, {.cache_pages = step % 2 ? 0u : 64u});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(30, rng),
                           "step " + std::to_string(step));
    if (step % 6 == 5) {  // a sharded base of 3 shards, no delta
      EXPECT_EQ(PartCount(**db), 3u) << (*db)->stats_json();
      EXPECT_NE((*db)->stats_json().find("\"deltas\": 0,"), std::string::npos) << (*db)->stats_json();
    }
    if (step % 6 == 2) testing::ExpectClashOfFreshBuild(**db, live, opts, origin, dir.path().string());
  }
  EXPECT_EQ(compactions, 3u);
  // Older revisions answer as they did: the built store, and the one before the last compaction.
  auto zero = Database::Open(store, {.revision = 0});
  ASSERT_FALSE(zero.ok());  // retired: 8 revisions are kept and 21 were written
  auto before = Database::Open(store, {.revision = revision_before_compaction});
  ASSERT_TRUE(before.ok()) << before.status().ToString();
  testing::ExpectAnswers(**before, live, origin, testing::RandomQueries(30, rng), "before the compaction");
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok());
  testing::ExpectClashOfFreshBuild(**db, live, opts, origin, dir.path().string());
}

// Revision 0 of a sharded store, the store as built, answers after a compaction has replaced its manifest
// and its shard files beside it; removing all but a few objects compacts into fewer shards.
TEST_P(ShardedChanges, TheBuiltRevisionOutlivesItsFilesAndFewObjectsTakeFewerShards) {
  testing::TempDir dir("mktree_sharded_changes");
  std::mt19937_64 rng(5);
  const std::vector<SceneObject> scene = testing::ClusteredScene(120, 4);
  const std::string store = dir.file("s.mkts");
  ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, testing::SmallPages(GetParam()), 4).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  LiveSet built;
  for (const SceneObject& o : scene) built[o.id] = o;
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  ChangeBatch most;
  for (ObjectId id = 0; id < 119; ++id) most.remove.push_back(id);
  auto done = (*w)->Commit(most);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  auto c = (*w)->Compact();
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  LiveSet live{{119, scene[119]}};
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(20, rng), "one object left");
  EXPECT_EQ(PartCount(**db), 1u);  // one shard: a single object gives no other shard an object
  auto zero = Database::Open(store, {.revision = 0});
  ASSERT_TRUE(zero.ok()) << zero.status().ToString();
  testing::ExpectAnswers(**zero, built, origin, testing::RandomQueries(20, rng), "revision 0");
  // Adding again after it: new ids, answered beside the one-shard base.
  ChangeBatch again;
  again.add = testing::ClusteredScene(50, 9);
  done = (*w)->Commit(again);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_EQ(done->added_ids.front(), 120u);
  testing::Apply(again, *done, &live);
  db = Database::Open(store);
  ASSERT_TRUE(db.ok());
  testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(20, rng), "re-added");
}

// One writer: a second one, and a sharded build of the same path, are refused while it is open.
TEST(ShardedChangesLocks, ASecondWriterAndAShardedBuildAreRefused) {
  testing::TempDir dir("mktree_sharded_changes");
  const std::vector<SceneObject> scene = testing::ClusteredScene(60, 2);
  const std::string store = dir.file("s.mkts");
  const IngestOptions opts = testing::SmallPages(Backend::kPagedFile);
  ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, opts, 2).ok());
  auto w = ChangeWriter::Open(store);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  auto second = ChangeWriter::Open(store);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), Status::Code::kIOError) << second.status().ToString();
  const Status rebuild = testing::BuildShardedFromObjects(scene, store, opts, 2);
  ASSERT_FALSE(rebuild.ok());
  EXPECT_NE(rebuild.message().find(store), std::string::npos) << rebuild.ToString();
  ChangeBatch b;
  b.remove = {3};
  ASSERT_TRUE((*w)->Commit(b).ok());
  w->reset();
  // A sharded build over it afterwards makes a new store: the old changes no longer answer.
  ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, opts, 2).ok());
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_EQ((*db)->object_count(), 60u);
  EXPECT_EQ((*db)->revision(), 0u);
}

// Incremental clash on a sharded store: the new and resolved pairs turn the clash at R into the clash now.
TEST(ShardedChangesClash, NewAndResolvedTurnTheOldClashIntoTheNew) {
  testing::TempDir dir("mktree_sharded_changes");
  std::mt19937_64 rng(77);
  const std::vector<SceneObject> scene = testing::ClusteredScene(300, 31);
  const std::string store = dir.file("s.mkts");
  ASSERT_TRUE(
      testing::BuildShardedFromObjects(scene, store, testing::SmallPages(Backend::kPagedFile), 2).ok());
  LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0;
  using PairIds = std::set<std::pair<ObjectId, ObjectId>>;
  auto ids = [](const std::vector<ClashPair>& pairs) {
    PairIds out;
    for (const ClashPair& p : pairs) out.insert({p.a, p.b});
    return out;
  };
  for (int round = 0; round < 2; ++round) {
    auto then = Database::Open(store);
    ASSERT_TRUE(then.ok());
    PairIds want = ids(testing::SelfClashPairs(**then));
    for (int b = 0; b < 2; ++b) {
      const ChangeBatch batch = testing::RandomBatch(live, 15, rng, &counter);
      auto done = (*w)->Commit(batch);
      ASSERT_TRUE(done.ok()) << done.status().ToString();
      testing::Apply(batch, *done, &live);
    }
    if (round == 1) {
      ASSERT_TRUE((*w)->Compact().ok());
    }
    auto now = Database::Open(store);
    ASSERT_TRUE(now.ok());
    uint64_t added = 0;
    const Status st = ClashSince(
        **now, **then, {},
        [&](const ClashPair& p, ClashChange change) {
          if (change == ClashChange::kNew) {
            EXPECT_TRUE(want.insert({p.a, p.b}).second) << p.a << " " << p.b;
            ++added;
          } else {
            EXPECT_EQ(want.erase({p.a, p.b}), 1u) << p.a << " " << p.b;
          }
        },
        nullptr);
    ASSERT_TRUE(st.ok()) << st.ToString();
    EXPECT_EQ(want, ids(testing::SelfClashPairs(**now))) << "round " << round;
    EXPECT_GT(added, 0u);
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, ShardedChanges, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
