// Objects added from files (ChangeBatch::add_files, `mktree update --add`) are streamed into the commit,
// never all in memory: they answer exactly as the same objects added from memory would (ids after the
// batch's own, in file order), a sharded store routes them to their shards' deltas, and a commit of files
// with many times the build's memory budget of geometry peaks within that budget.
#include <gtest/gtest.h>

#include "change_fixtures.h"
#include "child_peak_rss.h"
#include "engine/generator/tanker_generator.h"
#include "engine/revision/change_folder.h"

namespace mktree {
namespace {

// The objects "tanker:N:SEED" gives, numbered from 0.
std::vector<SceneObject> TankerObjects(uint64_t n, uint64_t seed) {
  std::vector<SceneObject> out;
  auto source = MakeTankerSource(n, seed, 0);
  SceneObject o;
  for (;;) {
    auto more = source->Next(&o);
    EXPECT_TRUE(more.ok()) << more.status().ToString();
    if (!more.ok() || !*more) break;
    out.push_back(o);
  }
  return out;
}

struct Case {
  Backend backend;
  uint32_t shards;  // 0: a store file
};

class AddedFiles : public ::testing::TestWithParam<Case> {};

TEST_P(AddedFiles, AnswerAsTheSameObjectsAddedFromMemory) {
  testing::TempDir dir("mktree_added_files");
  std::mt19937_64 rng(17);
  const std::vector<SceneObject> scene = testing::ClusteredScene(200, 40);
  const std::string store = dir.file("s.mkt");
  const IngestOptions opts = testing::SmallPages(GetParam().backend);
  if (GetParam().shards)
    ASSERT_TRUE(testing::BuildShardedFromObjects(scene, store, opts, GetParam().shards).ok());
  else
    ASSERT_TRUE(testing::BuildFromObjects(scene, store, opts).ok());
  const Vec3d origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  testing::LiveSet live = testing::LiveOf(scene);
  auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  uint64_t counter = 0;
  // The tankers (300 m by 50 by 30) reach the queries' region (RandomQueries) and every shard.
  for (int round = 0; round < 3; ++round) {
    ChangeBatch batch = testing::RandomBatch(live, 12, rng, &counter);
    const std::string spec_a = "tanker:" + std::to_string(30 + 10 * round) + ":" + std::to_string(round + 2);
    const std::string spec_b = "tanker:25:" + std::to_string(round + 9);
    batch.add_files = {spec_a, spec_b};
    std::vector<SceneObject> from_files = TankerObjects(30 + 10 * round, round + 2);
    for (const SceneObject& o : TankerObjects(25, round + 9)) from_files.push_back(o);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    ASSERT_EQ(done->added, batch.add.size() + from_files.size());
    ASSERT_EQ(done->added_ids.size(), done->added);
    for (size_t i = 1; i < done->added_ids.size(); ++i) ASSERT_EQ(done->added_ids[i], done->added_ids[0] + i);
    testing::Apply(batch, *done, &live);  // the batch's own objects: the first ids
    for (size_t i = 0; i < from_files.size(); ++i) {
      SceneObject o = from_files[i];
      o.id = done->added_ids[batch.add.size() + i];
      live[o.id] = o;
    }
    ASSERT_EQ(done->objects, live.size());
    auto db = Database::Open(store);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(25, rng),
                           "round " + std::to_string(round));
    for (size_t i = 0; i < from_files.size(); i += 7) {
      auto record = (*db)->Object(done->added_ids[batch.add.size() + i]);
      ASSERT_TRUE(record.ok()) << record.status().ToString();
      EXPECT_EQ(record->name, from_files[i].name);
    }
    auto at = OpenStoreRevision(store, std::nullopt);
    ASSERT_TRUE(at.ok() && at->hold);
    for (const RevisionPart& d : at->hold->manifest().deltas)
      EXPECT_EQ(d.shard == kNoShard, GetParam().shards == 0) << d.store.name;
  }
  auto c = (*w)->Compact();
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok());
  testing::ExpectAnswers(**db, live, origin, testing::RandomQueries(25, rng), "compacted");
  testing::ExpectClashOfFreshBuild(**db, live, opts, origin, dir.path().string());
}

INSTANTIATE_TEST_SUITE_P(Stores, AddedFiles,
                         ::testing::Values(Case{Backend::kHdf5, 0}, Case{Backend::kPagedFile, 0},
                                           Case{Backend::kPagedFile, 3}),
                         [](const auto& info) {
                           return std::string(BackendName(info.param.backend)) +
                                  (info.param.shards ? "_sharded" : "");
                         });

// 300,000 tanker objects, about 190 MiB of raw geometry: held in memory the batch alone would pass the
// budget twice over; streamed, the commit's peak is the delta build's.
TEST(BoundedMemory, FilesOfTwiceTheBudgetCommitWithinIt) {
  constexpr uint64_t kBudget = 80ull << 20;
  testing::TempDir dir("mktree_added_files");
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(testing::BuildFromObjects(testing::ClusteredScene(50, 2), store,
                                        testing::SmallPages(Backend::kPagedFile))
                  .ok());
  const testing::ChildRun run = testing::RunForPeakRss([&] {
    auto w = ChangeWriter::Open(store, {.compact_threshold = 0, .threads = 1});
    if (!w.ok()) return 2;
    ChangeBatch batch;
    batch.add_files = {"tanker:300000:2"};
    auto done = (*w)->Commit(batch);
    return done.ok() && done->added == 300000 ? 0 : 3;
  });
  ASSERT_TRUE(run.exited);
  ASSERT_EQ(run.code, 0);
  const uint64_t peak = run.peak_rss;
  EXPECT_LE(peak, kBudget) << "peak RSS " << (peak >> 20) << " MiB";
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_EQ((*db)->object_count(), 300050u);
}

}  // namespace
}  // namespace mktree
