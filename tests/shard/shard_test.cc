// Sharded stores (docs/shards.md): every answer of a manifest's Database against brute force and against
// the unsharded store of the same scene; damaged, missing and foreign shards; atomic builds.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/shard_build.h"
#include "engine/scene/scene_source.h"
#include "engine/shard/manifest.h"
#include "mktree/build.h"
#include "mktree/database.h"
#include "query/query_oracle.h"
#include "query/scene_fixtures.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::BruteForce;
using testing::TempDir;

std::vector<Query> RandomQueries(const Box3d& bounds, const std::vector<SceneObject>& objs, int n,
                                 uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<Query> qs;
  for (int i = 0; i < n; ++i) {
    Vec3d p;
    if (i % 3 == 0) {  // a vertex of an object: on its box's face, and on its surface
      const Mesh& m = objs[rng() % objs.size()].mesh;
      const size_t v = rng() % m.vertex_count();
      p = {m.vertices[3 * v], m.vertices[3 * v + 1], m.vertices[3 * v + 2]};
    } else {
      for (int a = 0; a < 3; ++a) p[a] = bounds.min[a] + unit(rng) * (bounds.max[a] - bounds.min[a]);
    }
    const QueryMode mode = i % 2 ? QueryMode::kExact : QueryMode::kAabb;
    if (i % 4 < 2) {
      qs.push_back(Query::Point(p, mode));
    } else {
      Box3d b;
      const double side = 0.2 + unit(rng) * 12;
      for (int a = 0; a < 3; ++a) {
        b.min[a] = p[a] - side * unit(rng);
        b.max[a] = b.min[a] + side;
      }
      qs.push_back(Query::Box(b, mode));
    }
  }
  return qs;
}

std::vector<ObjectId> SortedIds(std::vector<ObjectId> v) {
  std::sort(v.begin(), v.end());
  return v;
}

// Everything the sharded Database answers, against the unsharded one and brute force.
void ExpectSameAnswers(const Database& sharded, const Database& plain, const BruteForce& oracle,
                       const std::vector<Query>& qs, uint32_t shards) {
  ASSERT_EQ(sharded.object_count(), plain.object_count());
  EXPECT_EQ(sharded.shard_count(), shards);
  EXPECT_EQ(plain.shard_count(), 0u);
  const Box3d sb = sharded.bounds(), pb = plain.bounds();
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(sb.min[a], pb.min[a]);
    EXPECT_EQ(sb.max[a], pb.max[a]);
  }
  uint64_t answered = 0;
  for (size_t i = 0; i < qs.size(); ++i) {
    SCOPED_TRACE("query " + std::to_string(i));
    QueryResult rs, rp;
    ASSERT_TRUE(sharded.Run(qs[i], &rs).ok());
    ASSERT_TRUE(plain.Run(qs[i], &rp).ok());
    const std::vector<ObjectId> truth = SortedIds(oracle.Answer(qs[i]));
    EXPECT_EQ(rs.hits, truth);
    EXPECT_EQ(rs.hits, rp.hits);
    EXPECT_EQ(rs.stats.hits, truth.size());
    answered += !truth.empty();
    // Per-shard statistics add up to the total, top-level nodes aside.
    std::vector<ShardQueryStats> per;
    QueryStats total;
    std::vector<ObjectId> visited;
    auto whole = sharded.VisitUntilPerShard(
        qs[i],
        [&](ObjectId id) {
          visited.push_back(id);
          return true;
        },
        &total, &per);
    ASSERT_TRUE(whole.ok());
    EXPECT_TRUE(*whole);
    EXPECT_EQ(SortedIds(visited), truth);
    QueryStats sum;
    for (size_t s = 0; s < per.size(); ++s) {
      if (s) {
        EXPECT_LT(per[s - 1].shard, per[s].shard);
      }
      sum += per[s].stats;
    }
    EXPECT_EQ(sum.pages_touched, total.pages_touched);
    EXPECT_EQ(sum.leaves_visited, total.leaves_visited);
    EXPECT_EQ(sum.hits, total.hits);
    // Any and limits: the first `limit` ids of the visiting order, truncated when more exist.
    auto any = sharded.Any(qs[i], nullptr);
    ASSERT_TRUE(any.ok());
    EXPECT_EQ(*any, !truth.empty());
    for (uint64_t limit : {uint64_t{0}, uint64_t{1}, uint64_t{3}}) {
      Query q = qs[i];
      q.limit = limit;
      QueryResult r;
      ASSERT_TRUE(sharded.Run(q, &r).ok());
      EXPECT_EQ(r.hits.size(), std::min<uint64_t>(limit, truth.size()));
      EXPECT_EQ(r.truncated, truth.size() > limit);
      for (ObjectId id : r.hits) EXPECT_TRUE(std::binary_search(truth.begin(), truth.end(), id));
    }
  }
  EXPECT_GT(answered, qs.size() / 10);  // the queries meet objects
  // Batches: warm on three threads, cold, and counts only, in query order.
  std::vector<QueryResult> batch;
  ASSERT_TRUE(sharded.RunBatch(qs, 3, &batch).ok());
  ASSERT_EQ(batch.size(), qs.size());
  for (size_t i = 0; i < qs.size(); ++i) EXPECT_EQ(batch[i].hits, SortedIds(oracle.Answer(qs[i]))) << i;
  BatchOptions cold;
  cold.threads = 2;
  cold.cold = true;
  cold.ids = false;
  std::vector<uint64_t> counts;
  ASSERT_TRUE(sharded
                  .RunBatchStreamed(qs, cold,
                                    [&](uint64_t i, const QueryResult& r) {
                                      EXPECT_EQ(i, counts.size());
                                      EXPECT_TRUE(r.hits.empty());
                                      EXPECT_EQ(r.stats.pages_read, r.stats.pages_touched);
                                      counts.push_back(r.stats.hits);
                                      return Status::Ok();
                                    })
                  .ok());
  ASSERT_EQ(counts.size(), qs.size());
  for (size_t i = 0; i < qs.size(); ++i) EXPECT_EQ(counts[i], oracle.Answer(qs[i]).size()) << i;
  // Objects: records and meshes, by global id.
  for (ObjectId id = 0; id < plain.object_count(); id += 1 + plain.object_count() / 300) {
    auto a = sharded.Object(id), b = plain.Object(id);
    ASSERT_TRUE(a.ok()) << a.status().ToString();
    ASSERT_TRUE(b.ok());
    EXPECT_EQ(a->id, id);
    EXPECT_EQ(a->name, b->name);
    EXPECT_EQ(a->source, b->source);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(a->box.min[k], b->box.min[k]);
    auto ga = sharded.ObjectGeometry(id), gb = plain.ObjectGeometry(id);
    ASSERT_TRUE(ga.ok());
    ASSERT_TRUE(gb.ok());
    EXPECT_EQ(ga->vertices, gb->vertices);
    EXPECT_EQ(ga->triangles, gb->triangles);
    EXPECT_EQ(*sharded.ObjectName(id), *plain.ObjectName(id));
  }
  EXPECT_EQ(sharded.Object(static_cast<ObjectId>(plain.object_count())).status().code(),
            Status::Code::kInvalidArgument);
  Query bad = Query::Box(Box3d{{1, 1, 1}, {0, 0, 0}});
  QueryResult r;
  EXPECT_EQ(sharded.Run(bad, &r).code(), Status::Code::kInvalidArgument);
}

struct Case {
  BuildOptions::Backend backend;
  uint32_t shards;
};

class RandomScenes : public ::testing::TestWithParam<Case> {};

TEST_P(RandomScenes, AnswerAsTheUnshardedStoreAndBruteForce) {
  TempDir dir("mktree_shard");
  const std::vector<SceneObject> objs = testing::ClusteredScene(2500, 17 + GetParam().shards);
  BuildOptions o;
  o.backend = GetParam().backend;
  o.block_size = 1024;
  o.blocks_per_page = 2;
  o.threads = 2;
  ASSERT_TRUE(BuildFromObjects(objs, dir.path() / "plain.mkt", o).ok());
  o.shards = GetParam().shards;
  auto built = BuildFromObjects(objs, dir.path() / "s.mkts", o);
  ASSERT_TRUE(built.ok()) << built.status().ToString();
  EXPECT_EQ(built->objects, objs.size());
  for (uint32_t s = 0; s < o.shards; ++s)
    EXPECT_TRUE(std::filesystem::exists(ShardStorePath((dir.path() / "s.mkts").string(), s)));
  // A shard is an ordinary store on its own.
  auto alone = Database::Open(ShardStorePath((dir.path() / "s.mkts").string(), 0));
  ASSERT_TRUE(alone.ok()) << alone.status().ToString();
  auto sharded = Database::Open(dir.path() / "s.mkts", {.cache_pages = 64});
  ASSERT_TRUE(sharded.ok()) << sharded.status().ToString();
  auto plain = Database::Open(dir.path() / "plain.mkt", {.cache_pages = 64});
  ASSERT_TRUE(plain.ok());
  EXPECT_LT((*alone)->object_count(), o.shards > 1 ? objs.size() : objs.size() + 1);
  const BruteForce oracle(objs);
  ExpectSameAnswers(**sharded, **plain, oracle, RandomQueries((*plain)->bounds(), objs, 400, 5), o.shards);
}

INSTANTIATE_TEST_SUITE_P(
    Shards, RandomScenes,
    ::testing::Values(Case{BuildOptions::Backend::kHdf5, 1}, Case{BuildOptions::Backend::kHdf5, 2},
                      Case{BuildOptions::Backend::kHdf5, 3}, Case{BuildOptions::Backend::kHdf5, 4},
                      Case{BuildOptions::Backend::kPagedFile, 1}, Case{BuildOptions::Backend::kPagedFile, 2},
                      Case{BuildOptions::Backend::kPagedFile, 3}, Case{BuildOptions::Backend::kPagedFile, 4}),
    [](const auto& info) {
      return std::string(info.param.backend == BuildOptions::Backend::kHdf5 ? "hdf5" : "pagefile") + "_" +
             std::to_string(info.param.shards);
    });

class RealScenes : public ::testing::TestWithParam<std::string> {};

TEST_P(RealScenes, AnswerAsTheUnshardedStoreAndBruteForce) {
  const std::string file = std::string(MKTREE_SHARED_DATA) + "/" + GetParam();
  if (!std::filesystem::exists(file)) GTEST_SKIP() << file << " not found";
  std::vector<SceneObject> objs;
  {
    auto src = OpenSceneFile(file);
    ASSERT_TRUE(src.ok());
    SceneObject o;
    while (*(*src)->Next(&o)) objs.push_back(o);
  }
  const BruteForce oracle(objs);
  TempDir dir("mktree_shard");
  BuildOptions o;
  o.backend = BuildOptions::Backend::kPagedFile;
  o.threads = 2;
  ASSERT_TRUE(BuildFromFiles({file}, dir.path() / "plain.mkt", o).ok());
  auto plain = Database::Open(dir.path() / "plain.mkt");
  ASSERT_TRUE(plain.ok());
  const std::vector<Query> qs = RandomQueries((*plain)->bounds(), objs, 150, 9);
  for (uint32_t k = 1; k <= 4; ++k) {
    SCOPED_TRACE("shards " + std::to_string(k));
    o.shards = k;
    const std::string path = (dir.path() / (std::string("s") + std::to_string(k) + ".mkts")).string();
    auto built = BuildFromFiles({file}, path, o);
    ASSERT_TRUE(built.ok()) << built.status().ToString();
    auto sharded = Database::Open(path);
    ASSERT_TRUE(sharded.ok()) << sharded.status().ToString();
    ExpectSameAnswers(**sharded, **plain, oracle, qs, k);
  }
}

INSTANTIATE_TEST_SUITE_P(Shards, RealScenes,
                         ::testing::Values("buildings/duplex.obj", "buildings/steel_mini_project.obj"),
                         [](const auto& info) {
                           return info.index == 0 ? std::string("duplex") : std::string("steel");
                         });

// A built sharded store in a temporary folder.
struct Built {
  TempDir dir{"mktree_shard"};
  std::string manifest = (dir.path() / "s.mkts").string();
  std::vector<SceneObject> objs = testing::ClusteredScene(1500, 3);
  explicit Built(uint32_t shards = 3) {
    BuildOptions o;
    o.block_size = 1024;
    o.blocks_per_page = 2;
    o.shards = shards;
    o.backend = BuildOptions::Backend::kPagedFile;
    auto r = BuildFromObjects(objs, manifest, o);
    if (!r.ok()) throw std::runtime_error(r.status().ToString());
  }
};

void FlipByte(const std::string& path, uint64_t at) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(static_cast<std::streamoff>(at));
  char c = 0;
  f.read(&c, 1);
  c = static_cast<char>(c ^ 0x20);
  f.seekp(static_cast<std::streamoff>(at));
  f.write(&c, 1);
}

void ExpectRefusedNaming(const std::string& manifest, const std::string& file) {
  auto db = Database::Open(manifest);
  ASSERT_FALSE(db.ok());
  EXPECT_NE(db.status().message().find(std::filesystem::path(file).filename().string()), std::string::npos)
      << db.status().ToString();
}

TEST(ShardErrors, MissingShardStoreOrIdFileIsNamed) {
  Built b;
  for (const std::string& victim : {ShardStorePath(b.manifest, 1), ShardIdsPath(b.manifest, 2)}) {
    Built fresh;
    const std::string v = victim.substr(b.manifest.size());
    std::filesystem::remove(fresh.manifest + v);
    ExpectRefusedNaming(fresh.manifest, fresh.manifest + v);
  }
}

TEST(ShardErrors, TruncatedOrDamagedShardIsNamed) {
  for (int kind = 0; kind < 4; ++kind) {
    Built b;
    const std::string store = ShardStorePath(b.manifest, 1), ids = ShardIdsPath(b.manifest, 0);
    const uint64_t size = std::filesystem::file_size(store);
    switch (kind) {
      case 0:
        std::filesystem::resize_file(store, size - 100);
        break;
      case 1:
        FlipByte(store, 10);  // the header
        break;
      case 2:
        FlipByte(store, size - 20);  // the trailing sections
        break;
      case 3:
        FlipByte(ids, 40);
        break;
    }
    ExpectRefusedNaming(b.manifest, kind == 3 ? ids : store);
  }
}

TEST(ShardErrors, DamagedLeafPageIsAnErrorNeverAWrongAnswer) {
  Built b(2);
  // A byte in the middle of the store, past the fingerprinted ends: the page checksum catches it.
  const std::string store = ShardStorePath(b.manifest, 0);
  const uint64_t size = std::filesystem::file_size(store);
  ASSERT_GT(size, 3 * 65536u);
  FlipByte(store, size / 2);
  auto db = Database::Open(b.manifest, {.cache_pages = 0});
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  const BruteForce oracle(b.objs);
  int errors = 0;
  for (const Query& q : RandomQueries((*db)->bounds(), b.objs, 300, 4)) {
    QueryResult r;
    const Status st = (*db)->Run(q, &r);
    if (!st.ok()) {
      ++errors;
      EXPECT_NE(st.message().find("s.mkts.shard-0.mkt"), std::string::npos) << st.ToString();
      continue;
    }
    EXPECT_EQ(r.hits, SortedIds(oracle.Answer(q)));
  }
  EXPECT_GT(errors, 0);
}

TEST(ShardErrors, ShardOfAnotherBuildIsRefused) {
  Built a, b;  // the same scene twice: identical stores, different builds
  std::filesystem::copy_file(ShardIdsPath(b.manifest, 1), ShardIdsPath(a.manifest, 1),
                             std::filesystem::copy_options::overwrite_existing);
  ExpectRefusedNaming(a.manifest, ShardIdsPath(a.manifest, 1));
  Built c(3);
  Built other(2);  // another scene split: another store
  std::filesystem::copy_file(ShardStorePath(other.manifest, 1), ShardStorePath(c.manifest, 1),
                             std::filesystem::copy_options::overwrite_existing);
  ExpectRefusedNaming(c.manifest, ShardStorePath(c.manifest, 1));
}

TEST(ShardErrors, AnIdInTwoShardsIsRefused) {
  // Consistent files (checksums and fingerprints rewritten) whose id files claim one object twice.
  Built b(2);
  auto m = ReadManifest(b.manifest);
  ASSERT_TRUE(m.ok());
  auto ids0 = ReadShardIds(ShardIdsPath(b.manifest, 0), m->build_id, 0, m->objects);
  auto ids1 = ReadShardIds(ShardIdsPath(b.manifest, 1), m->build_id, 1, m->objects);
  ASSERT_TRUE(ids0.ok() && ids1.ok());
  ASSERT_GE(ids1->size(), 2u);
  ObjectId x = kNoIndex;
  for (ObjectId id : *ids0)
    if (id < (*ids1)[1]) x = id;
  ASSERT_NE(x, kNoIndex);
  (*ids1)[0] = x;
  ASSERT_TRUE(WriteShardIds(ShardIdsPath(b.manifest, 1), m->build_id, 1, *ids1).ok());
  auto fp = FingerprintFile(ShardIdsPath(b.manifest, 1));
  ASSERT_TRUE(fp.ok());
  m->shards[1].ids = *fp;
  ASSERT_TRUE(WriteManifest(b.manifest, *m).ok());
  auto db = Database::Open(b.manifest);
  ASSERT_FALSE(db.ok());
  EXPECT_NE(db.status().message().find("in no shard, or in two"), std::string::npos)
      << db.status().ToString();
}

TEST(ShardErrors, DamagedManifestIsRefused) {
  Built b;
  const uint64_t size = std::filesystem::file_size(b.manifest);
  for (uint64_t at : {uint64_t{0}, uint64_t{9}, uint64_t{30}, size / 2, size - 3}) {
    Built fresh;
    FlipByte(fresh.manifest, at);
    auto db = Database::Open(fresh.manifest);
    ASSERT_FALSE(db.ok()) << at;
    EXPECT_NE(db.status().message().find("s.mkts"), std::string::npos) << db.status().ToString();
  }
  std::filesystem::resize_file(b.manifest, size - 9);
  auto db = Database::Open(b.manifest);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), Status::Code::kCorruption);
}

TEST(ShardBuild, FailedBuildLeavesNothingAndKeepsThePrevious) {
  Built b(2);
  std::vector<SceneObject> objs = b.objs;
  // Valid for the sample pass, refused by the shard build: an object whose triangle names a vertex the
  // shard build's checks refuse is caught by the first pass; a store path that cannot be written is not.
  // So make the second shard's store path a directory.
  BuildOptions o;
  o.shards = 3;
  const std::string manifest = (b.dir.path() / "t.mkts").string();
  std::filesystem::create_directory(ShardStorePath(manifest, 1) + ".new");
  auto r = BuildFromObjects(objs, manifest, o);
  ASSERT_FALSE(r.ok());
  std::filesystem::remove(ShardStorePath(manifest, 1) + ".new");
  for (const auto& e : std::filesystem::directory_iterator(b.dir.path()))
    EXPECT_EQ(e.path().filename().string().rfind("t.mkts", 0), std::string::npos) << e.path();
  // The previous sharded store at a path stays whole when a rebuild fails.
  std::filesystem::create_directory(ShardStorePath(b.manifest, 1) + ".new");
  o.shards = 2;
  ASSERT_FALSE(BuildFromObjects(objs, b.manifest, o).ok());
  auto db = Database::Open(b.manifest);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_EQ((*db)->object_count(), objs.size());
}

TEST(ShardBuild, LeftoversOfKilledBuildsAreRemovedUnderTheBuildLock) {
  Built b(2);
  namespace fs = std::filesystem;
  const fs::path dir = b.dir.path();
  // What killed builds of s.mkts leave (tests/mpi/ranks.sh kills real ones), and names that are not theirs.
  const std::vector<std::string> leftovers = {
      "s.mkts.shard-0.mkt.new",       "s.mkts.shard-1.ids.new",      "s.mkts.shard-7.mkt.new.tmp.4242",
      "s.mkts.shard-2.ids.new.tmp.1", "s.mkts.shard-2.mkt.new.lock", "s.mkts.shard-0.mkt.from-3.new"};
  const std::vector<std::string> others = {"s.mkts.shard-0.mkt.new.tmp.x", "t.mkts.shard-0.mkt.new",
                                           "s.mkts.shard-x.mkt.new", "s.mkts.shard-0.mkt.from-.new",
                                           "s.mkts.shard-1.ids.new.bak"};
  for (const auto& n : leftovers) std::ofstream(dir / n) << "x";
  for (const auto& n : others) std::ofstream(dir / n) << "x";
  fs::create_directory(dir / "s.mkts.shard-5.mkt.new");  // not a file a build made
  BuildOptions o;
  o.shards = 3;
  {
    // A live build holds the lock: another is refused and removes nothing.
    auto lock = ShardBuildLock::Acquire(b.manifest);
    ASSERT_TRUE(lock.ok()) << lock.status().ToString();
    auto again = ShardBuildLock::Acquire(b.manifest);
    ASSERT_FALSE(again.ok());
    auto r = BuildFromObjects(b.objs, b.manifest, o);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("another build of this sharded store is running"), std::string::npos)
        << r.status().ToString();
    for (const auto& n : leftovers) EXPECT_TRUE(fs::exists(dir / n)) << n;
  }
  EXPECT_FALSE(fs::exists(b.manifest + ".build-lock"));  // released: removed
  auto r = BuildFromObjects(b.objs, b.manifest, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  for (const auto& n : leftovers) EXPECT_FALSE(fs::exists(dir / n)) << n;
  for (const auto& n : others) EXPECT_TRUE(fs::exists(dir / n)) << n;
  EXPECT_TRUE(fs::is_directory(dir / "s.mkts.shard-5.mkt.new"));
  EXPECT_FALSE(fs::exists(b.manifest + ".build-lock"));
  auto db = Database::Open(b.manifest);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_EQ((*db)->shard_count(), 3u);
  EXPECT_EQ((*db)->object_count(), b.objs.size());
}

TEST(ShardBuild, TooFewObjectsForTheShardsIsAnError) {
  TempDir dir("mktree_shard");
  const std::vector<SceneObject> objs = testing::ClusteredScene(3, 1);
  BuildOptions o;
  o.shards = 5;
  auto r = BuildFromObjects(objs, dir.path() / "s.mkts", o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kInvalidArgument);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(TopLevels, EveryObjectRoutesToExactlyOneShardAndSamplesMerge) {
  const std::vector<SceneObject> objs = testing::ClusteredScene(4000, 8);
  ShardSample whole(500), a(500), b(500);
  for (const SceneObject& o : objs) {
    whole.Add(o.id, o.mesh.Bounds());
    (o.id % 3 ? a : b).Add(o.id, o.mesh.Bounds());
  }
  a.Merge(b);  // two readers' samples: the same as one reader's
  const auto wi = whole.Items(), ai = a.Items();
  ASSERT_EQ(wi.size(), 500u);
  ASSERT_EQ(ai.size(), wi.size());
  for (size_t i = 0; i < wi.size(); ++i) EXPECT_EQ(wi[i].id, ai[i].id);
  for (uint32_t k = 1; k <= 7; ++k) {
    auto top = ChooseTopLevels(wi, k);
    ASSERT_TRUE(top.ok()) << top.status().ToString();
    EXPECT_TRUE(top->Validate("t").ok());
    std::vector<uint64_t> count(k);
    for (const SceneObject& o : objs) ++count[top->ShardOf(o.mesh.Bounds())];
    for (uint32_t s = 0; s < k; ++s) EXPECT_GT(count[s], 0u) << "shard " << s << " of " << k;
  }
}

// CanRouteTo (a sharded compaction's record-box filter): with no slack, exactly ShardOf's shard; with a
// slack, at least the shard of every box within it, objects on a cut (boxes a hair either side) included.
TEST(TopLevels, CanRouteToCoversEveryBoxWithinTheSlack) {
  const std::vector<SceneObject> objs = testing::ClusteredScene(3000, 12);
  ShardSample sample(400);
  for (const SceneObject& o : objs) sample.Add(o.id, o.mesh.Bounds());
  std::mt19937_64 rng(3);
  for (uint32_t k = 1; k <= 6; ++k) {
    auto top = ChooseTopLevels(sample.Items(), k);
    ASSERT_TRUE(top.ok()) << top.status().ToString();
    std::vector<Box3d> boxes;
    for (const SceneObject& o : objs) boxes.push_back(o.mesh.Bounds());
    for (const TopNode& t : top->nodes) {  // boxes whose key is the cut, and a hair either side of it
      if (t.is_leaf()) continue;
      for (const double d : {0.0, 1e-9, -1e-9}) {
        Box3d b = boxes[rng() % boxes.size()];
        const double w = b.max[t.axis] - b.min[t.axis];
        b.min[t.axis] = t.key == ShardKey::kMin ? t.cut + d : t.cut + d - w;
        b.max[t.axis] = b.min[t.axis] + w;
        boxes.push_back(b);
      }
    }
    const double slack = 1e-6;
    std::uniform_real_distribution<double> jitter(-slack, slack);
    for (const Box3d& b : boxes) {
      const uint32_t own = top->ShardOf(b);
      for (uint32_t s = 0; s < k; ++s) EXPECT_EQ(top->CanRouteTo(b, 0, s), s == own);
      for (int j = 0; j < 4; ++j) {
        Box3d moved = b;
        for (int a = 0; a < 3; ++a) {
          moved.min[a] += jitter(rng);
          moved.max[a] += jitter(rng);
        }
        EXPECT_TRUE(top->CanRouteTo(b, slack, top->ShardOf(moved)));
      }
    }
  }
}

// The MPI build's disjoint reads (tools/mpi): the tanker's id ranges, generated without the objects before
// them, are together exactly the whole scene's objects, for any split.
TEST(ShardParts, TankerRangesAreTheWholeScenesObjects) {
  for (const uint64_t n : {1u, 7u, 1000u, 25000u}) {
    std::vector<SceneObject> whole;
    auto all = MakeTankerSource(n, 3);
    for (SceneObject o; *all->Next(&o);) whole.push_back(o);
    ASSERT_EQ(whole.size(), n);
    for (const uint64_t parts : {2u, 3u, 5u}) {
      uint64_t at = 0;
      for (uint64_t r = 0; r < parts; ++r) {
        const uint64_t lo = (n * r + parts - 1) / parts, hi = (n * (r + 1) + parts - 1) / parts;
        ASSERT_EQ(lo, at);
        auto part = MakeTankerRangeSource(n, 3, lo, hi);
        for (SceneObject o; *part->Next(&o); ++at) {
          ASSERT_LT(at, n);
          const SceneObject& w = whole[at];
          ASSERT_EQ(o.id, w.id) << "n " << n << " part " << r;
          ASSERT_EQ(o.name, w.name) << "object " << at;
          ASSERT_EQ(o.source, w.source);
          ASSERT_EQ(o.mesh.vertices, w.mesh.vertices) << "object " << at;
          ASSERT_EQ(o.mesh.triangles, w.mesh.triangles) << "object " << at;
        }
        ASSERT_EQ(at, hi);
      }
      EXPECT_EQ(at, n);
    }
  }
}

}  // namespace
}  // namespace mktree
