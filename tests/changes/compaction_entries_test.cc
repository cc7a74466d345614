// A compaction copies the base's leaf entries (IngestOptions::stored_entries): every base object still
// live comes out byte for byte as the base held it but for its id, under the base's dictionary, which the
// changed objects are encoded with too; every live object's geometry is what the revision before gave.
#include <gtest/gtest.h>

#include <map>

#include "change_fixtures.h"
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

class CompactionEntries : public ::testing::TestWithParam<Backend> {};

TEST_P(CompactionEntries, BaseEntriesAreCopiedAndChangesShareItsDictionary) {
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

  std::map<ObjectId, std::vector<uint8_t>> old_base, compacted;
  size_t old_with_dict = 0, new_with_dict = 0;
  LiveEntries((*old_parts)[0], &old_base, &old_with_dict);
  LiveEntries((*new_parts)[0], &compacted, &new_with_dict);
  ASSERT_EQ(compacted.size(), live.size());
  ASSERT_GT(old_base.size(), 1000u);
  ASSERT_LT(old_base.size(), live.size());  // the changed objects came from deltas
  for (const auto& [id, bytes] : old_base) {
    auto it = compacted.find(id);
    ASSERT_NE(it, compacted.end()) << "object " << id;
    EXPECT_EQ(it->second, bytes) << "object " << id << ": its entry was not copied as the base held it";
  }
  // The deltas' objects were encoded again, with the base's dictionary (the deltas had their own).
  EXPECT_GT(new_with_dict, old_with_dict);

  auto db_then = Database::Open(store, {.revision = before});
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

INSTANTIATE_TEST_SUITE_P(Backends, CompactionEntries, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
