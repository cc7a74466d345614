#include "engine/geometry/triangle_pair.h"

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/intersections.h>
#include <CGAL/squared_distance_3.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "geometry/test_meshes.h"

namespace mktree {
namespace {

// The oracle: CGAL's exact kernel (tests only). Degenerate triangles are handed to it as the segment or
// point they are, chosen with CGAL's own predicates.
using K = CGAL::Exact_predicates_exact_constructions_kernel;
using P3 = K::Point_3;

using testing::Tri;

P3 ToCgal(const Vec3d& v) { return P3(v.x, v.y, v.z); }

struct Shape {
  int dim;  // 0 point, 1 segment, 2 triangle
  K::Point_3 p;
  K::Segment_3 s;
  K::Triangle_3 t;
};

Shape CgalShape(const Vec3d t[3]) {
  const P3 a = ToCgal(t[0]), b = ToCgal(t[1]), c = ToCgal(t[2]);
  Shape out;
  if (!CGAL::collinear(a, b, c)) {
    out.dim = 2;
    out.t = K::Triangle_3(a, b, c);
    return out;
  }
  P3 lo = a, hi = a;
  for (const P3& q : {b, c}) {
    if (CGAL::compare_xyz(q, lo) == CGAL::SMALLER) lo = q;
    if (CGAL::compare_xyz(q, hi) == CGAL::LARGER) hi = q;
  }
  if (lo == hi) {
    out.dim = 0;
    out.p = lo;
  } else {
    out.dim = 1;
    out.s = K::Segment_3(lo, hi);
  }
  return out;
}

bool OracleMeet(const Vec3d a[3], const Vec3d b[3]) {
  const Shape x = CgalShape(a), y = CgalShape(b);
  auto meet = [](const Shape& u, const Shape& v) -> bool {
    switch (u.dim * 3 + v.dim) {
      case 0:
        return u.p == v.p;
      case 1:
        return v.s.has_on(u.p);
      case 2:
        return v.t.has_on(u.p);
      case 4:
        return CGAL::do_intersect(u.s, v.s);
      case 5:
        return CGAL::do_intersect(u.s, v.t);
      case 8:
        return CGAL::do_intersect(u.t, v.t);
    }
    return false;
  };
  return x.dim <= y.dim ? meet(x, y) : meet(y, x);
}

// CGAL 5.5 has no segment-triangle distance: when they do not meet, the closest pair has an endpoint
// of the segment or an edge of the triangle in it.
K::FT SegmentTriangleDistance2(const K::Segment_3& s, const K::Triangle_3& t) {
  if (CGAL::do_intersect(s, t)) return 0;
  K::FT best = CGAL::squared_distance(s.source(), t);
  best = std::min(best, CGAL::squared_distance(s.target(), t));
  for (int i = 0; i < 3; ++i)
    best = std::min(best, CGAL::squared_distance(s, K::Segment_3(t.vertex(i), t.vertex((i + 1) % 3))));
  return best;
}

double OracleDistance2(const Vec3d a[3], const Vec3d b[3]) {
  const Shape x = CgalShape(a), y = CgalShape(b);
  const Shape& u = x.dim <= y.dim ? x : y;
  const Shape& v = x.dim <= y.dim ? y : x;
  K::FT d;
  switch (u.dim * 3 + v.dim) {
    case 0:
      d = CGAL::squared_distance(u.p, v.p);
      break;
    case 1:
      d = CGAL::squared_distance(u.p, v.s);
      break;
    case 2:
      d = CGAL::squared_distance(u.p, v.t);
      break;
    case 4:
      d = CGAL::squared_distance(u.s, v.s);
      break;
    case 5:
      d = SegmentTriangleDistance2(u.s, v.t);
      break;
    default:
      d = CGAL::squared_distance(u.t, v.t);
  }
  return CGAL::to_double(d);
}

Tri T(Vec3d a, Vec3d b, Vec3d c) { return Tri{{a, b, c}}; }

void ExpectMeet(const Tri& a, const Tri& b, bool meet) {
  EXPECT_EQ(TrianglesMeet(a.v, b.v), meet);
  EXPECT_EQ(TrianglesMeet(b.v, a.v), meet);
  EXPECT_EQ(OracleMeet(a.v, b.v), meet) << "the oracle disagrees with the planted answer";
  const ClosestPoints c = TriangleTriangleClosest(a.v, b.v);
  if (meet) {
    EXPECT_EQ(c.distance_squared, 0);
  } else {
    EXPECT_GT(c.distance_squared, 0);
  }
}

TEST(TrianglesMeet, PlantedCases) {
  const Tri base = T({0, 0, 0}, {4, 0, 0}, {0, 4, 0});
  ExpectMeet(base, T({1, 1, -1}, {1, 1, 1}, {3, 3, 1}), true);           // crossing
  ExpectMeet(base, T({4, 0, 0}, {5, 0, 1}, {5, 1, 1}), true);            // vertex on vertex
  ExpectMeet(base, T({1, 1, 0}, {1, 1, 3}, {2, 2, 3}), true);            // vertex on the face
  ExpectMeet(base, T({2, 2, 0}, {3, 3, 1}, {3, 3, -1}), true);           // vertex on the hypotenuse
  ExpectMeet(base, T({1, 0, 0}, {3, 0, 0}, {2, -1, 2}), true);           // edge along an edge
  ExpectMeet(base, T({0, 0, 0}, {4, 0, 0}, {0, -4, 0}), true);           // coplanar, sharing an edge
  ExpectMeet(base, T({1, 1, 0}, {5, 1, 0}, {1, 5, 0}), true);            // coplanar overlapping
  ExpectMeet(base, T({0.5, 0.5, 0}, {1, 0.5, 0}, {0.5, 1, 0}), true);    // coplanar, one inside the other
  ExpectMeet(base, T({3, 3, 0}, {5, 3, 0}, {3, 5, 0}), false);           // coplanar, disjoint
  ExpectMeet(base, T({0, 0, 1e-9}, {4, 0, 1e-9}, {0, 4, 1e-9}), false);  // parallel near miss
  ExpectMeet(base, T({2.000001, 2, -1}, {2.000001, 2, 1}, {9, 9, 0}), false);  // just past the hypotenuse
  // Degenerate triangles: a segment crossing, a segment in the plane, a point on and off the face.
  ExpectMeet(base, T({1, 1, -1}, {1, 1, 1}, {1, 1, 0.5}), true);
  ExpectMeet(base, T({-1, 1, 0}, {1, 1, 0}, {0, 1, 0}), true);
  ExpectMeet(base, T({-2, 1, 0}, {-1, 1, 0}, {-1.5, 1, 0}), false);
  ExpectMeet(base, T({1, 1, 0}, {1, 1, 0}, {1, 1, 0}), true);
  ExpectMeet(base, T({1, 1, 1e-100}, {1, 1, 1e-100}, {1, 1, 1e-100}), false);  // a point just above
  ExpectMeet(T({0, 0, 0}, {1, 1, 1}, {2, 2, 2}), T({2, 2, 2}, {3, 3, 3}, {4, 4, 4}),
             true);  // collinear, touching
  ExpectMeet(T({0, 0, 0}, {1, 1, 1}, {2, 2, 2}), T({3, 3, 3}, {4, 4, 4}, {5, 5, 5}), false);
}

// Random triangles with corners on a small integer grid: coplanar, collinear, shared corners and edges
// everywhere. Every answer is compared with CGAL's exact kernel.
TEST(TrianglesMeet, IntegerGridAgainstExactOracle) {
  std::mt19937_64 rng(20);
  int meets = 0, coplanar_meets = 0, degenerate = 0;
  for (int grid : {2, 3, 5}) {
    std::uniform_int_distribution<int> u(0, grid);
    for (int i = 0; i < 40000; ++i) {
      Vec3d a[3], b[3];
      for (auto& v : a) v = {double(u(rng)), double(u(rng)), double(u(rng))};
      for (auto& v : b) v = {double(u(rng)), double(u(rng)), double(u(rng))};
      // Flatten some pairs into one plane to exercise the coplanar paths.
      if (i % 3 == 0)
        for (int k = 0; k < 3; ++k) a[k].z = b[k].z = 1;
      const bool want = OracleMeet(a, b);
      ASSERT_EQ(TrianglesMeet(a, b), want) << "grid " << grid << " case " << i;
      ASSERT_EQ(TrianglesMeet(b, a), want);
      meets += want;
      coplanar_meets += want && i % 3 == 0;
      degenerate += CgalShape(a).dim < 2;
    }
  }
  // The cases must exercise what they claim to.
  EXPECT_GT(meets, 10000);
  EXPECT_GT(coplanar_meets, 5000);
  EXPECT_GT(degenerate, 1000);
}

// Random float triangles, most apart, some near: the answer and the distance against the oracle.
TEST(TriangleTriangleClosest, RandomAgainstExactOracle) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  int apart = 0;
  for (int i = 0; i < 20000; ++i) {
    Vec3d a[3], b[3];
    const double shift = (i % 4) * 0.7;
    for (auto& v : a) v = {u(rng), u(rng), u(rng)};
    for (auto& v : b) v = {u(rng) + shift, u(rng), u(rng)};
    if (i % 10 == 0) b[2] = b[1];  // a segment
    if (i % 10 == 1) a[1] = {(a[0].x + a[2].x) / 2, (a[0].y + a[2].y) / 2, (a[0].z + a[2].z) / 2};
    const bool meet = OracleMeet(a, b);
    ASSERT_EQ(TrianglesMeet(a, b), meet) << i;
    const ClosestPoints c = TriangleTriangleClosest(a, b);
    const double want = std::sqrt(OracleDistance2(a, b));
    const double got = std::sqrt(c.distance_squared);
    ASSERT_NEAR(got, want, 1e-12) << i;
    // The points are on their triangles and as far apart as reported.
    const double between = std::sqrt((c.on_a.x - c.on_b.x) * (c.on_a.x - c.on_b.x) +
                                     (c.on_a.y - c.on_b.y) * (c.on_a.y - c.on_b.y) +
                                     (c.on_a.z - c.on_b.z) * (c.on_a.z - c.on_b.z));
    ASSERT_NEAR(between, got, 1e-12);
    const Vec3d pa[3] = {c.on_a, c.on_a, c.on_a}, pb[3] = {c.on_b, c.on_b, c.on_b};
    ASSERT_NEAR(std::sqrt(OracleDistance2(pa, a)), 0, 1e-12);
    ASSERT_NEAR(std::sqrt(OracleDistance2(pb, b)), 0, 1e-12);
    apart += !meet;
  }
  EXPECT_GT(apart, 5000);
  EXPECT_LT(apart, 19000);
}

// Near misses at every feature pair: a triangle slid to a small gap along a known direction.
TEST(TriangleTriangleClosest, GapsAtEachFeaturePair) {
  const Vec3d a[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  for (double gap : {1e-9, 1e-4, 0.01, 0.5}) {
    const Vec3d vf[3] = {{0.2, 0.2, gap}, {0.3, 0.2, 1}, {0.2, 0.3, 1}};     // vertex above the face
    const Vec3d ee[3] = {{0.5, -0.5, gap}, {0.5, 1.5, gap}, {0.5, 0.5, 1}};  // edge over the face
    const Vec3d ee2[3] = {{1, 1, -1}, {1, 1, 1}, {3, 3, 0}};                 // crossing the hypotenuse's line
    const Vec3d side[3] = {{-gap, 0.2, -1}, {-gap, 0.2, 1}, {-gap - 1, 0.2, 0}};  // edge beside an edge
    EXPECT_NEAR(std::sqrt(TriangleTriangleClosest(a, vf).distance_squared), gap, 1e-15);
    EXPECT_NEAR(std::sqrt(TriangleTriangleClosest(a, ee).distance_squared), gap, 1e-15);
    EXPECT_NEAR(std::sqrt(TriangleTriangleClosest(a, side).distance_squared), gap, 1e-15);
    EXPECT_NEAR(std::sqrt(TriangleTriangleClosest(a, ee2).distance_squared), std::sqrt(0.5), 1e-15);
    for (const Vec3d* b : {vf, ee, side, ee2})
      EXPECT_NEAR(TriangleTriangleClosest(a, b).distance_squared, OracleDistance2(a, b), 1e-15);
  }
}

TEST(SegmentsMeet, DegenerateAndCollinear) {
  EXPECT_TRUE(SegmentsMeet({0, 0, 0}, {2, 2, 2}, {1, 1, 1}, {1, 1, 1}));     // point on segment
  EXPECT_FALSE(SegmentsMeet({0, 0, 0}, {2, 2, 2}, {3, 3, 3}, {3, 3, 3}));    // point beyond
  EXPECT_TRUE(SegmentsMeet({0, 0, 0}, {0, 0, 2}, {0, 0, 2}, {0, 0, 5}));     // collinear along z, touching
  EXPECT_FALSE(SegmentsMeet({0, 0, 0}, {0, 0, 2}, {0, 0, 2.5}, {0, 0, 5}));  // collinear along z, apart
  EXPECT_TRUE(SegmentsMeet({0, 0, 0}, {2, 0, 0}, {1, -1, 0}, {1, 1, 0}));    // crossing
  EXPECT_FALSE(SegmentsMeet({0, 0, 0}, {2, 0, 0}, {1, -1, 1e-12}, {1, 1, 1e-12}));
  EXPECT_TRUE(SegmentsMeet({5, 5, 5}, {5, 5, 5}, {5, 5, 5}, {5, 5, 5}));
  EXPECT_TRUE(SegmentMeetsTriangle({0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}));
  EXPECT_FALSE(SegmentMeetsTriangle({0.6, 0.6, -1}, {0.6, 0.6, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}));
}

}  // namespace
}  // namespace mktree
