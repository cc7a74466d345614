// Queries on the real scenes of ../shared/data against brute force: AABB mode on every file, exact mode
// on the closed meshes.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <random>

#include "engine/geometry/exact_geometry.h"
#include "engine/ingest/store_builder.h"
#include "mktree/database.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

std::vector<SceneObject> ReadAll(const std::string& path) {
  std::vector<SceneObject> objs;
  auto src = OpenSceneFile(path, 0);
  EXPECT_TRUE(src.ok()) << src.status().ToString();
  if (!src.ok()) return objs;
  SceneObject o;
  for (;;) {
    auto more = (*src)->Next(&o);
    EXPECT_TRUE(more.ok()) << more.status().ToString();
    if (!more.ok() || !*more) break;
    objs.push_back(o);
  }
  return objs;
}

struct RealScene {
  const char* file;
  bool exact;  // closed meshes: check exact mode too
};

class RealSceneTest : public ::testing::TestWithParam<RealScene> {};

TEST_P(RealSceneTest, QueriesMatchBruteForce) {
  const std::string file = std::string(MKTREE_SHARED_DATA) + "/" + GetParam().file;
  const auto objs = ReadAll(file);
  ASSERT_FALSE(objs.empty());
  const testing::TempDir dir("mktree_real");
  const std::string store = dir.file("scene.mkt");
  IngestOptions opts;
  opts.store.backend = GetParam().exact ? Backend::kPagedFile : Backend::kHdf5;
  auto report = BuildStore({[&](ObjectId first) { return OpenSceneFile(file, first); }}, store, opts);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->objects, objs.size());
  auto db = Database::Open(store, {.cache_pages = 32});
  ASSERT_TRUE(db.ok()) << db.status().ToString();

  Box3f all;
  for (const SceneObject& o : objs) all.Extend(o.Aabb());
  // Brute force over the geometry the store keeps, in its frame: one classifier per object, built once
  // (with its grid) for all queries.
  ASSERT_EQ(report->origin.x, 0);  // these scenes lie near 0: world and store frame agree
  ASSERT_EQ(report->origin.y, 0);
  ASSERT_EQ(report->origin.z, 0);
  const std::vector<testing::StoredObject> stored = testing::StoredScene(objs);
  std::vector<std::unique_ptr<SolidClassifier>> solid;
  SolidClassifierOptions many;
  many.expected_queries = 1000;
  for (const testing::StoredObject& o : stored)
    solid.push_back(std::make_unique<SolidClassifier>(o.mesh, many));
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> unit(0, 1);
  const int n = GetParam().exact ? 150 : 300;
  std::vector<ObjectId> expected;
  for (int i = 0; i < n; ++i) {
    Vec3d p;
    for (int a = 0; a < 3; ++a) p[a] = all.min[a] + unit(rng) * (all.max[a] - all.min[a]);
    Box3d box;
    const double side = (all.max[0] - all.min[0]) * std::pow(10.0, -3 + 2.5 * unit(rng));
    for (int a = 0; a < 3; ++a) {
      box.min[a] = p[a] - side / 2;
      box.max[a] = p[a] + side / 2;
    }
    for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
      if (mode == QueryMode::kExact && !GetParam().exact) continue;
      QueryResult r;
      ASSERT_TRUE((*db)->Run(Query::Point(p, mode), &r).ok());
      expected.clear();
      for (const testing::StoredObject& o : stored)
        if (o.box.Contains(p) && (mode == QueryMode::kAabb || solid[o.id]->Contains(p)))
          expected.push_back(o.id);
      ASSERT_EQ(r.hits, expected) << "point " << i;
      EXPECT_EQ(r.stats.hits, r.hits.size());
      ASSERT_TRUE((*db)->Run(Query::Box(box, mode), &r).ok());
      expected.clear();
      for (const testing::StoredObject& o : stored)
        if (o.box.Intersects(box) && (mode == QueryMode::kAabb || solid[o.id]->MeetsBox(box)))
          expected.push_back(o.id);
      ASSERT_EQ(r.hits, expected) << "box " << i;
      EXPECT_EQ(r.stats.cache_hits + r.stats.pages_read, r.stats.pages_touched);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, RealSceneTest,
    ::testing::Values(RealScene{"buildings/duplex.obj", false},
                      RealScene{"buildings/steel_mini_project.obj", false},
                      RealScene{"city/denhaag_01.obj", false}, RealScene{"ships/ContainerShip.ac", false},
                      RealScene{"ships/Freighter.ac", false}, RealScene{"ships/truman.ac", false},
                      RealScene{"meshes/fandisk.off", true}, RealScene{"meshes/3torus.off", true},
                      RealScene{"meshes/gearwheel.bin.stl", true}, RealScene{"meshes/armadillo.off", true}),
    [](const auto& info) {
      std::string name = info.param.file;
      for (char& c : name)
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
      return name;
    });

}  // namespace
}  // namespace mktree
