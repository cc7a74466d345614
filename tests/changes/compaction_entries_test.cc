// The parts of a changed store share the base's dictionary (IngestOptions::dictionary), and a compaction
// copies their leaf entries (IngestOptions::copy_stored_entries): every live object comes out byte for
// byte as its part held it but for its id, under the same dictionary; every live object's geometry and
// record are what the revision before gave.
#include <gtest/gtest.h>

#include <map>

#include "change_fixtures.h"
#include "engine/changes/part_builder.h"
#include "engine/query/revision_database.h"
#include "engine/revision/change_folder.h"
#include "engine/store_format/leaf_reader.h"

namespace mktree {
namespace {

// Every live object's entry in part `p` (global id -> entry bytes with the id field zeroed), and how many
// were encoded with the store's dictionary.
void LiveEntries(const RevisionPartDb& p, std::map<ObjectId, std::vector<uint8_t>>* out, size_t* with_dict) {
  for (uint32_t leaf = 0; leaf < p.db->reader().tree().leaves.size(); ++leaf) {
    auto pinned = p.db->leaves().Read(leaf, nullptr);
    ASSERT_TRUE(pinned.ok()) << pinned.status().ToString();
    for (const ObjectEntryView& e : pinned->view.entries()) {
      if (p.hidden[e.id]) continue;
      const uint8_t* begin = e.geometry.data() - kObjectEntryHeaderBytes;
      std::vector<uint8_t> bytes(begin, begin + e.entry_bytes());
      std::fill(bytes.begin(), bytes.begin() + 4, 0);
      (*out)[p.global(e.id)] = std::move(bytes);
      if (e.codec == Codec::kZstdDict) ++*with_dict;
    }
  }
}

// Every live object's geometry and record at revision `then` and at the newest are the same.
void ExpectSameObjects(const std::string& store, uint64_t then, const testing::LiveSet& live) {
  auto db_then = Database::Open(store, {.revision = then});
  auto db_now = Database::Open(store);
  ASSERT_TRUE(db_then.ok() && db_now.ok());
  for (const auto& [id, o] : live) {
    auto a = (*db_then)->ObjectGeometry(id);
    auto b = (*db_now)->ObjectGeometry(id);
    ASSERT_TRUE(a.ok() && b.ok()) << "object " << id;
    EXPECT_EQ(a->vertices, b->vertices) << "object " << id;
    EXPECT_EQ(a->triangles, b->triangles) << "object " << id;
    auto ra = (*db_then)->Object(id);
    auto rb = (*db_now)->Object(id);
    ASSERT_TRUE(ra.ok() && rb.ok()) << "object " << id;
    EXPECT_EQ(ra->name, rb->name);
    EXPECT_EQ(ra->attributes, rb->attributes);
  }
}

class CompactionEntries : public ::testing::TestWithParam<Backend> {};

TEST_P(CompactionEntries, EveryPartSharesTheBaseDictionaryAndItsEntriesAreCopied) {
  testing::TempDir dir("mktree_compaction_entries");
  std::mt19937_64 rng(61);
  const std::vector<SceneObject> scene = testing::ClusteredScene(1500, 4);
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(GetParam())).ok());
  testing::LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  uint64_t before = 0;
  {
    auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    uint64_t counter = 0;
    for (size_t n : {90, 60}) {
      const ChangeBatch batch = testing::RandomBatch(live, n, rng, &counter);
      auto done = (*w)->Commit(batch);
      ASSERT_TRUE(done.ok()) << done.status().ToString();
      testing::Apply(batch, *done, &live);
      before = done->revision;
    }
    auto c = (*w)->Compact();
    ASSERT_TRUE(c.ok()) << c.status().ToString();
  }
  auto then = OpenStoreRevision(store, before);
  auto now = OpenStoreRevision(store, std::nullopt);
  ASSERT_TRUE(then.ok() && now.ok());
  auto old_parts = OpenRevisionParts(store, then->hold->manifest(), {});
  auto new_parts = OpenRevisionParts(store, now->hold->manifest(), {});
  ASSERT_TRUE(old_parts.ok()) << old_parts.status().ToString();
  ASSERT_TRUE(new_parts.ok()) << new_parts.status().ToString();
  ASSERT_EQ(new_parts->size(), 1u);
  ASSERT_GE(old_parts->size(), 2u);

  const auto& old_dict = (*old_parts)[0].db->reader().options().codec.dictionary;
  const auto& new_dict = (*new_parts)[0].db->reader().options().codec.dictionary;
  ASSERT_TRUE(old_dict) << "the scene is too small to train a dictionary on: the test checks nothing";
  ASSERT_TRUE(new_dict);
  EXPECT_EQ(old_dict->bytes(), new_dict->bytes());
  for (size_t p = 1; p < old_parts->size(); ++p) {  // the deltas: encoded with the base's dictionary
    const auto& d = (*old_parts)[p].db->reader().options().codec.dictionary;
    ASSERT_TRUE(d) << "part " << p;
    EXPECT_EQ(d->bytes(), old_dict->bytes()) << "part " << p;
  }

  std::map<ObjectId, std::vector<uint8_t>> before_compaction, compacted;
  size_t old_with_dict = 0, new_with_dict = 0, in_base = 0;
  for (const RevisionPartDb& p : *old_parts) {
    LiveEntries(p, &before_compaction, &old_with_dict);
    if (p.base) in_base = before_compaction.size();
  }
  LiveEntries((*new_parts)[0], &compacted, &new_with_dict);
  ASSERT_EQ(compacted.size(), live.size());
  ASSERT_EQ(before_compaction.size(), live.size());
  ASSERT_GT(in_base, 1000u);
  ASSERT_LT(in_base, live.size());  // some objects came from deltas
  EXPECT_EQ(new_with_dict, old_with_dict);
  EXPECT_GT(new_with_dict, live.size() / 2);
  for (const auto& [id, bytes] : before_compaction) {
    auto it = compacted.find(id);
    ASSERT_NE(it, compacted.end()) << "object " << id;
    EXPECT_EQ(it->second, bytes) << "object " << id << ": its entry was not copied as its part held it";
  }

  ExpectSameObjects(store, before, live);
}

// An entry the target store cannot hold as it is (under a dictionary it does not have: a delta of a store
// changed before parts shared their base's dictionary) is decoded and encoded again; the others are
// copied; the part built from both gives every object's geometry and record.
TEST_P(CompactionEntries, AnEntryUnderAnotherDictionaryIsDecodedTheOthersCopied) {
  testing::TempDir dir("mktree_compaction_entries");
  std::mt19937_64 rng(62);
  std::vector<SceneObject> scene = testing::ClusteredScene(1500, 5);
  // Single triangles of random corners: too small for zstd to shrink, stored raw (codec none).
  std::uniform_real_distribution<double> corner(-20, 20);
  for (int i = 0; i < 40; ++i) {
    SceneObject o;
    o.id = static_cast<ObjectId>(scene.size());
    o.name = "triangle_" + std::to_string(i);
    for (int v = 0; v < 9; ++v) o.mesh.vertices.push_back(corner(rng));
    o.mesh.triangles = {0, 1, 2};
    scene.push_back(std::move(o));
  }
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(GetParam())).ok());
  testing::LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  {
    auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    uint64_t counter = 0;
    const ChangeBatch batch = testing::RandomBatch(live, 120, rng, &counter);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    testing::Apply(batch, *done, &live);
  }
  auto at = OpenStoreRevision(store, std::nullopt);
  ASSERT_TRUE(at.ok());
  auto parts = OpenRevisionParts(store, at->hold->manifest(), {});
  ASSERT_TRUE(parts.ok()) << parts.status().ToString();
  ASSERT_EQ(parts->size(), 2u);
  const StoreDatabase& base = *(*parts)[0].db;
  ASSERT_TRUE(base.reader().options().codec.dictionary);

  // A target with no dictionary: entries compressed with the base's must be decoded.
  std::vector<const RevisionPartDb*> all{&(*parts)[0], &(*parts)[1]};
  LiveObjectStream stream(all, 1, dir.path().string());
  stream.CopyEntriesFor(nullptr, base.reader().tree().origin);
  size_t copied = 0, decoded = 0;
  IdOrderedObjects next = [&](SceneObject* out) -> Result<bool> {
    MKTREE_ASSIGN_OR_RETURN(const bool more, stream.Next(out));
    if (!more) return false;
    if (!out->stored_entry.empty()) {
      ++copied;
      EXPECT_NE(out->stored_entry[28], static_cast<uint8_t>(Codec::kZstdDict)) << "object " << out->id;
      EXPECT_TRUE(out->mesh.vertices.empty());
    } else {
      ++decoded;
      EXPECT_FALSE(out->mesh.vertices.empty()) << "object " << out->id;
    }
    return true;
  };
  PartBuild b;
  b.folder = dir.path().string();
  b.name = "mixed";
  b.history = 1;
  b.ingest = PartIngestOptions(base, 1);
  b.ingest.dictionary = std::shared_ptr<const CodecDictionary>();
  b.ingest.copy_stored_entries = true;
  auto built = BuildRevisionPart(b, next);
  ASSERT_TRUE(built.ok()) << built.status().ToString();
  EXPECT_GT(decoded, 1000u);  // the base's entries under its dictionary
  EXPECT_GT(copied, 0u);      // entries zstd could not shrink, stored raw, and the like
  ASSERT_EQ(copied + decoded, live.size());

  auto mixed = Database::Open(ChangesFile(b.folder, "mixed.mkt"));
  auto now = Database::Open(store);
  ASSERT_TRUE(mixed.ok() && now.ok());
  ASSERT_EQ((*mixed)->object_count(), live.size());
  ObjectId local = 0;
  for (const auto& [id, o] : live) {  // the part numbers the live objects in increasing global id
    auto a = (*now)->ObjectGeometry(id);
    auto m = (*mixed)->ObjectGeometry(local);
    ASSERT_TRUE(a.ok() && m.ok()) << "object " << id;
    EXPECT_EQ(a->vertices, m->vertices) << "object " << id;
    EXPECT_EQ(a->triangles, m->triangles) << "object " << id;
    auto ra = (*now)->Object(id);
    auto rm = (*mixed)->Object(local);
    ASSERT_TRUE(ra.ok() && rm.ok());
    EXPECT_EQ(ra->name, rm->name);
    ++local;
  }
}

// A sharded store: its build gives every shard shard 0's dictionary, every delta and every compaction's
// shard takes it too, so that each compaction copies every live entry.
TEST_P(CompactionEntries, ShardsShareShardZerosDictionaryAndTheNextCompactionCopiesEveryEntry) {
  testing::TempDir dir("mktree_compaction_entries");
  std::mt19937_64 rng(63);
  const std::vector<SceneObject> scene = testing::ClusteredScene(3000, 6);
  const std::string store = dir.file("s.mkts");
  ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, testing::SmallPages(GetParam()), 3).ok());
  testing::LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0;
  std::vector<uint8_t> shard0_dictionary;
  uint64_t before = 0;
  for (int round = 0; round < 2; ++round) {
    const ChangeBatch batch = testing::RandomBatch(live, 150, rng, &counter);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    testing::Apply(batch, *done, &live);
    before = done->revision;
    auto then = OpenStoreRevision(store, before);
    ASSERT_TRUE(then.ok());
    auto old_parts = OpenRevisionParts(store, then->hold->manifest(), {});
    ASSERT_TRUE(old_parts.ok()) << old_parts.status().ToString();
    ASSERT_GE(then->hold->manifest().deltas.size(), 1u);
    ASSERT_EQ(old_parts->size(), 3u + then->hold->manifest().deltas.size());  // three shards, the deltas
    const auto& d0 = (*old_parts)[0].db->reader().options().codec.dictionary;
    ASSERT_TRUE(d0);
    if (round == 0) shard0_dictionary = d0->bytes();
    for (const RevisionPartDb& p : *old_parts) {
      const auto& d = p.db->reader().options().codec.dictionary;
      ASSERT_TRUE(d);
      EXPECT_EQ(d->bytes(), shard0_dictionary) << "round " << round << ", part " << p.index;
    }

    auto c = (*w)->Compact();
    ASSERT_TRUE(c.ok()) << c.status().ToString();
    auto now = OpenStoreRevision(store, std::nullopt);
    ASSERT_TRUE(now.ok());
    auto new_parts = OpenRevisionParts(store, now->hold->manifest(), {});
    ASSERT_TRUE(new_parts.ok()) << new_parts.status().ToString();
    ASSERT_EQ(new_parts->size(), 3u);
    std::map<ObjectId, std::vector<uint8_t>> before_compaction, compacted;
    size_t old_with_dict = 0, new_with_dict = 0;
    for (const RevisionPartDb& p : *old_parts) LiveEntries(p, &before_compaction, &old_with_dict);
    for (const RevisionPartDb& p : *new_parts) {
      const auto& d = p.db->reader().options().codec.dictionary;
      ASSERT_TRUE(d);
      EXPECT_EQ(d->bytes(), shard0_dictionary) << "round " << round;
      LiveEntries(p, &compacted, &new_with_dict);
    }
    ASSERT_EQ(compacted.size(), live.size());
    ASSERT_EQ(before_compaction.size(), live.size());
    size_t same = 0;
    for (const auto& [id, bytes] : before_compaction) same += compacted.at(id) == bytes;
    EXPECT_EQ(same, live.size()) << "round " << round
                                 << ": every entry shares the dictionary, each is copied";

    ExpectSameObjects(store, before, live);
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, CompactionEntries, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
