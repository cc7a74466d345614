// A sharded store routes each change to the shard that owns its box (docs/changes.md, "Sharded stores"):
// every object a delta answers for routes to the delta's shard through the base's top levels, a shard's
// deltas merge only with each other, an object replaced into another shard's region moves to that shard's
// delta, and every query still equals brute force. The revision file says each delta's shard (format 2)
// and a reader refuses a shard the base does not have.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "change_fixtures.h"
#include "engine/query/revision_database.h"
#include "engine/revision/change_folder.h"
#include "engine/revision/revision_manifest.h"
#include "engine/shard/manifest.h"

namespace mktree {
namespace {

class RoutedDeltas : public ::testing::TestWithParam<Backend> {};

// Every live object of every delta of the store's newest revision routes to the delta's shard by the box
// it has in `live`; a shard's deltas are ordered by size as merging leaves them. Returns the shards that
// have deltas.
std::set<uint32_t> ExpectRouted(const std::string& store, const testing::LiveSet& live,
                                const std::string& what) {
  std::set<uint32_t> shards;
  auto at = OpenStoreRevision(store, std::nullopt);
  EXPECT_TRUE(at.ok() && at->hold) << what << ": " << at.status().ToString();
  if (!at.ok() || !at->hold) return shards;
  const RevisionManifest& m = at->hold->manifest();
  auto base = ReadManifest(ChangesFile(ChangesFolder(store), m.base.store.name));
  EXPECT_TRUE(base.ok()) << what << ": " << base.status().ToString();
  if (!base.ok()) return shards;
  auto parts = OpenRevisionParts(store, m, {});
  EXPECT_TRUE(parts.ok()) << what << ": " << parts.status().ToString();
  if (!parts.ok()) return shards;
  const size_t first = BasePartCount(*parts);
  EXPECT_EQ(first, base->shards.size()) << what;
  std::map<uint32_t, uint64_t> newest_size;  // of the shard's newest delta seen so far (oldest first)
  for (size_t d = 0; d < m.deltas.size(); ++d) {
    const RevisionPart& delta = m.deltas[d];
    EXPECT_LT(delta.shard, base->shards.size()) << what << ": delta " << delta.store.name;
    shards.insert(delta.shard);
    if (auto it = newest_size.find(delta.shard); it != newest_size.end()) {
      EXPECT_GT(it->second, 2 * delta.objects) << what << ": shard " << delta.shard << "'s deltas not merged";
    }
    newest_size[delta.shard] = delta.objects;
    const RevisionPartDb& p = (*parts)[first + d];
    for (ObjectId local = 0; local < p.ids.size(); ++local) {
      if (p.hidden_count && p.hidden[local]) continue;
      const ObjectId id = p.ids[local];
      auto it = live.find(id);
      EXPECT_NE(it, live.end()) << what << ": delta " << delta.store.name << " answers for id " << id;
      if (it == live.end()) continue;
      EXPECT_EQ(base->top.ShardOf(it->second.mesh.Bounds()), delta.shard)
          << what << ": object " << id << " in delta " << delta.store.name;
    }
  }
  return shards;
}

TEST_P(RoutedDeltas, EveryChangeGoesToTheShardThatOwnsItsBox) {
  testing::TempDir dir("mktree_routed_deltas");
  std::mt19937_64 rng(77);
  const std::vector<SceneObject> scene = testing::ClusteredScene(360, 12);
  const std::string store = dir.file("s.mkts");
  const IngestOptions opts = testing::SmallPages(GetParam());
  ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, opts, 4).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  testing::LiveSet live = testing::LiveOf(scene);
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0;
  std::set<uint32_t> shards_seen;
  const size_t sizes[] = {1, 40, 0, 9, 60, 2, 25};
  for (int step = 0; step < 14; ++step) {
    const std::string what = "step " + std::to_string(step);
    const ChangeBatch batch = testing::RandomBatch(live, sizes[step % 7], rng, &counter);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    testing::Apply(batch, *done, &live);
    const std::set<uint32_t> shards = ExpectRouted(store, live, what);
    shards_seen.insert(shards.begin(), shards.end());
    auto db = Database::Open(store, {.cache_pages = step % 2 ? 0u : 64u});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(25, rng), what);
    if (step == 7) {
      testing::ExpectClashOfFreshBuild(**db, live, opts, origin, dir.path().string());
      auto c = (*w)->Compact();
      ASSERT_TRUE(c.ok()) << c.status().ToString();
      EXPECT_TRUE(ExpectRouted(store, live, "after the compaction").empty());
    }
  }
  EXPECT_GE(shards_seen.size(), 3u) << "the random batches should reach most of the 4 shards";
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok());
  testing::ExpectClashOfFreshBuild(**db, live, opts, origin, dir.path().string());
}

// Replacing an object with one in another shard's region moves it: its old copy is hidden in its base
// shard, the new one lives in the other shard's delta; moving it back moves it again.
TEST_P(RoutedDeltas, AReplaceIntoAnotherShardsRegionMovesTheObject) {
  testing::TempDir dir("mktree_routed_deltas");
  std::mt19937_64 rng(3);
  const std::vector<SceneObject> scene = testing::ClusteredScene(200, 31);
  const std::string store = dir.file("s.mkts");
  ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, testing::SmallPages(GetParam()), 3).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  auto built = ReadManifest(store);
  ASSERT_TRUE(built.ok()) << built.status().ToString();
  const TopLevels& top = built->top;
  // Two objects of different shards; the first is replaced by a copy of the second, shifted a hair.
  ObjectId a = 0, b = 0;
  for (; b < scene.size(); ++b)
    if (top.ShardOf(scene[b].mesh.Bounds()) != top.ShardOf(scene[a].mesh.Bounds())) break;
  ASSERT_LT(b, scene.size());
  testing::LiveSet live = testing::LiveOf(scene);
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  for (int round = 0; round < 2; ++round) {
    SceneObject moved = round == 0 ? scene[b] : scene[a];
    for (double& v : moved.mesh.vertices) v += 1e-3;
    moved.id = a;
    moved.name = "moved_" + std::to_string(round);
    ChangeBatch batch;
    batch.replace.push_back(moved);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    testing::Apply(batch, *done, &live);
    const std::set<uint32_t> shards = ExpectRouted(store, live, "round " + std::to_string(round));
    EXPECT_TRUE(shards.count(top.ShardOf(moved.mesh.Bounds()))) << "round " << round;
    auto db = Database::Open(store);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(25, rng),
                           "round " + std::to_string(round));
    auto record = (*db)->Object(a);
    ASSERT_TRUE(record.ok()) << record.status().ToString();
    EXPECT_EQ(record->name, moved.name);
  }
}

// Hundreds of small batches on a sharded store (objects moving across shards, an automatic compaction now
// and then): merges of every size within each shard, each revision checked against brute force and for
// its routing.
TEST_P(RoutedDeltas, HundredsOfSmallBatchesMergeWithinTheirShards) {
  testing::TempDir dir("mktree_routed_deltas");
  std::mt19937_64 rng(911);
  const std::vector<SceneObject> scene = testing::ClusteredScene(240, 19);
  const std::string store = dir.file("s.mkts");
  ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, testing::SmallPages(GetParam()), 3).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  testing::LiveSet live = testing::LiveOf(scene);
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0.6, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0, compactions = 0;
  size_t most_deltas = 0;
  for (int step = 0; step < 200; ++step) {
    const std::string what = "step " + std::to_string(step);
    const ChangeBatch batch = testing::RandomBatch(live, 1 + rng() % 8, rng, &counter);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    ASSERT_EQ(done->compaction_error, "");
    compactions += done->compacted;
    testing::Apply(batch, *done, &live);
    if (step % 5 == 0) ExpectRouted(store, live, what);
    auto db = Database::Open(store, {.cache_pages = 16});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(6, rng), what);
    const RevisionManifest* m = RevisionManifestOf(**db);
    ASSERT_NE(m, nullptr);
    most_deltas = std::max(most_deltas, m->deltas.size());
  }
  EXPECT_GE(compactions, 1u);
  EXPECT_GE(most_deltas, 6u) << "several deltas a shard, so that merges ran within shards";
}

INSTANTIATE_TEST_SUITE_P(Backends, RoutedDeltas, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A revision with no routed delta is written in format 1, as before routing; one with a routed delta in
// format 2, each delta line ending in its shard ("-": unrouted). Both decode to what was encoded.
TEST(RoutedDeltasFile, FormatOneUnlessADeltaIsRoutedAndTheShardRoundTrips) {
  RevisionManifest m;
  m.history = 0x1234;
  m.revision = 3;
  m.base.store = {"base-0.mkt", 100, 7};
  m.base.objects = 10;
  RevisionPart d;
  d.made_at = 2;
  d.store = {"delta-2-1.mkt", 50, 8};
  d.ids = {"delta-2-1.ids", 20, 9};
  d.objects = 2;
  m.deltas.push_back(d);
  const std::string one = EncodeRevisionManifest(m);
  EXPECT_EQ(one.substr(0, one.find('\n')).back(), '1') << one;
  m.deltas.push_back(d);
  m.deltas.back().store.name = "delta-3-2.mkt";
  m.deltas.back().shard = 5;
  const std::string two = EncodeRevisionManifest(m);
  EXPECT_EQ(two.substr(0, two.find('\n')).back(), '2') << two;
  EXPECT_NE(two.find(" 2 -\n"), std::string::npos) << two;  // the unrouted delta: objects, then "-"
  EXPECT_NE(two.find(" 2 5\n"), std::string::npos) << two;
  for (const std::string& text : {one, two}) {
    auto back = DecodeRevisionManifest(text, "rev.rev");
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    EXPECT_EQ(EncodeRevisionManifest(*back), text);
  }
  auto back = DecodeRevisionManifest(two, "rev.rev");
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->deltas[0].shard, kNoShard);
  EXPECT_EQ(back->deltas[1].shard, 5u);
  // Format 1 has no shard field, format 2 needs it, format 3 is not read.
  std::string bad = one;
  bad.replace(bad.find(" 1\n"), 3, " 2\n");
  auto refused = DecodeRevisionManifest(bad, "rev.rev");
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("rev.rev line "), std::string::npos)
      << refused.status().ToString();
  bad = one;
  bad.replace(bad.find(" 1\n"), 3, " 3\n");
  refused = DecodeRevisionManifest(bad, "rev.rev");
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("rev.rev line 1: revision format 3"), std::string::npos)
      << refused.status().ToString();
}

// A revision file that routes a delta to a shard its base has not (damaged, or of another store) is
// refused by readers and writers, naming the revision file; a store file's delta routed anywhere likewise.
TEST(RoutedDeltasFile, AShardTheBaseHasNotIsRefusedNamingTheRevisionFile) {
  testing::TempDir dir("mktree_routed_deltas");
  std::mt19937_64 rng(9);
  const std::vector<SceneObject> scene = testing::ClusteredScene(120, 5);
  for (const bool sharded : {true, false}) {
    const std::string store = dir.file(sharded ? "s.mkts" : "s.mkt");
    const IngestOptions opts = testing::SmallPages(Backend::kPagedFile);
    if (sharded)
      ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, opts, 3).ok());
    else
      ASSERT_TRUE(testing::BuildFromObjects(scene, store, opts).ok());
    testing::LiveSet live;
    for (const SceneObject& o : scene) live[o.id] = o;
    uint64_t revision = 0;
    {
      auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
      ASSERT_TRUE(w.ok()) << w.status().ToString();
      uint64_t counter = 0;
      auto done = (*w)->Commit(testing::RandomBatch(live, 12, rng, &counter));
      ASSERT_TRUE(done.ok()) << done.status().ToString();
      revision = done->revision;
    }
    const std::string file = ChangesFile(ChangesFolder(store), RevisionFileName(revision));
    auto m = DecodeRevisionManifest(ReadText(file), file);
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    ASSERT_FALSE(m->deltas.empty());
    for (const RevisionPart& d : m->deltas) EXPECT_EQ(d.shard == kNoShard, !sharded) << d.store.name;
    m->deltas.back().shard = 7;
    {
      std::ofstream out(file, std::ios::binary | std::ios::trunc);
      out << EncodeRevisionManifest(*m);
    }
    auto db = Database::Open(store);
    ASSERT_FALSE(db.ok()) << (sharded ? "sharded" : "store file");
    EXPECT_EQ(db.status().code(), Status::Code::kCorruption) << db.status().ToString();
    EXPECT_NE(db.status().message().find(file), std::string::npos) << db.status().ToString();
    EXPECT_NE(db.status().message().find("routed to shard 7"), std::string::npos) << db.status().ToString();
    auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
    ASSERT_FALSE(w.ok());
    EXPECT_NE(w.status().message().find("routed to shard 7"), std::string::npos) << w.status().ToString();
  }
}

}  // namespace
}  // namespace mktree
