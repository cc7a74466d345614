// Rays against triangles, boxes and meshes (engine/geometry/ray_cast.h) and closest points of meshes
// (closest_point.h): known answers on boxes, watertightness on shared edges and vertices, the coplanar
// case, and the hierarchy walks against scans.
#include "engine/geometry/ray_cast.h"

#include <gtest/gtest.h>

#include <random>

#include "engine/geometry/closest_point.h"
#include "geometry/test_meshes.h"

namespace mktree {
namespace {

using testing::BoxMesh;

TEST(RayCast, BoxFacesEdgesAndVerticesAtKnownT) {
  const Mesh box = BoxMesh({0, 0, 0}, {1, 2, 3});
  struct Case {
    Vec3d o, d;
    double t;
  };
  const Case cases[] = {
      {{-1, 1, 1.5}, {1, 0, 0}, 1},             // a face's middle
      {{-2, 0, 0}, {2, 0, 0}, 2},               // along an edge (the line lies in two faces)
      {{-1, -1, -1}, {1, 1, 1}, std::sqrt(3)},  // through the corner
      {{0.5, 1, 5}, {0, 0, -1}, 2},             // the top face's shared diagonal passes through its centre
      {{0.5, 1, 1.5}, {0, 0, 1}, 1.5},          // from inside: where it leaves
      {{0, 0, 0}, {-1, 0, 0}, 0},               // from the corner, outward: touching at t = 0
  };
  for (const Case& c : cases) {
    const RayHit3 h = FirstHit(box, PreparedRay(c.o, c.d), INFINITY);
    ASSERT_TRUE(h.hit()) << c.o.x << " " << c.o.y << " " << c.o.z;
    EXPECT_NEAR(h.t, c.t, 1e-12);
  }
  EXPECT_FALSE(FirstHit(box, PreparedRay({-1, 1, 1.5}, {-1, 0, 0}), INFINITY).hit());  // away from it
  EXPECT_FALSE(FirstHit(box, PreparedRay({-1, 1, 1.5}, {1, 0, 0}), 0.5).hit());        // too short
  EXPECT_TRUE(FirstHit(box, PreparedRay({-1, 1, 1.5}, {1, 0, 0}), 1.0).hit());         // max_t included
  const RayHit3 h = FirstHit(box, PreparedRay({0.5, 1, 1.5}, {0, 0, 1}), INFINITY);
  EXPECT_EQ(h.normal.z, 1.0);  // the top face turns outward
}

// A ray from inside a closed convex mesh, aimed at a point of an edge or at a vertex (up to the rounding of
// its direction), leaves it: no ray slips between triangles.
TEST(RayCast, WatertightOnSharedEdgesAndVertices) {
  const Mesh sphere = testing::UvSphereMesh(12, 24, 1.0);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1), d(-0.5, 0.5);
  for (int i = 0; i < 5000; ++i) {
    const uint32_t* t = &sphere.triangles[3 * (rng() % sphere.triangle_count())];
    const Vec3d a = testing::VertexOf(sphere, t[0]), b = testing::VertexOf(sphere, t[1]);
    const double s = i % 3 == 0 ? 0.0 : u(rng);  // a vertex, or a point of an edge
    const Vec3d target{a.x + s * (b.x - a.x), a.y + s * (b.y - a.y), a.z + s * (b.z - a.z)};
    const Vec3d o{d(rng), d(rng), d(rng)};
    const PreparedRay ray(o, {target.x - o.x, target.y - o.y, target.z - o.z});
    EXPECT_TRUE(FirstHit(sphere, ray, INFINITY).hit()) << "ray " << i;
  }
}

TEST(RayCast, LineInATrianglesPlaneEntersItWhereItCrossesItsEdge) {
  const Vec3d a{0, 0, 0}, b{4, 0, 0}, c{0, 4, 0};
  RayHit3 h;
  ASSERT_TRUE(RayTriangle(PreparedRay({-2, 1, 0}, {1, 0, 0}), a, b, c, INFINITY, &h));
  EXPECT_NEAR(h.t, 2, 1e-12);
  ASSERT_TRUE(RayTriangle(PreparedRay({1, 1, 0}, {1, 0, 0}), a, b, c, INFINITY, &h));
  EXPECT_EQ(h.t, 0);  // starting inside the sheet
  EXPECT_FALSE(RayTriangle(PreparedRay({-2, 5, 0}, {1, 0, 0}), a, b, c, INFINITY, &h));
  EXPECT_FALSE(RayTriangle(PreparedRay({0, 0, 1}, {1, 1, 1}), a, a, c, INFINITY, &h));  // zero area
}

TEST(RayCast, BoxEnterIsALowerBoundOfEveryHitInside) {
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> d(-5, 5);
  const Mesh sphere = testing::UvSphereMesh(10, 20, 1.3);
  const Box3d bounds = sphere.Bounds();
  for (int i = 0; i < 2000; ++i) {
    const PreparedRay ray({d(rng), d(rng), d(rng)}, {d(rng), d(rng), d(rng)});
    const RayHit3 h = FirstHit(sphere, ray, INFINITY);
    double enter;
    const bool in = RayBoxEnter(ray, bounds, INFINITY, &enter);
    if (h.hit()) {
      ASSERT_TRUE(in);
      EXPECT_LE(enter, h.t);
    }
  }
  double enter;
  Box3d flat;
  flat.min = {0, 0, 1};
  flat.max = {1, 1, 1};
  EXPECT_TRUE(RayBoxEnter(PreparedRay({-1, 0.5, 1}, {1, 0, 0}), flat, INFINITY, &enter));  // in its plane
  EXPECT_NEAR(enter, 1, 1e-12);
  EXPECT_FALSE(RayBoxEnter(PreparedRay({-1, 0.5, 1.01}, {1, 0, 0}), flat, INFINITY, &enter));
}

// The hierarchy walks give the scans' answers.
TEST(RayCast, HierarchyWalksAgreeWithScans) {
  const Mesh sphere = testing::UvSphereMesh(30, 60, 2.0);
  const TriangleHierarchy h(sphere);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> d(-4, 4);
  for (int i = 0; i < 300; ++i) {
    const Vec3d p{d(rng), d(rng), d(rng)};
    const PreparedRay ray(p, {-p.x + d(rng) / 4, -p.y, -p.z});
    RayHit3 scan;
    const double* v = sphere.vertices.data();
    for (size_t t = 0; t < sphere.triangle_count(); ++t) {
      const uint32_t* c = &sphere.triangles[3 * t];
      auto at = [&](uint32_t k) { return Vec3d{v[3 * k], v[3 * k + 1], v[3 * k + 2]}; };
      RayHit3 one;
      if (RayTriangle(ray, at(c[0]), at(c[1]), at(c[2]), INFINITY, &one) && one.t < scan.t) scan = one;
    }
    EXPECT_EQ(FirstHit(h, ray, INFINITY).t, scan.t);
    const SurfacePoint walked = ClosestOnSurface(h, p);
    EXPECT_NEAR(std::sqrt(walked.distance_squared), testing::SurfaceDistance(sphere, p), 1e-12);
    EXPECT_DOUBLE_EQ(ClosestOnSurface(sphere, p).distance_squared, walked.distance_squared);
  }
}

TEST(ClosestPoint, BoundsAndBoxes) {
  const Mesh box = BoxMesh({0, 0, 0}, {1, 1, 1});
  const SurfacePoint p = ClosestOnSurface(box, {2, 0.5, 0.5});
  EXPECT_DOUBLE_EQ(p.distance_squared, 1.0);
  EXPECT_DOUBLE_EQ(p.point.x, 1.0);
  EXPECT_FALSE(std::isfinite(ClosestOnSurface(box, {2, 0.5, 0.5}, 0.99).distance_squared));
  EXPECT_DOUBLE_EQ(ClosestOnSurface(box, {2, 0.5, 0.5}, 1.0).distance_squared, 1.0);  // bound included
  Box3d b;
  b.min = {0, 0, 0};
  b.max = {1, 1, 1};
  EXPECT_EQ(BoxPointDistanceSquared(b, {0.5, 0.5, 0.5}), 0);
  EXPECT_EQ(BoxPointDistanceSquared(b, {2, 3, 1}), 5);
  EXPECT_TRUE(std::isinf(BoxPointDistanceSquared(Box3d{}, {0, 0, 0})));
}

}  // namespace
}  // namespace mktree
