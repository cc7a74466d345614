#include "engine/geometry/solid_classifier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "engine/geometry/triangle_box.h"
#include "geometry/test_meshes.h"

namespace mktree {
namespace {

using testing::BoxMesh;
using testing::MakeBox;
using testing::Queries;
using testing::RandomIn;

Vec3d Add(const Vec3d& a, const Vec3d& d, double s) { return {a.x + s * d.x, a.y + s * d.y, a.z + s * d.z}; }

Vec3d Normalized(const Vec3d& v) {
  const double l = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return {v.x / l, v.y / l, v.z / l};
}

// Checks a convex mesh at `base` (a point on the surface) with outward direction `out`: on the surface
// and 1e-6 inside are inside, 1e-6 outside is outside; both the one-shot and the classifier forms.
void ExpectSurfaceBand(const Mesh& m, const SolidClassifier& sc, const Vec3d& base, const Vec3d& out) {
  const Vec3d n = Normalized(out);
  EXPECT_TRUE(sc.Contains(base)) << base.x << " " << base.y << " " << base.z;
  EXPECT_TRUE(sc.Contains(Add(base, n, -1e-6))) << base.x << " " << base.y << " " << base.z;
  EXPECT_FALSE(sc.Contains(Add(base, n, 1e-6))) << base.x << " " << base.y << " " << base.z;
  // Within the tolerance outside is still "on the surface".
  EXPECT_TRUE(sc.Contains(Add(base, n, 0.5 * sc.tolerance())));
  EXPECT_FALSE(sc.Contains(Add(base, n, 3 * sc.tolerance())));
  EXPECT_TRUE(PointInSolid(m, base));
  EXPECT_FALSE(PointInSolid(m, Add(base, n, 1e-6)));
}

void CheckCube(const Vec3d& lo, double size) {
  const Vec3d hi{lo.x + size, lo.y + size, lo.z + size};
  const Mesh m = BoxMesh(lo, hi);
  const SolidClassifier sc(m);
  ASSERT_EQ(sc.method(), SolidClassifier::Method::kRayParity);
  auto at = [&](double u, double v, double w) {
    return Vec3d{lo.x + u * size, lo.y + v * size, lo.z + w * size};
  };
  EXPECT_TRUE(sc.Contains(at(0.5, 0.5, 0.5)));
  EXPECT_FALSE(sc.Contains(at(1.5, 0.5, 0.5)));
  EXPECT_FALSE(sc.Contains(at(-0.5, 0.5, 0.5)));  // its +x ray runs through the whole cube
  // Points whose +x ray runs exactly along faces, edges and the triangulation diagonals.
  EXPECT_FALSE(sc.Contains(at(-1, 0, 0)));
  EXPECT_FALSE(sc.Contains(at(-1, 0.5, 0)));
  EXPECT_FALSE(sc.Contains(at(-1, 1, 1)));
  EXPECT_FALSE(sc.Contains(at(-1, 0.25, 0.25)));
  EXPECT_TRUE(sc.Contains(at(0.25, 0.25, 0.25)));
  EXPECT_TRUE(sc.Contains(at(0.25, 0.75, 0.75)));
  EXPECT_FALSE(sc.Contains(at(-1, 1.5, 1.5)));
  // Faces (centres and off-centre), edges (midpoints and quarter points), vertices.
  for (int k = 0; k < 3; ++k) {
    for (int side = 0; side < 2; ++side) {
      Vec3d out{0, 0, 0};
      out[k] = side ? 1 : -1;
      for (double u : {0.5, 0.1, 0.9}) {
        Vec3d f{0.5, u, 1 - u};
        f = {f[(3 - k) % 3], f[(4 - k) % 3], f[(5 - k) % 3]};
        f[k] = side;
        ExpectSurfaceBand(m, sc, at(f.x, f.y, f.z), out);
      }
    }
  }
  for (int k = 0; k < 3; ++k)
    for (int s1 = 0; s1 < 2; ++s1)
      for (int s2 = 0; s2 < 2; ++s2)
        for (double t : {0.5, 0.25}) {
          Vec3d e, out;
          e[k] = t, out[k] = 0;
          e[(k + 1) % 3] = s1, out[(k + 1) % 3] = s1 ? 1 : -1;
          e[(k + 2) % 3] = s2, out[(k + 2) % 3] = s2 ? 1 : -1;
          ExpectSurfaceBand(m, sc, at(e.x, e.y, e.z), out);
        }
  for (int c = 0; c < 8; ++c)
    ExpectSurfaceBand(m, sc, at(c & 1, (c >> 1) & 1, (c >> 2) & 1),
                      {c & 1 ? 1.0 : -1.0, c & 2 ? 1.0 : -1.0, c & 4 ? 1.0 : -1.0});
}

TEST(SolidClassifierTest, UnitCube) { CheckCube({0, 0, 0}, 1); }
TEST(SolidClassifierTest, CubeFarFromOrigin) { CheckCube({1000, -2000, 500}, 2); }

TEST(SolidClassifierTest, Tetrahedron) {
  const Mesh m = testing::TetrahedronMesh();
  const SolidClassifier sc(m);
  EXPECT_TRUE(sc.Contains({0.1, 0.1, 0.1}));
  EXPECT_FALSE(sc.Contains({0.5, 0.5, 0.5}));
  EXPECT_FALSE(sc.Contains({-0.1, 0.1, 0.1}));
  const double third = 1.0 / 3;
  // Slanted face x + y + z = 1 (centre, off-centre), the three axis faces, edges, vertices.
  ExpectSurfaceBand(m, sc, {third, third, third}, {1, 1, 1});
  ExpectSurfaceBand(m, sc, {0.5, 0.25, 0.25}, {1, 1, 1});
  ExpectSurfaceBand(m, sc, {0.2, 0.3, 0}, {0, 0, -1});
  ExpectSurfaceBand(m, sc, {0.2, 0, 0.3}, {0, -1, 0});
  ExpectSurfaceBand(m, sc, {0, 0.2, 0.3}, {-1, 0, 0});
  ExpectSurfaceBand(m, sc, {0.5, 0.5, 0}, {1, 1, -1});
  ExpectSurfaceBand(m, sc, {0.5, 0, 0}, {0, -1, -1});
  ExpectSurfaceBand(m, sc, {0, 0, 0.5}, {-1, -1, 0});
  ExpectSurfaceBand(m, sc, {0, 0, 0}, {-1, -1, -1});
  ExpectSurfaceBand(m, sc, {1, 0, 0}, {1, -0.5, -0.5});
  ExpectSurfaceBand(m, sc, {0, 0, 1}, {-0.5, -0.5, 1});
}

TEST(SolidClassifierTest, ConvexSphereAgainstHalfSpaces) {
  const Mesh m = testing::UvSphereMesh(11, 10, 1.0);  // 200 triangles
  ASSERT_EQ(m.triangle_count(), 200u);
  const SolidClassifier sc(m);
  std::mt19937_64 rng(3);
  const Box3d region = MakeBox(-1.2, -1.2, -1.2, 1.2, 1.2, 1.2);
  int in = 0, out = 0;
  for (int it = 0; it < 20000; ++it) {
    const Vec3d p = RandomIn(region, rng);
    // Analytic answer for a convex polyhedron: behind every face plane. Skip the 1e-9 band.
    bool inside = true, near = false;
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      const uint32_t* i = &m.triangles[3 * t];
      const Vec3d a = testing::VertexOf(m, i[0]), b = testing::VertexOf(m, i[1]),
                  c = testing::VertexOf(m, i[2]);
      const Vec3d e1{b.x - a.x, b.y - a.y, b.z - a.z}, e2{c.x - a.x, c.y - a.y, c.z - a.z};
      const Vec3d n =
          Normalized({e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x});
      const double d = n.x * (p.x - a.x) + n.y * (p.y - a.y) + n.z * (p.z - a.z);
      if (std::fabs(d) < 1e-9) near = true;
      if (d > 0) inside = false;
    }
    if (near) continue;
    ASSERT_EQ(sc.Contains(p), inside) << p.x << " " << p.y << " " << p.z;
    (inside ? in : out)++;
  }
  EXPECT_GT(in, 5000);
  EXPECT_GT(out, 5000);
}

// Voxel unions with integer vertices, queried on a quarter grid: rays run along faces, edges and
// triangle diagonals all the time, and many points lie exactly on the surface. No point is skipped.
TEST(SolidClassifierTest, VoxelUnionsOnAQuarterGridAreExact) {
  std::mt19937_64 rng(4);
  for (int trial = 0; trial < 6; ++trial) {
    testing::VoxelSet v;
    v.n = 5;
    v.occupied.resize(125);
    std::bernoulli_distribution occ(trial % 2 ? 0.3 : 0.6);
    for (char& c : v.occupied) c = occ(rng);
    const Mesh m = testing::VoxelMesh(v);
    const SolidClassifier brute(m);
    const SolidClassifier grid(m, Queries(1000));
    ASSERT_EQ(brute.method(), SolidClassifier::Method::kRayParity);
    ASSERT_TRUE(grid.has_grid());
    std::uniform_int_distribution<int> q(-2, 22);
    for (int it = 0; it < 4000; ++it) {
      const Vec3d p{q(rng) * 0.25, q(rng) * 0.25, q(rng) * 0.25};
      const bool want = v.Contains(p);
      ASSERT_EQ(brute.Contains(p), want) << "trial " << trial << " " << p.x << " " << p.y << " " << p.z;
      ASSERT_EQ(grid.Contains(p), want) << "trial " << trial << " " << p.x << " " << p.y << " " << p.z;
    }
  }
}

TEST(SolidClassifierTest, GridAndBruteForceAgree) {
  const Mesh m = testing::UvSphereMesh(60, 64, 3.0);
  const SolidClassifier brute(m, Queries(1));
  const SolidClassifier grid(m, Queries(100));
  ASSERT_FALSE(brute.has_grid());
  ASSERT_TRUE(grid.has_grid());
  std::mt19937_64 rng(5);
  const Box3d region = MakeBox(-3.3, -3.3, -3.3, 3.3, 3.3, 3.3);
  for (int it = 0; it < 5000; ++it) {
    const Vec3d p = RandomIn(region, rng);
    ASSERT_EQ(brute.Contains(p), grid.Contains(p));
    const Vec3d q = RandomIn(region, rng);
    const Box3d box = MakeBox(std::min(p.x, q.x), std::min(p.y, q.y), std::min(p.z, q.z), std::max(p.x, q.x),
                              std::max(p.y, q.y), std::max(p.z, q.z));
    ASSERT_EQ(brute.MeetsBox(box), grid.MeetsBox(box));
  }
  // Points on vertices: on the surface.
  for (size_t i = 0; i < m.vertex_count(); i += 7) {
    ASSERT_TRUE(grid.Contains(testing::VertexOf(m, static_cast<uint32_t>(i))));
    ASSERT_TRUE(brute.Contains(testing::VertexOf(m, static_cast<uint32_t>(i))));
  }
}

TEST(SolidClassifierTest, MeetsBox) {
  const Mesh m = BoxMesh({0, 0, 0}, {4, 4, 4});
  const SolidClassifier sc(m);
  // Inside the solid without touching any triangle: found by the corner test alone.
  const Box3d inner = MakeBox(1, 1, 1, 2, 2, 2);
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    const uint32_t* i = &m.triangles[3 * t];
    ASSERT_FALSE(TriangleMeetsBox(testing::VertexOf(m, i[0]), testing::VertexOf(m, i[1]),
                                  testing::VertexOf(m, i[2]), inner));
  }
  EXPECT_TRUE(sc.MeetsBox(inner));
  EXPECT_TRUE(MeshMeetsBox(m, inner));
  EXPECT_TRUE(sc.MeetsBox(MakeBox(-1, -1, -1, 5, 5, 5)));    // encloses the solid
  EXPECT_TRUE(sc.MeetsBox(MakeBox(3, 3, 3, 6, 6, 6)));       // crosses the surface
  EXPECT_TRUE(sc.MeetsBox(MakeBox(4, 1, 1, 5, 2, 2)));       // touches a face from outside
  EXPECT_TRUE(sc.MeetsBox(MakeBox(4, 4, 4, 5, 5, 5)));       // touches a corner
  EXPECT_FALSE(sc.MeetsBox(MakeBox(4.001, 1, 1, 5, 2, 2)));  // a hair away
  EXPECT_FALSE(MeshMeetsBox(m, MakeBox(4.001, 1, 1, 5, 2, 2)));
  EXPECT_FALSE(sc.MeetsBox(MakeBox(10, 10, 10, 11, 11, 11)));
  EXPECT_FALSE(sc.MeetsBox(Box3d{}));
  // A zero-size box answers as the point query.
  std::mt19937_64 rng(6);
  for (int it = 0; it < 2000; ++it) {
    std::uniform_int_distribution<int> q(-2, 18);
    const Vec3d p{q(rng) * 0.25, q(rng) * 0.25, q(rng) * 0.25};
    ASSERT_EQ(sc.MeetsBox(MakeBox(p.x, p.y, p.z, p.x, p.y, p.z)), sc.Contains(p));
  }
}

TEST(SolidClassifierTest, EmptyMesh) {
  const Mesh m;
  const SolidClassifier sc(m);
  EXPECT_FALSE(sc.Contains({0, 0, 0}));
  EXPECT_FALSE(sc.MeetsBox(MakeBox(-1, -1, -1, 1, 1, 1)));
  EXPECT_FALSE(PointInSolid(m, {0, 0, 0}));
  EXPECT_FALSE(MeshMeetsBox(m, MakeBox(-1, -1, -1, 1, 1, 1)));
}

TEST(SolidClassifierTest, OpenMeshesUseTheWindingNumber) {
  // A cube without its top: the cavity is 5/6 enclosed (w = 5/6), so its inside counts as solid;
  // above the opening w is small.
  Mesh lidless = BoxMesh({0, 0, 0}, {1, 1, 1});
  lidless.triangles.erase(lidless.triangles.begin() + 6, lidless.triangles.begin() + 12);  // top face
  const SolidClassifier sc(lidless);
  ASSERT_EQ(sc.method(), SolidClassifier::Method::kWindingNumber);
  EXPECT_NEAR(WindingNumber(lidless, {0.5, 0.5, 0.5}), 5.0 / 6, 1e-12);
  EXPECT_TRUE(sc.Contains({0.5, 0.5, 0.5}));
  EXPECT_TRUE(sc.Contains({0.5, 0.5, 0.1}));
  EXPECT_FALSE(sc.Contains({0.5, 0.5, 2}));
  EXPECT_FALSE(sc.Contains({2, 0.5, 0.5}));
  EXPECT_TRUE(sc.Contains({0.5, 0.5, 0}));  // on the bottom
  EXPECT_TRUE(sc.Contains({1, 1, 1}));      // on the rim
  EXPECT_FALSE(sc.Contains({1 + 1e-6, 0.5, 0.5}));
  EXPECT_TRUE(sc.Contains({1 - 1e-6, 0.5, 0.5}));

  // A single sheet encloses nothing: only contact counts, on either side.
  Mesh sheet;
  for (int i = 0; i < 4; ++i) testing::AddVertex(&sheet, i & 1, (i >> 1) & 1, 0);
  sheet.triangles = {0, 1, 3, 0, 3, 2};
  const SolidClassifier ss(sheet);
  EXPECT_TRUE(ss.Contains({0.3, 0.6, 0}));
  EXPECT_TRUE(ss.Contains({1, 1, 0}));
  EXPECT_FALSE(ss.Contains({0.3, 0.6, 1e-6}));
  EXPECT_FALSE(ss.Contains({0.3, 0.6, -1e-6}));
  EXPECT_FALSE(ss.Contains({0.3, 0.6, 0.5}));
  EXPECT_TRUE(ss.MeetsBox(MakeBox(0.2, 0.2, -1, 0.4, 0.4, 1)));
  EXPECT_FALSE(ss.MeetsBox(MakeBox(0.2, 0.2, 0.1, 0.4, 0.4, 1)));

  // Inverted orientation does not matter (|w|).
  Mesh inverted = BoxMesh({0, 0, 0}, {1, 1, 1});
  for (size_t t = 0; t < inverted.triangles.size(); t += 3)
    std::swap(inverted.triangles[t], inverted.triangles[t + 1]);
  inverted.triangles.resize(inverted.triangles.size() - 6);
  const SolidClassifier si(inverted);
  EXPECT_TRUE(si.Contains({0.5, 0.5, 0.5}));
  EXPECT_FALSE(si.Contains({0.5, 0.5, 1.5}));
}

}  // namespace
}  // namespace mktree
