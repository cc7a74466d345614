// The solid classifier on the real meshes in MKTREE_SHARED_DATA/meshes, against references that share
// no code with it: the winding number (solid angles) and plain double ray parity in random directions.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "engine/geometry/solid_classifier.h"
#include "engine/geometry/triangle_box.h"
#include "geometry/mesh_files.h"
#include "geometry/test_meshes.h"

namespace mktree {
namespace {

using testing::Diagonal;
using testing::Grown;
using testing::Queries;
using testing::RandomIn;
using testing::SurfaceDistance;
using testing::VertexOf;

struct Case {
  const char* file;
  int random_points;
};

class ClosedMeshTest : public ::testing::TestWithParam<Case> {};

TEST_P(ClosedMeshTest, RandomPointsAgreeWithTwoReferences) {
  auto mesh = testing::ReadSharedMesh(GetParam().file);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const Mesh& m = *mesh;
  const SolidClassifier brute(m, Queries(1));
  const SolidClassifier grid(m, Queries(1000));
  ASSERT_EQ(brute.method(), SolidClassifier::Method::kRayParity);
  const Box3d region = Grown(m.Bounds(), 0.05);
  std::mt19937_64 rng(11);
  int in = 0, out = 0;
  for (int it = 0; it < GetParam().random_points; ++it) {
    const Vec3d p = RandomIn(region, rng);
    const bool got = grid.Contains(p);
    ASSERT_EQ(brute.Contains(p), got);
    if (SurfaceDistance(m, p) <= grid.tolerance()) continue;  // on the surface: tested below
    const double w = WindingNumber(m, p);
    ASSERT_LT(std::fabs(std::fabs(w) - std::round(std::fabs(w))), 1e-6) << "closed mesh, w = " << w;
    ASSERT_EQ(got, std::fabs(w) >= 0.5) << p.x << " " << p.y << " " << p.z << " w = " << w;
    ASSERT_EQ(got, testing::InsideVotes(m, p, 5, rng) >= 3) << p.x << " " << p.y << " " << p.z;
    (got ? in : out)++;
  }
  EXPECT_GT(in, GetParam().random_points / 20);
  EXPECT_GT(out, GetParam().random_points / 20);
}

// Points on faces, edges and vertices are inside; 1e-6 off along the face normal they are whatever
// the winding number says (1e-6 exceeds the tolerance of these meshes, and near a concave edge or
// vertex "off the face" can be inside).
TEST_P(ClosedMeshTest, PointsOnAndNearTheSurface) {
  auto mesh = testing::ReadSharedMesh(GetParam().file);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const Mesh& m = *mesh;
  const SolidClassifier sc(m, Queries(1000));
  ASSERT_LT(sc.tolerance(), 1e-6);
  std::mt19937_64 rng(12);
  std::uniform_int_distribution<size_t> pick(0, m.triangle_count() - 1);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  int in = 0, out = 0;
  for (int it = 0; it < 60; ++it) {
    const uint32_t* t = &m.triangles[3 * pick(rng)];
    const Vec3d a = VertexOf(m, t[0]), b = VertexOf(m, t[1]), c = VertexOf(m, t[2]);
    Vec3d n{(b.y - a.y) * (c.z - a.z) - (b.z - a.z) * (c.y - a.y),
            (b.z - a.z) * (c.x - a.x) - (b.x - a.x) * (c.z - a.z),
            (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)};
    const double len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    if (len == 0) continue;
    n = {n.x / len, n.y / len, n.z / len};
    double s = u(rng), r = u(rng);
    if (s + r > 1) s = 1 - s, r = 1 - r;
    const Vec3d face{a.x + s * (b.x - a.x) + r * (c.x - a.x), a.y + s * (b.y - a.y) + r * (c.y - a.y),
                     a.z + s * (b.z - a.z) + r * (c.z - a.z)};
    const Vec3d edge{(a.x + b.x) / 2, (a.y + b.y) / 2, (a.z + b.z) / 2};
    for (const Vec3d& base : {face, edge, a}) {
      ASSERT_TRUE(sc.Contains(base));
      for (double off : {1e-6, -1e-6}) {
        const Vec3d p{base.x + off * n.x, base.y + off * n.y, base.z + off * n.z};
        const bool want = SurfaceDistance(m, p) <= sc.tolerance() || std::fabs(WindingNumber(m, p)) >= 0.5;
        ASSERT_EQ(sc.Contains(p), want) << GetParam().file << " off " << off;
        (want ? in : out)++;
      }
    }
  }
  EXPECT_GT(in, 60);
  EXPECT_GT(out, 60);
}

TEST_P(ClosedMeshTest, BoxInsideTheSolidAndRandomBoxes) {
  auto mesh = testing::ReadSharedMesh(GetParam().file);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const Mesh& m = *mesh;
  const SolidClassifier sc(m, Queries(1000));
  std::mt19937_64 rng(13);
  const Box3d bounds = m.Bounds();
  const double diag = Diagonal(bounds);
  auto any_triangle_meets = [&](const Box3d& box) {
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      const uint32_t* i = &m.triangles[3 * t];
      if (TriangleMeetsBox(VertexOf(m, i[0]), VertexOf(m, i[1]), VertexOf(m, i[2]), box)) return true;
    }
    return false;
  };
  // A box strictly inside the solid, touching no triangle: found through the corner test.
  bool found_inner = false;
  for (int it = 0; it < 2000 && !found_inner; ++it) {
    const Vec3d p = RandomIn(bounds, rng);
    const double d = SurfaceDistance(m, p);
    if (d < 0.01 * diag || !sc.Contains(p)) continue;
    const double h = d / 2;
    Box3d box;
    box.min = {p.x - h, p.y - h, p.z - h};
    box.max = {p.x + h, p.y + h, p.z + h};
    ASSERT_FALSE(any_triangle_meets(box));
    EXPECT_TRUE(sc.MeetsBox(box));
    EXPECT_TRUE(MeshMeetsBox(m, box));
    found_inner = true;
  }
  EXPECT_TRUE(found_inner);
  // Random boxes: some triangle meets, or (none does) the centre's winding number decides.
  for (int it = 0; it < 100; ++it) {
    const Vec3d c = RandomIn(Grown(bounds, 0.05), rng);
    const double h = 0.02 * diag * std::uniform_real_distribution<double>(0, 1)(rng);
    Box3d box;
    box.min = {c.x - h, c.y - h, c.z - h};
    box.max = {c.x + h, c.y + h, c.z + h};
    const bool surface = any_triangle_meets(box);
    if (!surface && SurfaceDistance(m, {box.min[0], box.min[1], box.min[2]}) <= sc.tolerance()) continue;
    const bool want = surface || std::fabs(WindingNumber(m, c)) >= 0.5;
    ASSERT_EQ(sc.MeetsBox(box), want);
  }
}

INSTANTIATE_TEST_SUITE_P(RealMeshes, ClosedMeshTest,
                         ::testing::Values(Case{"3torus.off", 3000}, Case{"gearwheel.bin.stl", 600},
                                           Case{"fandisk.off", 300}, Case{"armadillo.off", 120}),
                         [](const auto& info) {
                           std::string n = info.param.file;
                           return n.substr(0, n.find('.'));
                         });

// The open bunny: classified by |winding number| >= 1/2 plus surface contact (see solid_classifier.h).
TEST(OpenBunnyTest, SurfaceFarOutsideNearSurfaceAndDeepInside) {
  auto mesh = testing::ReadSharedMesh("bunny.bin.stl");
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const Mesh& m = *mesh;
  const SolidClassifier sc(m);
  ASSERT_EQ(sc.method(), SolidClassifier::Method::kWindingNumber);
  const Box3d bounds = m.Bounds();
  const double diag = Diagonal(bounds);
  std::mt19937_64 rng(14);

  // Far outside: beyond the bounds.
  for (int it = 0; it < 20; ++it) {
    Vec3d p = RandomIn(bounds, rng);
    p[it % 3] = it % 2 ? bounds.max[it % 3] + 0.1 * diag : bounds.min[it % 3] - 0.1 * diag;
    ASSERT_FALSE(sc.Contains(p));
  }
  // Orientation of the scan (outward or not), from the signed volume.
  double volume6 = 0;
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    const uint32_t* i = &m.triangles[3 * t];
    const Vec3d a = VertexOf(m, i[0]), b = VertexOf(m, i[1]), c = VertexOf(m, i[2]);
    volume6 += a.x * (b.y * c.z - b.z * c.y) + a.y * (b.z * c.x - b.x * c.z) + a.z * (b.x * c.y - b.y * c.x);
  }
  const double outward = volume6 > 0 ? 1 : -1;
  // On the surface; and 1e-4 x diagonal off a face, away from the holes: inside / outside.
  std::uniform_int_distribution<size_t> pick(0, m.triangle_count() - 1);
  int tested = 0;
  for (int it = 0; it < 60; ++it) {
    const uint32_t* i = &m.triangles[3 * pick(rng)];
    const Vec3d a = VertexOf(m, i[0]), b = VertexOf(m, i[1]), c = VertexOf(m, i[2]);
    const Vec3d g{(a.x + b.x + c.x) / 3, (a.y + b.y + c.y) / 3, (a.z + b.z + c.z) / 3};
    ASSERT_TRUE(sc.Contains(g));
    ASSERT_TRUE(sc.Contains(a));
    Vec3d n{(b.y - a.y) * (c.z - a.z) - (b.z - a.z) * (c.y - a.y),
            (b.z - a.z) * (c.x - a.x) - (b.x - a.x) * (c.z - a.z),
            (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)};
    const double len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    if (len == 0) continue;
    const double off = 1e-4 * diag * outward / len;
    const Vec3d in_p{g.x - off * n.x, g.y - off * n.y, g.z - off * n.z};
    const Vec3d out_p{g.x + off * n.x, g.y + off * n.y, g.z + off * n.z};
    // Only where the scan is locally clean (the offset points are nearest to this face) and the
    // winding number is near-integer (far from the holes).
    if (SurfaceDistance(m, in_p) < 0.9e-4 * diag || SurfaceDistance(m, out_p) < 0.9e-4 * diag) continue;
    if (std::fabs(WindingNumber(m, in_p) - std::round(WindingNumber(m, in_p))) > 0.2) continue;
    EXPECT_TRUE(sc.Contains(in_p));
    EXPECT_FALSE(sc.Contains(out_p));
    ++tested;
  }
  EXPECT_GT(tested, 30);

  // Deep inside and far outside within the bounds: where rays in 9 random directions agree
  // unanimously (no hole in sight), the classifier agrees with them.
  int unanimous = 0, inside = 0;
  const int points = 120;
  for (int it = 0; it < points; ++it) {
    const Vec3d p = RandomIn(bounds, rng);
    if (SurfaceDistance(m, p) < 0.01 * diag) continue;
    const int votes = testing::InsideVotes(m, p, 9, rng);
    if (votes != 0 && votes != 9) continue;
    ++unanimous;
    inside += votes == 9;
    ASSERT_EQ(sc.Contains(p), votes == 9) << p.x << " " << p.y << " " << p.z;
  }
  EXPECT_GT(unanimous, points / 2);
  EXPECT_GT(inside, 5);
}

}  // namespace
}  // namespace mktree
