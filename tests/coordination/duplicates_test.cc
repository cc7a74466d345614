// The duplicates test against brute force: objects copied under other names and identities (in place, and
// moved by less and by more than the tolerance) are found exactly when every vertex agrees within the
// tolerance, whatever the names.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "coordination/coordination_fixtures.h"
#include "engine/coordination/duplicate_shapes.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::TempPath;

// Every vertex of each within `tol` (per axis) of some vertex of the other, and the same counts.
bool BruteSame(const Mesh& a, const Mesh& b, double tol) {
  if (a.vertex_count() != b.vertex_count() || a.triangle_count() != b.triangle_count()) return false;
  auto covered = [tol](const Mesh& x, const Mesh& y) {
    for (size_t i = 0; i < x.vertex_count(); ++i) {
      bool hit = false;
      for (size_t j = 0; j < y.vertex_count() && !hit; ++j) {
        double d = 0;
        for (int k = 0; k < 3; ++k) d = std::max(d, std::abs(x.vertices[3 * i + k] - y.vertices[3 * j + k]));
        hit = d <= tol;
      }
      if (!hit) return false;
    }
    return true;
  };
  return covered(a, b) && covered(b, a);
}

Mesh Moved(Mesh m, double dx) {
  for (size_t v = 0; v < m.vertex_count(); ++v) m.vertices[3 * v] += dx;
  return m;
}

TEST(Duplicates, AgainstBruteForce) {
  auto scene = testing::AttributedScene(400, 19);
  const double tol = 0.001;
  const size_t n = scene.size();
  for (size_t k = 0; k < 30; ++k) {
    SceneObject copy = scene[k * 13 % n];
    copy.name = "copy_" + std::to_string(k);
    copy.attributes = {{"ifc_global_id", "C" + std::to_string(k)}, {"ifc_type", "IfcBeam"}};
    if (k % 3 == 1) copy.mesh = Moved(copy.mesh, 0.0004);  // within the tolerance
    if (k % 3 == 2) copy.mesh = Moved(copy.mesh, 0.01);    // beyond it
    scene.push_back(copy);
  }
  for (size_t i = 0; i < scene.size(); ++i) scene[i].id = static_cast<ObjectId>(i);
  testing::BuildScene(scene, TempPath("dups.mkt"));
  auto db = testing::OpenStore(TempPath("dups.mkt"));
  const ClashRun run = testing::RunTests(
      *db,
      testing::Tests(
          R"({"tests": [{"name": "d", "a": {}, "mode": "duplicates", "tolerance": 0.001, "keep_spatial": true, "rules": []}]})"));
  std::set<std::pair<ObjectId, ObjectId>> got, want;
  for (const testing::RunRecord& r : testing::Records(run)) got.insert({r.pair.a, r.pair.b});
  // Brute force over the stored meshes (float32 in the store): every pair.
  std::vector<Mesh> stored;
  for (ObjectId i = 0; i < scene.size(); ++i) {
    auto m = db->ObjectGeometry(i);
    ASSERT_TRUE(m.ok());
    stored.push_back(*m);
  }
  for (ObjectId i = 0; i < scene.size(); ++i)
    for (ObjectId j = i + 1; j < scene.size(); ++j)
      if (BruteSame(stored[i], stored[j], tol)) want.insert({i, j});
  EXPECT_EQ(got, want);
  EXPECT_GE(want.size(), 20u);  // the copies in place and those moved within the tolerance
  EXPECT_EQ(run.tests[0].duplicates, want.size());
  EXPECT_EQ(run.tests[0].mode, "duplicates");
}

TEST(Duplicates, ShapeComparison) {
  const Mesh a = testing::BoxMesh(Box3d{{0, 0, 0}, {1, 2, 3}});
  double dev = 0;
  EXPECT_TRUE(coordination::SameShape(a, a, 0, &dev));
  EXPECT_EQ(dev, 0);
  EXPECT_TRUE(coordination::SameShape(a, Moved(a, 0.0005), 0.001, &dev));
  EXPECT_NEAR(dev, 0.0005, 1e-12);
  EXPECT_FALSE(coordination::SameShape(a, Moved(a, 0.002), 0.001, &dev));
  Mesh fewer = a;
  fewer.triangles.resize(fewer.triangles.size() - 3);
  EXPECT_FALSE(coordination::SameShape(a, fewer, 1, &dev));
  EXPECT_TRUE(coordination::BoxesCoincide(a.Bounds(), Moved(a, 0.0005).Bounds(), 0.001));
  EXPECT_FALSE(coordination::BoxesCoincide(a.Bounds(), Moved(a, 0.002).Bounds(), 0.001));
  EXPECT_FALSE(coordination::BoxesCoincide(Box3d(), a.Bounds(), 1));
}

}  // namespace
}  // namespace mktree
