// Hidden objects (ClashPart::hidden) and the focus of a clash over several parts (MultiClashScope::focus):
// on random scenes split into parts with id maps, in both backends, a clash that hides objects gives the
// pairs of a store built without them, and a focused clash gives exactly the full clash's pairs that touch
// the focus, reading far fewer pages. The full clash is checked against brute force over the stored
// geometry first.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "clash/clash_oracle.h"
#include "engine/clash/clash_engine.h"
#include "engine/geometry/mesh_separation.h"
#include "engine/ingest/store_builder.h"
#include "engine/query/store_database.h"
#include "engine/scene/scene_source.h"
#include "engine/scene/vector_scene_source.h"
#include "engine/store_format/object_codec.h"
#include "query/scene_fixtures.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::BoxMesh;
using testing::ExpectSame;
using testing::OracleClass;
using testing::Sorted;

using testing::TempPath;

// A clustered scene; every fifth object's name puts it in one of seven groups ("grp3/...").
std::vector<SceneObject> Scene(size_t n, uint64_t seed) {
  std::vector<SceneObject> objs = testing::ClusteredScene(n, seed);
  for (size_t i = 0; i < objs.size(); ++i) {
    objs[i].id = static_cast<ObjectId>(i);
    if (i % 5 == 0) objs[i].name = "grp" + std::to_string(i % 7) + "/" + objs[i].name;
  }
  return objs;
}

// Builds the objects (ids by position) into `path` with small pages (many leaves).
void BuildSmallPages(const std::vector<SceneObject>& objs, const std::string& path, Backend backend) {
  IngestOptions o;
  o.store.backend = backend;
  o.store.params.block_size = 512;
  o.store.params.blocks_per_page = 2;
  std::vector<SceneOpener> in{[&objs](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(new VectorSceneSource(&objs, first));
  }};
  auto r = BuildStore(in, path, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
}

std::unique_ptr<StoreDatabase> Open(const std::string& path, uint64_t cache_pages) {
  auto reader = StoreReader::Open(path);
  EXPECT_TRUE(reader.ok()) << reader.status().ToString();
  if (!reader.ok()) return nullptr;
  return OpenStoreDatabase(std::move(*reader), {.cache_pages = cache_pages});
}

// A store of some of a scene's objects, with the global id of each of its objects.
struct PartStore {
  std::unique_ptr<StoreDatabase> db;
  std::vector<ObjectId> ids;  // increasing
};

// Builds scene[ids[0]], scene[ids[1]], ... (ids increasing) into one store.
PartStore BuildPart(const std::vector<SceneObject>& scene, std::vector<ObjectId> ids, const std::string& name,
                    Backend backend, uint64_t cache_pages = 4096) {
  std::vector<SceneObject> objs;
  for (ObjectId g : ids) objs.push_back(scene[g]);
  const std::string path = TempPath(name + "_" + BackendName(backend));
  BuildSmallPages(objs, path, backend);
  return {Open(path, cache_pages), std::move(ids)};
}

std::vector<ClashPair> Clash(const std::vector<ClashPart>& parts, const MultiClashScope& scope,
                             const ClashOptions& o, ClashStats* stats = nullptr) {
  std::vector<ClashPair> got;
  const Status st = RunMultiClash(
      parts, scope, o, [&](const ClashPair& p) { got.push_back(p); }, stats);
  EXPECT_TRUE(st.ok()) << st.ToString();
  return Sorted(std::move(got));
}

std::vector<ClashPair> Collide(const ClashPart& part, const Mesh& mesh, const ClashOptions& o,
                               ClashStats* stats) {
  std::vector<ClashPair> got;
  const Status st = RunCollide(
      part, mesh, std::nullopt, o, [&](const ClashPair& p) { got.push_back(p); }, stats);
  EXPECT_TRUE(st.ok()) << st.ToString();
  return Sorted(std::move(got));
}

// Brute force over the stored geometry: every pair whose stored boxes grown by c meet, classified by
// docs/clash.md §1's rules (tests/clash/clash_oracle.h).
std::vector<ClashPair> BruteForce(const std::vector<SceneObject>& scene, double c, double t) {
  const Vec3d origin = ChooseStoreOrigin(scene.front().mesh.Bounds());
  const auto objects = testing::StoredScene(scene, origin);
  std::vector<std::unique_ptr<ClashShape>> shapes;
  for (size_t i = 0; i < objects.size(); ++i)
    shapes.push_back(testing::StoredShape(scene[i].mesh, objects[i].mesh));
  std::vector<ClashPair> out;
  for (size_t i = 0; i < objects.size(); ++i) {
    for (size_t j = i + 1; j < objects.size(); ++j) {
      const Box3f& a = objects[i].box;
      const Box3f& b = objects[j].box;
      bool meet = true;
      for (int ax = 0; ax < 3; ++ax)
        meet = meet && double{a.min[ax]} - c <= b.max[ax] && double{b.min[ax]} - c <= a.max[ax];
      if (!meet) continue;
      const double r = CoordinateResolution(a) + CoordinateResolution(b);
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

// The pairs of `all` that `keep` accepts.
template <typename Keep>
std::vector<ClashPair> Where(const std::vector<ClashPair>& all, Keep keep) {
  std::vector<ClashPair> out;
  for (const ClashPair& p : all)
    if (keep(p)) out.push_back(p);
  return out;
}

std::vector<ObjectId> Iota(size_t n) {
  std::vector<ObjectId> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = static_cast<ObjectId>(i);
  return v;
}

// The counts a clash's pairs decide: equal for two runs that test the same object pairs.
void ExpectSamePairCounts(const ClashStats& got, const ClashStats& want) {
  EXPECT_EQ(got.candidate_pairs, want.candidate_pairs);
  EXPECT_EQ(got.excluded_pairs, want.excluded_pairs);
  EXPECT_EQ(got.hard, want.hard);
  EXPECT_EQ(got.touch, want.touch);
  EXPECT_EQ(got.clearance, want.clearance);
  EXPECT_EQ(got.reported_pairs, want.reported_pairs);
}

class ClashFocusBackends : public ::testing::TestWithParam<Backend> {};

// Hiding a random fifth of the objects gives the full clash's pairs without them, and exactly the clash
// (pairs, fields and pair counts) of a store built without them; with group exclusions too.
TEST_P(ClashFocusBackends, HiddenObjectsAreAbsent) {
  const auto scene = Scene(1500, 3);
  const PartStore full = BuildPart(scene, Iota(scene.size()), "hidden_full", GetParam());
  std::mt19937_64 rng(4);
  std::vector<bool> hidden(scene.size(), false);
  std::vector<ObjectId> visible;
  for (size_t i = 0; i < scene.size(); ++i) {
    hidden[i] = rng() % 5 == 0;
    if (!hidden[i]) visible.push_back(static_cast<ObjectId>(i));
  }
  const PartStore reduced = BuildPart(scene, visible, "hidden_reduced", GetParam());
  for (bool groups : {false, true}) {
    SCOPED_TRACE(groups ? "group exclusions" : "no exclusions");
    ClashOptions o;
    o.clearance = 0.05;
    if (groups) o.exclude_group_separator = "/";
    ClashStats sf, sh, sr;
    const auto all = Clash({ClashPart{&full.db->leaves()}}, {}, o, &sf);
    if (!groups) ExpectSame(all, BruteForce(scene, o.clearance, o.touch_tolerance));
    const auto got = Clash({ClashPart{&full.db->leaves(), nullptr, &hidden}}, {}, o, &sh);
    const auto want = Where(all, [&](const ClashPair& p) { return !hidden[p.a] && !hidden[p.b]; });
    ASSERT_LT(want.size(), all.size());
    ASSERT_FALSE(want.empty());
    ExpectSame(got, want);
    const auto built = Clash({ClashPart{&reduced.db->leaves(), &reduced.ids}}, {}, o, &sr);
    ExpectSame(built, want);
    ExpectSamePairCounts(sh, sr);
    if (groups) {
      EXPECT_GT(sh.excluded_pairs, 0u);
    }
    EXPECT_LE(sh.shapes_prepared, visible.size());  // no hidden object is decoded
  }
}

// Collide over one part: its hidden objects are no candidates, and pairs carry global ids.
TEST_P(ClashFocusBackends, CollideOverAPartHidesAndMapsIds) {
  const auto scene = Scene(1200, 5);
  std::mt19937_64 rng(6);
  std::vector<ObjectId> ids;  // a part holding about half the scene, under its global ids
  for (size_t i = 0; i < scene.size(); ++i)
    if (rng() % 2) ids.push_back(static_cast<ObjectId>(i));
  const PartStore part = BuildPart(scene, ids, "collide_part", GetParam());
  std::vector<bool> hidden(ids.size(), false);
  std::vector<ObjectId> visible;
  for (size_t k = 0; k < ids.size(); ++k) {
    hidden[k] = rng() % 4 == 0;
    if (!hidden[k]) visible.push_back(ids[k]);
  }
  const PartStore reduced = BuildPart(scene, visible, "collide_reduced", GetParam());
  Box3d box;  // the middle of the scene
  box.min = {30, 5, 2};
  box.max = {70, 30, 15};
  const Mesh probe = BoxMesh(box);
  ClashOptions o;
  o.clearance = 0.1;
  ClashStats s_all, s_hidden, s_reduced;
  const auto all = Collide(ClashPart{&part.db->leaves(), &part.ids}, probe, o, &s_all);
  const auto got = Collide(ClashPart{&part.db->leaves(), &part.ids, &hidden}, probe, o, &s_hidden);
  const auto want = Collide(ClashPart{&reduced.db->leaves(), &reduced.ids}, probe, o, &s_reduced);
  const std::set<ObjectId> part_ids(ids.begin(), ids.end()), shown(visible.begin(), visible.end());
  for (const ClashPair& p : all) EXPECT_TRUE(part_ids.count(p.a)) << p.a;  // global ids
  ASSERT_LT(want.size(), all.size());
  ASSERT_FALSE(want.empty());
  ExpectSame(want, Where(all, [&](const ClashPair& p) { return shown.count(p.a) > 0; }));
  ExpectSame(got, want);
  ExpectSamePairCounts(s_hidden, s_reduced);
}

// A focus over three parts gives exactly the full clash's pairs with an object in it, for an empty focus,
// one object, a random 5 %, everything, and ids in no part, repeated and out of order.
TEST_P(ClashFocusBackends, FocusGivesThePairsTouchingIt) {
  const auto scene = Scene(1500, 7);
  std::mt19937_64 rng(8);
  std::vector<ObjectId> split[3];
  for (size_t i = 0; i < scene.size(); ++i) split[rng() % 3].push_back(static_cast<ObjectId>(i));
  std::vector<PartStore> stores;
  for (int k = 0; k < 3; ++k)
    stores.push_back(BuildPart(scene, split[k], "focus_part" + std::to_string(k), GetParam()));
  std::vector<ClashPart> parts;
  for (const PartStore& s : stores) parts.push_back(ClashPart{&s.db->leaves(), &s.ids});
  const PartStore whole = BuildPart(scene, Iota(scene.size()), "focus_whole", GetParam());
  ClashOptions o;
  o.clearance = 0.05;
  o.exclude_group_separator = "/";
  ClashStats s_all;
  const auto all = Clash(parts, {}, o, &s_all);
  ExpectSame(Clash({ClashPart{&whole.db->leaves()}}, {}, o), all);
  ASSERT_GT(all.size(), 100u);

  std::vector<ObjectId> five;
  for (size_t i = 0; i < scene.size(); ++i)
    if (rng() % 20 == 0) five.push_back(static_cast<ObjectId>(i));
  std::shuffle(five.begin(), five.end(), rng);
  five.push_back(five.front());                             // a repeat
  five.push_back(static_cast<ObjectId>(scene.size() + 9));  // in no part
  const std::vector<std::vector<ObjectId>> focuses{{}, {all[all.size() / 2].a}, five, Iota(scene.size())};
  for (const auto& f : focuses) {
    SCOPED_TRACE("focus of " + std::to_string(f.size()));
    const std::set<ObjectId> in(f.begin(), f.end());
    ClashStats s;
    const auto got = Clash(parts, {nullptr, &f}, o, &s);
    const auto want = Where(all, [&](const ClashPair& p) { return in.count(p.a) || in.count(p.b); });
    ExpectSame(got, want);
    EXPECT_EQ(s.reported_pairs, want.size());
    if (f.size() >= scene.size()) {
      ExpectSamePairCounts(s, s_all);
      EXPECT_EQ(s.leaf_pairs_visited, s_all.leaf_pairs_visited);
    } else {
      EXPECT_LT(s.candidate_pairs, s_all.candidate_pairs);
    }
    if (f.empty()) {
      EXPECT_EQ(s.leaf_reads, 0u);
      EXPECT_EQ(s.pages_touched, 0u);
    }
  }
  // With the part pairs limited too: both limits hold.
  const ClashPartPairs across = [](uint32_t i, uint32_t j) { return i != j; };
  const auto got = Clash(parts, {across, &five}, o);
  std::vector<int> part_of(scene.size());
  for (int k = 0; k < 3; ++k)
    for (ObjectId g : split[k]) part_of[g] = k;
  const std::set<ObjectId> in(five.begin(), five.end());
  ExpectSame(got, Where(all, [&](const ClashPair& p) {
               return part_of[p.a] != part_of[p.b] && (in.count(p.a) || in.count(p.b));
             }));
}

// A revision as the living store keeps it: the base store with its removed and replaced objects hidden,
// plus a delta store of the replacements (same ids, moved) and the added objects (new ids). Its clash is
// the clash of a store built from the live objects, and the clash focused on the changed ids is that
// clash's pairs touching them.
TEST_P(ClashFocusBackends, RevisionOfBaseAndDelta) {
  auto scene = Scene(1500, 9);
  const size_t n = scene.size();
  const PartStore base = BuildPart(scene, Iota(n), "rev_base", GetParam());
  std::mt19937_64 rng(10);
  std::vector<bool> hidden(n, false);
  std::vector<ObjectId> changed, delta_ids;
  auto live = scene;  // by global id; removed ones get an empty name and are left out below
  std::vector<bool> gone(n, false);
  for (size_t i = 0; i < n; ++i) {
    const uint64_t r = rng() % 40;
    if (r == 0) {  // removed
      hidden[i] = gone[i] = true;
      changed.push_back(static_cast<ObjectId>(i));
    } else if (r == 1) {  // replaced: moved by (0.5, 0.25, 0)
      hidden[i] = true;
      changed.push_back(static_cast<ObjectId>(i));
      delta_ids.push_back(static_cast<ObjectId>(i));
      for (size_t v = 0; v < live[i].mesh.vertices.size(); v += 3) {
        live[i].mesh.vertices[v] += 0.5;
        live[i].mesh.vertices[v + 1] += 0.25;
      }
    }
  }
  for (int k = 0; k < 30; ++k) {  // added: copies of existing objects moved by (0.125, 0, 0.125)
    SceneObject o = scene[rng() % n];
    for (size_t v = 0; v < o.mesh.vertices.size(); v += 3) {
      o.mesh.vertices[v] += 0.125;
      o.mesh.vertices[v + 2] += 0.125;
    }
    o.name = "added" + std::to_string(k);
    changed.push_back(static_cast<ObjectId>(live.size()));
    delta_ids.push_back(static_cast<ObjectId>(live.size()));
    live.push_back(std::move(o));
    gone.push_back(false);
  }
  const PartStore delta = BuildPart(live, delta_ids, "rev_delta", GetParam());
  std::vector<ObjectId> live_ids;
  for (size_t g = 0; g < live.size(); ++g)
    if (!gone[g]) live_ids.push_back(static_cast<ObjectId>(g));
  const PartStore fresh = BuildPart(live, live_ids, "rev_fresh", GetParam());

  ClashOptions o;
  o.clearance = 0.05;
  o.exclude_group_separator = "/";
  const std::vector<ClashPart> revision{ClashPart{&base.db->leaves(), nullptr, &hidden},
                                        ClashPart{&delta.db->leaves(), &delta.ids}};
  ClashStats s_rev, s_fresh;
  const auto want = Clash({ClashPart{&fresh.db->leaves(), &fresh.ids}}, {}, o, &s_fresh);
  ExpectSame(Clash(revision, {}, o, &s_rev), want);
  ExpectSamePairCounts(s_rev, s_fresh);
  const std::set<ObjectId> in(changed.begin(), changed.end());
  const auto touching = Where(want, [&](const ClashPair& p) { return in.count(p.a) || in.count(p.b); });
  ASSERT_FALSE(touching.empty());
  ExpectSame(Clash(revision, {nullptr, &changed}, o), touching);
}

INSTANTIATE_TEST_SUITE_P(Both, ClashFocusBackends, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

// A focus of five objects in a scene of a few thousand reads a small share of the pages the full clash
// reads: the leaves holding them and their neighbours', not the scene's.
TEST(ClashFocus, ReadsInProportionToTheFocus) {
  const auto scene = Scene(4000, 11);
  const PartStore whole = BuildPart(scene, Iota(scene.size()), "pages_whole", Backend::kPagedFile, 0);
  ClashOptions o;
  o.clearance = 0.05;
  ClashStats s_all;
  const auto all = Clash({ClashPart{&whole.db->leaves()}}, {}, o, &s_all);
  std::mt19937_64 rng(12);
  for (int trial = 0; trial < 3; ++trial) {
    std::vector<ObjectId> f;
    for (int k = 0; k < 5; ++k) f.push_back(static_cast<ObjectId>(rng() % scene.size()));
    const std::set<ObjectId> in(f.begin(), f.end());
    ClashStats s;
    ExpectSame(Clash({ClashPart{&whole.db->leaves()}}, {nullptr, &f}, o, &s),
               Where(all, [&](const ClashPair& p) { return in.count(p.a) || in.count(p.b); }));
    EXPECT_LT(2 * s.pages_read, s_all.pages_read);
    EXPECT_LT(2 * s.distinct_pages, s_all.distinct_pages);
    EXPECT_LT(4 * s.leaf_pairs_tree, s_all.leaf_pairs_tree);  // the traversal keeps near the focus
    EXPECT_LT(4 * s.leaf_pairs_visited, s_all.leaf_pairs_visited);
    if (trial == 0)
      std::printf("full: %llu pages read, %llu leaf pairs; focus of 5: %llu pages read, %llu leaf pairs\n",
                  static_cast<unsigned long long>(s_all.pages_read),
                  static_cast<unsigned long long>(s_all.leaf_pairs_visited),
                  static_cast<unsigned long long>(s.pages_read),
                  static_cast<unsigned long long>(s.leaf_pairs_visited));
    EXPECT_LT(4 * s.shapes_prepared, s_all.shapes_prepared);
  }
}

// A focus with a partner set (a set against a set): exactly the full clash's pairs with one object in
// each set, over parts and over one store, reading fewer pages than a focus on either set alone.
TEST(ClashFocus, PartnerSetGivesThePairsBetweenTheSets) {
  const auto scene = Scene(3000, 21);
  const PartStore whole = BuildPart(scene, Iota(scene.size()), "partner_whole", Backend::kPagedFile, 0);
  std::mt19937_64 rng(22);
  std::vector<ObjectId> split[2];
  for (size_t i = 0; i < scene.size(); ++i) split[rng() % 2].push_back(static_cast<ObjectId>(i));
  std::vector<PartStore> stores;
  for (int k = 0; k < 2; ++k)
    stores.push_back(BuildPart(scene, split[k], "partner_part" + std::to_string(k), Backend::kPagedFile, 0));
  std::vector<ClashPart> parts;
  for (const PartStore& ps : stores) parts.push_back(ClashPart{&ps.db->leaves(), &ps.ids});
  ClashOptions o;
  o.clearance = 0.05;
  ClashStats s_all;
  const auto all = Clash({ClashPart{&whole.db->leaves()}}, {}, o, &s_all);
  ASSERT_GT(all.size(), 100u);
  // A: ids in one x band (5 %), B: 20 % spread at random, overlapping A in a few objects.
  std::vector<ObjectId> a, b;
  for (size_t i = 0; i < scene.size(); ++i) {
    if (scene[i].mesh.Bounds().min[0] < 30 && rng() % 4 == 0) a.push_back(static_cast<ObjectId>(i));
    if (rng() % 5 == 0) b.push_back(static_cast<ObjectId>(i));
  }
  const std::set<ObjectId> in_a(a.begin(), a.end()), in_b(b.begin(), b.end());
  auto between = [&](const ClashPair& p) {
    return (in_a.count(p.a) && in_b.count(p.b)) || (in_b.count(p.a) && in_a.count(p.b));
  };
  const auto want = Where(all, between);
  ASSERT_GT(want.size(), 5u);
  ClashStats s_ab, s_ba, s_a, s_b;
  ExpectSame(Clash({ClashPart{&whole.db->leaves()}}, {nullptr, &a, &b}, o, &s_ab), want);
  ExpectSame(Clash({ClashPart{&whole.db->leaves()}}, {nullptr, &b, &a}, o, &s_ba), want);
  ExpectSame(Clash(parts, {nullptr, &a, &b}, o), want);
  // A against itself.
  ExpectSame(Clash({ClashPart{&whole.db->leaves()}}, {nullptr, &a, &a}, o),
             Where(all, [&](const ClashPair& p) { return in_a.count(p.a) && in_a.count(p.b); }));
  Clash({ClashPart{&whole.db->leaves()}}, {nullptr, &a}, o, &s_a);
  Clash({ClashPart{&whole.db->leaves()}}, {nullptr, &b}, o, &s_b);
  EXPECT_EQ(s_ab.pages_read, s_ba.pages_read);
  EXPECT_LT(s_ab.pages_read, s_a.pages_read);
  EXPECT_LT(s_ab.pages_read, s_b.pages_read);
  EXPECT_LT(s_ab.leaf_pairs_visited, s_a.leaf_pairs_visited);
  EXPECT_LT(s_ab.candidate_pairs, s_a.candidate_pairs);
  EXPECT_LT(s_ab.pages_read, s_all.pages_read);
  std::printf(
      "full: %llu pages read; focus A: %llu; focus B: %llu; A x B: %llu\n",
      static_cast<unsigned long long>(s_all.pages_read), static_cast<unsigned long long>(s_a.pages_read),
      static_cast<unsigned long long>(s_b.pages_read), static_cast<unsigned long long>(s_ab.pages_read));
  // A partner without a focus is refused.
  const Status st = RunMultiClash(
      {ClashPart{&whole.db->leaves()}}, {nullptr, nullptr, &b}, o, [](const ClashPair&) {}, nullptr);
  EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
}

// Bad hidden flags are an error, not a read past their end.
TEST(ClashFocus, HiddenFlagsOfTheWrongSizeAreAnError) {
  const auto scene = Scene(200, 13);
  const PartStore whole = BuildPart(scene, Iota(scene.size()), "bad_hidden", Backend::kPagedFile);
  const std::vector<bool> short_flags(scene.size() - 1, false);
  const Status st = RunMultiClash(
      {ClashPart{&whole.db->leaves(), nullptr, &short_flags}}, MultiClashScope{}, ClashOptions{},
      [](const ClashPair&) {}, nullptr);
  EXPECT_EQ(st.code(), Status::Code::kInternal) << st.ToString();
  const Status collide = RunCollide(
      ClashPart{&whole.db->leaves(), nullptr, &short_flags}, BoxMesh(whole.db->bounds()), std::nullopt,
      ClashOptions{}, [](const ClashPair&) {}, nullptr);
  EXPECT_EQ(collide.code(), Status::Code::kInternal) << collide.ToString();
}

}  // namespace
}  // namespace mktree
