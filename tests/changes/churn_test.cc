// Random batches against brute force: after every batch, and after compaction, every query kind, the
// objects' records and the self-clash equal brute force over the live set, on both backends.
#include <gtest/gtest.h>

#include "change_fixtures.h"

namespace mktree {
namespace {

using testing::LiveSet;

class Churn : public ::testing::TestWithParam<Backend> {};

TEST_P(Churn, EveryBatchAnswersAsBruteForceOverTheLiveSet) {
  testing::TempDir dir("mktree_churn");
  std::mt19937_64 rng(38);
  std::vector<SceneObject> scene = testing::ClusteredScene(500, 7);
  const std::string store = dir.file("s.mkt");
  const IngestOptions opts = testing::SmallPages(GetParam());
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, opts).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;

  ChangeOptions co;
  co.compact_threshold = 0;  // compaction on demand only, below
  co.threads = 1;
  auto w = ChangeWriter::Open(store, co);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0;
  const size_t sizes[] = {1, 5, 40, 0, 3, 120, 2, 17};
  for (int step = 0; step < 24; ++step) {
    const ChangeBatch batch = testing::RandomBatch(live, sizes[step % 8], rng, &counter);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    ASSERT_EQ(done->revision, static_cast<uint64_t>(step + 1));
    testing::Apply(batch, *done, &live);
    ASSERT_EQ(done->objects, live.size());
    auto db = Database::Open(store, {.cache_pages = step % 3 == 0 ? 0u : 64u});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    ASSERT_EQ((*db)->revision(), done->revision);
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(30, rng),
                           "step " + std::to_string(step));
    if (step % 8 == 7) testing::ExpectClashOfFreshBuild(**db, live, opts, origin, dir.path().string());
  }
  auto c = (*w)->Compact();
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_GT(c->folded, 0u);
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(60, rng), "after compaction");
  testing::ExpectClashOfFreshBuild(**db, live, opts, origin, dir.path().string());
  // The store file is the compacted base itself: one part.
  EXPECT_EQ((*db)->stats_json().find("\"parts\": [{"), (*db)->stats_json().find("\"parts\": ["));
}

TEST_P(Churn, RemovingEverythingAndAddingAgainKeepsIdsForLife) {
  testing::TempDir dir("mktree_churn");
  std::mt19937_64 rng(5);
  std::vector<SceneObject> scene = testing::ClusteredScene(60, 3);
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(GetParam())).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  ChangeBatch all;
  for (const SceneObject& o : scene) all.remove.push_back(o.id);
  auto done = (*w)->Commit(all);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_EQ(done->objects, 0u);
  LiveSet live;
  {
    auto db = Database::Open(store);
    ASSERT_TRUE(db.ok());
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(10, rng), "empty");
    EXPECT_FALSE((*db)->Object(0).ok());
  }
  ChangeBatch again;
  again.add = testing::ClusteredScene(30, 9);
  done = (*w)->Commit(again);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  ASSERT_EQ(done->added_ids.front(), 60u);  // never an id used before
  testing::Apply(again, *done, &live);
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok());
  testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(30, rng), "re-added");
  EXPECT_EQ((*db)->id_limit(), 90u);
}

TEST_P(Churn, AutomaticCompactionKeepsAnswers) {
  testing::TempDir dir("mktree_churn");
  std::mt19937_64 rng(11);
  std::vector<SceneObject> scene = testing::ClusteredScene(200, 5);
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(GetParam())).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0.2, .threads = 1});
  ASSERT_TRUE(w.ok());
  uint64_t counter = 0, compactions = 0;
  for (int step = 0; step < 10; ++step) {
    const ChangeBatch batch = testing::RandomBatch(live, 15, rng, &counter);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    EXPECT_EQ(done->compaction_error, "");
    compactions += done->compacted;
    testing::Apply(batch, *done, &live);
    auto db = Database::Open(store);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(20, rng),
                           "step " + std::to_string(step));
  }
  EXPECT_GE(compactions, 2u);
}

INSTANTIATE_TEST_SUITE_P(Backends, Churn, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree

namespace mktree {
namespace {

// `mktree build` over a store with changes makes a new store: its changes are gone with the old one.
TEST(ChangesAndBuild, ABuildOverAStoreDropsItsChanges) {
  testing::TempDir dir("mktree_churn");
  std::vector<SceneObject> scene = testing::ClusteredScene(80, 4);
  const std::string store = dir.file("s.mkt");
  const IngestOptions opts = testing::SmallPages(Backend::kPagedFile);
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, opts).ok());
  {
    auto w = ChangeWriter::Open(store);
    ASSERT_TRUE(w.ok());
    ChangeBatch b;
    b.remove = {1, 2, 3};
    ASSERT_TRUE((*w)->Commit(b).ok());
  }
  ASSERT_EQ((*Database::Open(store))->object_count(), 77u);
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, opts).ok());  // the same bytes as the first build
  EXPECT_FALSE(std::filesystem::exists(store + ".changes"));
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok());
  EXPECT_EQ((*db)->object_count(), 80u);
  EXPECT_EQ((*db)->revision(), 0u);
}

}  // namespace
}  // namespace mktree

namespace mktree {
namespace {

// A closed prism of many sides: its entry is larger than a 2 KiB page.
SceneObject LargeObject(std::mt19937_64& rng, const std::string& name) {
  std::uniform_real_distribution<double> x(0, 100), y(0, 40), z(0, 20);
  SceneObject o;
  o.name = name;
  o.mesh = testing::PrismMesh(static_cast<int>(rng() % 3), y(rng), z(rng), 0.5, x(rng), x(rng) + 12, 400);
  return o;
}

// Hundreds of small batches (1 to 6 changes, large objects among them, a replace by name now and then, a
// compaction every so often), each checked against brute force: the many-commit path, merges of every size.
TEST_P(Churn, HundredsOfSmallBatchesWithLargeObjects) {
  testing::TempDir dir("mktree_churn");
  std::mt19937_64 rng(383);
  std::vector<SceneObject> scene = testing::ClusteredScene(150, 17);
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(GetParam())).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  testing::LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0.5, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0;
  for (int step = 0; step < 300; ++step) {
    ChangeBatch batch = testing::RandomBatch(live, 1 + rng() % 6, rng, &counter);
    if (step % 7 == 0) batch.add.push_back(LargeObject(rng, "large_" + std::to_string(step)));
    if (step % 11 == 5 && !batch.replace.empty()) {  // the same change, by the object's unique name
      SceneObject o = batch.replace.back();
      batch.replace.pop_back();
      o.name = live.at(o.id).name;
      const ObjectId id = o.id;
      batch.replace_by_name.push_back(o);
      auto done = (*w)->Commit(batch);
      ASSERT_TRUE(done.ok()) << done.status().ToString();
      testing::Apply(batch, *done, &live);
      live[id] = o;
      live[id].id = id;
    } else {
      auto done = (*w)->Commit(batch);
      ASSERT_TRUE(done.ok()) << done.status().ToString();
      ASSERT_EQ(done->compaction_error, "");
      testing::Apply(batch, *done, &live);
    }
    if (step % 25 == 24) {
      ASSERT_TRUE((*w)->Compact().ok());
    }
    auto db = Database::Open(store, {.cache_pages = 16});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(6, rng),
                           "step " + std::to_string(step));
  }
}

}  // namespace
}  // namespace mktree

namespace mktree {
namespace {

// The store file is a hard link of the newest base: damage to it is damage, never taken for a rebuild (which
// would answer the base alone and let a writer replace the changes folder).
TEST(ChangesAndBuild, ADamagedStoreFileIsCorruptionNotANewStore) {
  testing::TempDir dir("mktree_churn");
  std::vector<SceneObject> scene = testing::ClusteredScene(80, 6);
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(Backend::kPagedFile)).ok());
  {
    auto w = ChangeWriter::Open(store);
    ASSERT_TRUE(w.ok());
    ChangeBatch b;
    b.remove = {4};
    ASSERT_TRUE((*w)->Commit(b).ok());
  }
  std::filesystem::resize_file(store, std::filesystem::file_size(store) - 1);
  const auto folder_files = [&] {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(store + ".changes"))
      names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  };
  const std::vector<std::string> before = folder_files();
  auto db = Database::Open(store);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), Status::Code::kCorruption) << db.status().ToString();
  EXPECT_NE(db.status().message().find("damaged"), std::string::npos) << db.status().ToString();
  auto w = ChangeWriter::Open(store);
  ASSERT_FALSE(w.ok());
  EXPECT_EQ(w.status().code(), Status::Code::kCorruption) << w.status().ToString();
  EXPECT_EQ(folder_files(), before);  // nothing set aside or removed
}

}  // namespace
}  // namespace mktree

namespace mktree {
namespace {

// The newest revision file lost (deleted by hand): the store is back at the revision before it, and the next
// writer gives neither its revision number nor the ids its batch added again.
TEST(ChangesAndBuild, ALostRevisionFileIsNotReusedByTheNextWriter) {
  testing::TempDir dir("mktree_churn");
  std::vector<SceneObject> scene = testing::ClusteredScene(40, 8);
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(Backend::kPagedFile)).ok());
  ChangeBatch add;
  add.add = testing::ClusteredScene(5, 9);
  std::vector<ObjectId> lost_ids;
  {
    auto w = ChangeWriter::Open(store, {.compact_threshold = 0});
    ASSERT_TRUE(w.ok());
    ASSERT_TRUE((*w)->Commit(add).ok());
    auto second = (*w)->Commit(add);
    ASSERT_TRUE(second.ok());
    ASSERT_EQ(second->revision, 2u);
    lost_ids = second->added_ids;
  }
  std::filesystem::remove(store + ".changes/rev-000000000002.rev");
  ASSERT_EQ((*Database::Open(store))->revision(), 1u);
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  auto third = (*w)->Commit(add);
  ASSERT_TRUE(third.ok()) << third.status().ToString();
  EXPECT_GT(third->revision, 2u);
  EXPECT_GT(third->added_ids.front(), lost_ids.back());
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok());
  EXPECT_EQ((*db)->object_count(), 50u);
}

}  // namespace
}  // namespace mktree

namespace mktree {
namespace {

// Two unit cubes in one object, the second 1e-9 beyond the first: closed in the input's doubles, but
// float32 storage welds their facing corners. Whether an object is a solid is decided on the input and
// kept (docs/clash.md §1); a merge of deltas or a compaction re-encodes stored objects and must keep it.
SceneObject TwoCubesWeldedByRounding() {
  SceneObject o;
  o.name = "two_cubes";
  const Mesh a = testing::BoxMesh(Box3d{{10, 10, 10}, {11, 11, 11}});
  const Mesh b = testing::BoxMesh(Box3d{{11 + 1e-9, 10, 10}, {12, 11, 11}});
  o.mesh = a;
  const uint32_t base = static_cast<uint32_t>(a.vertex_count());
  o.mesh.vertices.insert(o.mesh.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (uint32_t t : b.triangles) o.mesh.triangles.push_back(base + t);
  return o;
}

TEST(ChangesAndBuild, ASolidJudgedOnTheInputStaysOneThroughMergesAndCompaction) {
  testing::TempDir dir("mktree_churn");
  std::vector<SceneObject> scene;
  scene.push_back(TwoCubesWeldedByRounding());
  SceneObject inner;  // wholly inside the first cube: a containment pair, only while the cubes are a solid
  inner.name = "inner";
  inner.mesh = testing::BoxMesh(Box3d{{10.4, 10.4, 10.4}, {10.6, 10.6, 10.6}});
  scene.push_back(inner);
  for (int i = 0; i < 6; ++i) {
    SceneObject f;
    f.name = "far_" + std::to_string(i);
    f.mesh = testing::BoxMesh(Box3d{{20.0 + 3 * i, 10, 10}, {21.0 + 3 * i, 11, 11}});
    scene.push_back(f);
  }
  for (size_t i = 0; i < scene.size(); ++i) scene[i].id = static_cast<ObjectId>(i);
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(scene, store, testing::SmallPages(Backend::kPagedFile)).ok());
  const auto pairs_now = [&] {
    auto db = Database::Open(store);
    EXPECT_TRUE(db.ok()) << db.status().ToString();
    return testing::SortedPairs(testing::SelfClashPairs(**db));
  };
  const auto built = pairs_now();
  ASSERT_EQ(built.size(), 1u);
  ASSERT_EQ(std::get<0>(built[0]), 0u);
  ASSERT_EQ(std::get<1>(built[0]), 1u);
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  ChangeBatch again;  // the same cubes from the input again: a delta holds them
  again.replace.push_back(TwoCubesWeldedByRounding());
  again.replace.back().id = 0;
  ASSERT_TRUE((*w)->Commit(again).ok());
  EXPECT_EQ(pairs_now(), built);
  ChangeBatch other;  // a delta of one object: the two deltas merge, re-encoding the cubes
  other.replace.push_back(scene[4]);
  ASSERT_TRUE((*w)->Commit(other).ok());
  EXPECT_EQ(pairs_now(), built) << "after the merge of deltas";
  auto c = (*w)->Compact();
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(pairs_now(), built) << "after compaction";
}

}  // namespace
}  // namespace mktree
