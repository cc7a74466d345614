// Self-clash and collide on a sharded store (docs/shards.md, "Clash"): the same pairs, classes,
// separations and points as the unsharded store of the same scene and as brute force over the stored
// geometry, with pairs planted across the shards' cuts; exclusions, caps, threads, cache sizes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <tuple>

#include "clash/clash_oracle.h"
#include "engine/generator/tanker_generator.h"
#include "engine/geometry/mesh_separation.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/scene_source.h"
#include "engine/shard/manifest.h"
#include "engine/store_format/object_codec.h"
#include "mktree/build.h"
#include "mktree/clash.h"
#include "mktree/database.h"
#include "query/scene_fixtures.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::BoxMesh;
using testing::ExpectSame;
using testing::OracleClass;
using testing::Sorted;
using testing::TempDir;

// Brute force over the stored geometry: every pair whose stored boxes grown by c meet, classified by
// docs/clash.md §1's rules (restated here, not engine/clash's).
std::vector<ClashPair> Oracle(const std::vector<SceneObject>& scene, double c, double t) {
  const Vec3d origin = ChooseStoreOrigin(scene.front().mesh.Bounds());
  const auto objects = testing::StoredScene(scene, origin);
  std::vector<std::unique_ptr<ClashShape>> shapes;
  for (size_t i = 0; i < objects.size(); ++i)
    shapes.push_back(testing::StoredShape(scene[i].mesh, objects[i].mesh));
  std::vector<ClashPair> out;
  std::vector<size_t> by_x(objects.size());
  for (size_t i = 0; i < by_x.size(); ++i) by_x[i] = i;
  std::sort(by_x.begin(), by_x.end(),
            [&](size_t x, size_t y) { return objects[x].box.min[0] < objects[y].box.min[0]; });
  for (size_t k = 0; k < by_x.size(); ++k) {
    const Box3f& a = objects[by_x[k]].box;
    for (size_t m = k + 1; m < by_x.size() && double{objects[by_x[m]].box.min[0]} - c <= a.max[0]; ++m) {
      const Box3f& b = objects[by_x[m]].box;
      bool meet = true;
      for (int ax = 0; ax < 3; ++ax)
        meet = meet && double{a.min[ax]} - c <= b.max[ax] && double{b.min[ax]} - c <= a.max[ax];
      if (!meet) continue;
      const size_t i = std::min(by_x[k], by_x[m]), j = std::max(by_x[k], by_x[m]);
      const double r = CoordinateResolution(objects[i].box) + CoordinateResolution(objects[j].box);
      SeparateOptions narrow;
      narrow.depth_lower_enough = std::max(t, r);
      const Separation s =
          Separate(*shapes[i], *shapes[j],
                   std::max(c, std::nextafter(r, std::numeric_limits<double>::infinity())), nullptr, narrow);
      ClashPair p;
      p.a = objects[i].id;
      p.b = objects[j].id;
      if (!OracleClass(s, c, t, r, &p)) continue;
      p.point_a = {s.point_a.x + origin.x, s.point_a.y + origin.y, s.point_a.z + origin.z};
      p.point_b = {s.point_b.x + origin.x, s.point_b.y + origin.y, s.point_b.z + origin.z};
      out.push_back(p);
    }
  }
  return Sorted(std::move(out));
}

Box3d B(double x0, double y0, double z0, double x1, double y1, double z1) {
  Box3d b;
  b.min[0] = x0, b.min[1] = y0, b.min[2] = z0, b.max[0] = x1, b.max[1] = y1, b.max[2] = z1;
  return b;
}

// A clustered scene plus groups of planted pairs every `step` (0.5) along a line across the whole scene on
// each axis: a cut of the top levels is a plane across each line but one, and wherever it lies some group has
// a contained, a crossing and a touching (gap exactly 0) pair across it (each kind's two boxes differ in min
// and in max by at least 0.5 on every axis). Also shallow, coplanar and near-miss pairs; dyadic coordinates,
// kept exactly by the store.
std::vector<SceneObject> PlantedAcrossCuts(size_t n, uint64_t seed, double step = 0.5) {
  std::vector<SceneObject> objs = testing::ClusteredScene(n, seed);
  auto add = [&](const std::string& name, const Mesh& m) {
    SceneObject o;
    o.name = name;
    o.mesh = m;
    objs.push_back(std::move(o));
  };
  int g = 0;
  const double lo[3] = {-12, -7, -5}, hi[3] = {112, 47, 25};
  for (int axis = 0; axis < 3; ++axis) {
    for (double at = lo[axis]; at <= hi[axis]; at += step, ++g) {
      double p[3] = {48, 16, 8};
      p[axis] = at;
      p[(axis + 1) % 3] += 5 * (g % 8);  // groups that overlap along the line are apart across it
      const double x = p[0], y = p[1], z = p[2];
      const std::string pre = "plant" + std::to_string(g) + "/";
      add(pre + "outer", BoxMesh(B(x, y, z, x + 2, y + 2, z + 2)));
      add(pre + "inner", BoxMesh(B(x + 0.5, y + 0.5, z + 0.5, x + 1, y + 1, z + 1)));
      add(pre + "cross", BoxMesh(B(x + 1.5, y + 0.5, z + 0.5, x + 3, y + 1.5, z + 1.5)));
      add(pre + "touch", BoxMesh(B(x - 1, y - 1, z - 1, x, y, z)));  // a corner on the outer's
      add(pre + "shallow", BoxMesh(B(x + 0.25, y + 1.9990234375, z + 1.25, x + 0.75, y + 3, z + 1.75)));
      add(pre + "coplanar", BoxMesh(B(x + 0.5, y - 1, z, x + 1.5, y, z + 2)));
      add(pre + "nearmiss", BoxMesh(B(x, y, z + 2.03125, x + 1, y + 1, z + 3)));
    }
  }
  for (size_t i = 0; i < objs.size(); ++i) objs[i].id = static_cast<ObjectId>(i);
  return objs;
}

std::vector<ClashPair> RunSelf(const Database& db, const ClashOptions& o, ClashStats* stats) {
  std::vector<ClashPair> got;
  const Status st = db.SelfClash(
      o, [&](const ClashPair& p) { got.push_back(p); }, stats);
  EXPECT_TRUE(st.ok()) << st.ToString();
  return got;
}

std::vector<ClashPair> RunCollide(const Database& db, const Mesh& m, const std::optional<RigidTransform>& t,
                                  const ClashOptions& o, ClashStats* stats) {
  std::vector<ClashPair> got;
  const Status st = db.Collide(
      m, t, o, [&](const ClashPair& p) { got.push_back(p); }, stats);
  EXPECT_TRUE(st.ok()) << st.ToString();
  return got;
}

// Which shard holds each global id (from the id files).
std::vector<uint32_t> ShardOfIds(const std::string& manifest) {
  auto m = ReadManifest(manifest);
  EXPECT_TRUE(m.ok());
  std::vector<uint32_t> of(m->objects);
  for (uint32_t s = 0; s < m->top.shard_count; ++s) {
    auto ids = ReadShardIds(ShardIdsPath(manifest, s), m->build_id, s, m->objects);
    EXPECT_TRUE(ids.ok());
    for (ObjectId id : *ids) of[id] = s;
  }
  return of;
}

void ExpectSameCounts(const ClashStats& a, const ClashStats& b) {
  EXPECT_EQ(a.hard, b.hard);
  EXPECT_EQ(a.touch, b.touch);
  EXPECT_EQ(a.clearance, b.clearance);
  EXPECT_EQ(a.reported_pairs, b.reported_pairs);
  EXPECT_EQ(a.capped_pairs, b.capped_pairs);
  EXPECT_EQ(a.unreported_touches, b.unreported_touches);
  // Each candidate pair (float32 boxes grown by C meet) is tested once, sharded or not.
  EXPECT_EQ(a.candidate_pairs, b.candidate_pairs);
  EXPECT_EQ(a.excluded_pairs, b.excluded_pairs);
}

struct Scene {
  TempDir dir{"mktree_shard_clash"};
  std::vector<SceneObject> objs;
  BuildOptions options;
  std::string plain;
  Scene(std::vector<SceneObject> o, BuildOptions::Backend backend, uint32_t block = 1024)
      : objs(std::move(o)), plain((dir.path() / "plain.mkt").string()) {
    options.backend = backend;
    options.block_size = block;
    options.blocks_per_page = 2;
    options.threads = 2;
    auto r = BuildFromObjects(objs, plain, options);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
  }
  std::string Sharded(uint32_t k) {
    const std::string path = (dir.path() / ("s" + std::to_string(k) + ".mkts")).string();
    if (std::filesystem::exists(path)) return path;
    BuildOptions o = options;
    o.shards = k;
    auto r = BuildFromObjects(objs, path, o);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    return path;
  }
};

class ShardClash : public ::testing::TestWithParam<BuildOptions::Backend> {};

TEST_P(ShardClash, PlantedPairsAcrossCutsAsUnshardedAndBruteForce) {
  Scene scene(PlantedAcrossCuts(800, 21), GetParam());
  for (const double c : {0.0, 0.05}) {
    SCOPED_TRACE("C " + std::to_string(c));
    ClashOptions o;
    o.clearance = c;
    o.threads = 2;
    const std::vector<ClashPair> truth = Oracle(scene.objs, c, o.touch_tolerance);
    auto plain = Database::Open(scene.plain, {.cache_pages = 64});
    ASSERT_TRUE(plain.ok());
    ClashStats plain_stats;
    const std::vector<ClashPair> want = Sorted(RunSelf(**plain, o, &plain_stats));
    ExpectSame(want, truth);
    for (uint32_t k = 1; k <= 4; ++k) {
      const std::string manifest = scene.Sharded(k);
      const std::vector<uint32_t> shard_of = ShardOfIds(manifest);
      const std::vector<uint64_t> caches =
          c > 0 ? std::vector<uint64_t>{0, 8, 4096} : std::vector<uint64_t>{0};
      for (const uint64_t cache : caches) {
        SCOPED_TRACE("shards " + std::to_string(k) + " cache " + std::to_string(cache));
        auto db = Database::Open(manifest, {.cache_pages = cache});
        ASSERT_TRUE(db.ok()) << db.status().ToString();
        ClashStats stats;
        const std::vector<ClashPair> got = RunSelf(**db, o, &stats);
        ExpectSame(Sorted(got), truth);
        ExpectSameCounts(stats, plain_stats);
        EXPECT_EQ(stats.reported_pairs, got.size());
        for (const ClashPair& p : got) EXPECT_LT(p.a, p.b);
        EXPECT_GT(stats.pages_read, 0u);
        EXPECT_LE(stats.distinct_pages, stats.store_pages);
        if (cache == 4096) {
          EXPECT_EQ(stats.pages_read, stats.distinct_pages);  // each page read once
        }
        // Pairs across the cuts: of every planted kind.
        if (k > 1 && cache == 0) {
          uint64_t cross = 0, contained = 0, touch = 0;
          for (const ClashPair& p : got) {
            if (shard_of[p.a] == shard_of[p.b]) continue;
            cross += p.meeting == ClashMeeting::kCross && p.cls == ClashClass::kHard;
            contained += p.meeting == ClashMeeting::kAInsideB || p.meeting == ClashMeeting::kBInsideA;
            touch += p.cls == ClashClass::kTouch;
          }
          EXPECT_GT(cross, 0u);
          EXPECT_GT(contained, 0u);
          EXPECT_GT(touch, 0u);
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, ShardClash,
                         ::testing::Values(BuildOptions::Backend::kHdf5, BuildOptions::Backend::kPagedFile),
                         [](const auto& info) {
                           return std::string(info.param == BuildOptions::Backend::kHdf5 ? "hdf5"
                                                                                         : "pagefile");
                         });

// The same pairs in the same order and the same counts on 1 and 2 threads and for any window.
TEST(ShardClashRuns, SameOutputForAnyThreadCountAndWindow) {
  Scene scene(PlantedAcrossCuts(600, 5, 2.0), BuildOptions::Backend::kPagedFile);
  const std::string manifest = scene.Sharded(3);
  std::vector<ClashPair> first;
  ClashStats first_stats;
  for (const unsigned threads : {1u, 2u}) {
    for (const uint64_t window : {uint64_t{0}, uint64_t{64} << 10}) {
      SCOPED_TRACE(std::to_string(threads) + " threads, window " + std::to_string(window));
      auto db = Database::Open(manifest, {.cache_pages = 16});
      ASSERT_TRUE(db.ok());
      ClashOptions o;
      o.clearance = 0.02;
      o.threads = threads;
      o.window_bytes = window;
      ClashStats stats;
      const std::vector<ClashPair> got = RunSelf(**db, o, &stats);
      if (first.empty()) {
        first = got;
        first_stats = stats;
        ASSERT_FALSE(first.empty());
        continue;
      }
      ExpectSame(got, first);
      ExpectSameCounts(stats, first_stats);
      EXPECT_EQ(stats.triangle_tests, first_stats.triangle_tests);
      if (window == 0) {
        EXPECT_EQ(stats.pages_read, first_stats.pages_read);
        EXPECT_EQ(stats.leaf_reads, first_stats.leaf_reads);
      }
    }
  }
}

TEST(ShardClashRuns, ExclusionsAndTheCapAsOnOneStore) {
  Scene scene(PlantedAcrossCuts(400, 9, 2.0), BuildOptions::Backend::kPagedFile);
  auto plain = Database::Open(scene.plain);
  ASSERT_TRUE(plain.ok());
  for (uint32_t k : {2u, 4u}) {
    SCOPED_TRACE("shards " + std::to_string(k));
    auto db = Database::Open(scene.Sharded(k));
    ASSERT_TRUE(db.ok());
    ClashOptions o;
    o.exclude_group_separator = "/";
    o.exclude = [](ObjectId a, ObjectId b) { return (a + b) % 5 == 0; };
    ClashStats ps, ss;
    const auto want = Sorted(RunSelf(**plain, o, &ps));
    const auto got = Sorted(RunSelf(**db, o, &ss));
    ExpectSame(got, want);
    ExpectSameCounts(ss, ps);
    EXPECT_GT(ss.excluded_pairs, 0u);
    for (const ClashPair& p : got) EXPECT_NE((p.a + p.b) % 5, 0u);
    // Touches counted, not reported.
    o.report_touch = false;
    const auto quiet = RunSelf(**db, o, &ss);
    RunSelf(**plain, o, &ps);
    ExpectSameCounts(ss, ps);
    EXPECT_GT(ss.unreported_touches, 0u);
    EXPECT_EQ(quiet.size(), got.size() - ss.unreported_touches);
    // The cap: what it leaves out is counted, and what it gives are pairs of the answer.
    o.report_touch = true;
    o.max_pairs = 7;
    const auto capped = RunSelf(**db, o, &ss);
    ASSERT_EQ(capped.size(), 7u);
    EXPECT_EQ(ss.reported_pairs, 7u);
    EXPECT_EQ(ss.capped_pairs, want.size() - 7);
    EXPECT_EQ(ss.hard + ss.touch + ss.clearance, want.size());
    for (const ClashPair& p : capped)
      EXPECT_TRUE(std::binary_search(want.begin(), want.end(), p, [](const ClashPair& x, const ClashPair& y) {
        return testing::PairKey(x) < testing::PairKey(y);
      }));
  }
}

TEST(ShardClashRuns, CollideAsUnshardedAndBruteForce) {
  Scene scene(PlantedAcrossCuts(800, 13, 2.0), BuildOptions::Backend::kHdf5);
  const Vec3d origin = ChooseStoreOrigin(scene.objs.front().mesh.Bounds());
  const auto stored = testing::StoredScene(scene.objs, origin);
  auto plain = Database::Open(scene.plain, {.cache_pages = 32});
  ASSERT_TRUE(plain.ok());
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> unit(0, 1);
  for (uint32_t k = 1; k <= 4; ++k) {
    auto db = Database::Open(scene.Sharded(k), {.cache_pages = 32});
    ASSERT_TRUE(db.ok());
    for (int q = 0; q < 12; ++q) {
      SCOPED_TRACE("shards " + std::to_string(k) + " probe " + std::to_string(q));
      const Mesh probe = BoxMesh(B(0, 0, 0, 1 + 10 * unit(rng), 1 + 4 * unit(rng), 1 + 3 * unit(rng)));
      const RigidTransform t = RigidTransform::FromEulerDegrees(
          30 * unit(rng), 0, 90 * unit(rng), {-10 + 130 * unit(rng), -5 + 50 * unit(rng), 25 * unit(rng)});
      ClashOptions o;
      o.clearance = q % 2 ? 0.1 : 0.0;
      o.threads = 2;
      ClashStats ps, ss;
      const auto want = Sorted(RunCollide(**plain, probe, t, o, &ps));
      const auto got = Sorted(RunCollide(**db, probe, t, o, &ss));
      ExpectSame(got, want);
      ExpectSameCounts(ss, ps);
      // Brute force: every stored object against the moved probe, in the store frame.
      Mesh moved = probe;
      for (size_t v = 0; v < moved.vertex_count(); ++v) {
        const Vec3d p =
            t.Apply({probe.vertices[3 * v], probe.vertices[3 * v + 1], probe.vertices[3 * v + 2]});
        for (int i = 0; i < 3; ++i) moved.vertices[3 * v + i] = p[i] - origin[i];
      }
      const ClashShape probe_shape(moved);
      const Box3d pb = moved.Bounds();
      uint64_t expected = 0;
      for (const auto& obj : stored) {
        bool meet = true;
        for (int i = 0; i < 3; ++i)
          meet = meet && double{obj.box.min[i]} - o.clearance <= pb.max[i] &&
                 pb.min[i] - o.clearance <= double{obj.box.max[i]};
        if (!meet) continue;
        const Separation s =
            Separate(ClashShape(obj.mesh), probe_shape,
                     std::max(o.clearance, std::nextafter(CoordinateResolution(obj.box), 1.0)), nullptr);
        const bool hit = s.meeting != Meeting::kApart || s.distance <= CoordinateResolution(obj.box) ||
                         s.distance < o.clearance;
        if (!hit) continue;
        ++expected;
        EXPECT_TRUE(std::any_of(got.begin(), got.end(), [&](const ClashPair& p) { return p.a == obj.id; }))
            << obj.id;
      }
      EXPECT_EQ(got.size(), expected);
    }
    // The cap, a probe far away (no shard reached: no page read) and a bad mesh.
    ClashOptions o;
    o.max_pairs = 2;
    const Mesh wide = BoxMesh(B(-10, -10, -10, 130, 60, 40));
    ClashStats ss;
    const auto capped = RunCollide(**db, wide, std::nullopt, o, &ss);
    EXPECT_EQ(capped.size(), 2u);
    EXPECT_EQ(ss.reported_pairs, 2u);
    EXPECT_EQ(ss.capped_pairs + 2, ss.hard + ss.touch + ss.clearance);
    EXPECT_GT(ss.capped_pairs, 100u);
    const auto far = RunCollide(**db, BoxMesh(B(1000, 1000, 1000, 1001, 1001, 1001)), std::nullopt, {}, &ss);
    EXPECT_TRUE(far.empty());
    EXPECT_EQ(ss.pages_read, 0u);
    EXPECT_GT(ss.store_pages, 0u);
    EXPECT_EQ((*db)->Collide(Mesh(), std::nullopt, {}, nullptr, nullptr).code(),
              Status::Code::kInvalidArgument);
  }
}

std::vector<SceneObject> Load(std::unique_ptr<SceneSource> src) {
  std::vector<SceneObject> objs;
  SceneObject o;
  while (*src->Next(&o)) objs.push_back(o);
  return objs;
}

// The tanker and the real scenes at K = 1..4: the unsharded store's pairs and brute force's.
void RealScene(std::vector<SceneObject> objs, double c, BuildOptions::Backend backend) {
  Scene scene(std::move(objs), backend, 4096);
  ClashOptions o;
  o.clearance = c;
  o.threads = 2;
  auto plain = Database::Open(scene.plain);
  ASSERT_TRUE(plain.ok());
  ClashStats ps;
  const auto want = Sorted(RunSelf(**plain, o, &ps));
  ExpectSame(want, Oracle(scene.objs, c, o.touch_tolerance));
  EXPECT_GT(want.size(), 0u);
  for (uint32_t k = 1; k <= 4; ++k) {
    SCOPED_TRACE("shards " + std::to_string(k));
    auto db = Database::Open(scene.Sharded(k));
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    ClashStats ss;
    ExpectSame(Sorted(RunSelf(**db, o, &ss)), want);
    ExpectSameCounts(ss, ps);
  }
}

TEST(ShardClashScenes, Tanker) {
  RealScene(Load(MakeTankerSource(4000, 1)), 0.01, BuildOptions::Backend::kPagedFile);
}
TEST(ShardClashScenes, TankerHdf5) {
  RealScene(Load(MakeTankerSource(3000, 2)), 0.0, BuildOptions::Backend::kHdf5);
}

void RealFile(const std::string& name, double c) {
  const std::string file = std::string(MKTREE_SHARED_DATA) + "/" + name;
  if (!std::filesystem::exists(file)) GTEST_SKIP() << file << " not found";
  auto src = OpenSceneFile(file);
  ASSERT_TRUE(src.ok());
  RealScene(Load(std::move(*src)), c, BuildOptions::Backend::kPagedFile);
}
TEST(ShardClashScenes, Steel) { RealFile("buildings/steel_mini_project.obj", 0.01); }
TEST(ShardClashScenes, Duplex) { RealFile("buildings/duplex.obj", 0.05); }

}  // namespace
}  // namespace mktree
