#include "engine/geometry/touch_certificate.h"

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <random>
#include <vector>

#include "engine/geometry/exact_predicates.h"
#include "engine/geometry/mesh_edges.h"
#include "engine/geometry/mesh_separation.h"
#include "engine/geometry/triangle_pair.h"
#include "geometry/touch_meshes.h"

namespace mktree {
namespace {

using testing::Box;
using testing::ConvexPrism;
using testing::Prism;
using testing::Pt;
using testing::Tetra;

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using P3 = K::Point_3;
using V3 = K::Vector_3;

// The oracle for convex solids (separating axis theorem, exact): the interiors of two convex polytopes are
// disjoint iff their projections on some face normal or edge-edge cross product overlap by at most 0; the
// penetration depth is the smallest overlap over those axes, normalised.
std::vector<P3> Points(const Mesh& m) {
  std::vector<P3> p;
  for (size_t i = 0; i < m.vertex_count(); ++i)
    p.emplace_back(m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]);
  return p;
}
double ConvexDepth(const Mesh& a, const Mesh& b) {
  const std::vector<P3> pa = Points(a), pb = Points(b);
  std::vector<V3> axes, ea, eb;
  auto add = [&](const Mesh& m, const std::vector<P3>& p, std::vector<V3>* edges) {
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      const P3 &x = p[m.triangles[3 * t]], &y = p[m.triangles[3 * t + 1]], &z = p[m.triangles[3 * t + 2]];
      axes.push_back(CGAL::cross_product(y - x, z - x));
      edges->push_back(y - x);
      edges->push_back(z - y);
      edges->push_back(x - z);
    }
  };
  add(a, pa, &ea);
  add(b, pb, &eb);
  for (const V3& u : ea)
    for (const V3& v : eb) axes.push_back(CGAL::cross_product(u, v));
  double best = std::numeric_limits<double>::infinity();
  for (const V3& n : axes) {
    if (n == CGAL::NULL_VECTOR) continue;
    auto range = [&](const std::vector<P3>& p) {
      K::FT lo = (p[0] - CGAL::ORIGIN) * n, hi = lo;
      for (const P3& q : p) {
        const K::FT d = (q - CGAL::ORIGIN) * n;
        lo = CGAL::min(lo, d);
        hi = CGAL::max(hi, d);
      }
      return std::make_pair(lo, hi);
    };
    const auto [la, ha] = range(pa);
    const auto [lb, hb] = range(pb);
    const K::FT overlap = CGAL::min(ha - lb, hb - la);
    if (overlap <= 0) return 0;
    best = std::min(best, CGAL::to_double(overlap) / std::sqrt(CGAL::to_double(n.squared_length())));
  }
  return best;
}
// Non-convex solids given as convex parts whose union they are: the interiors are disjoint iff they are
// disjoint from every part's.
bool InteriorsDisjoint(const std::vector<Mesh>& parts_a, const std::vector<Mesh>& parts_b) {
  for (const Mesh& x : parts_a)
    for (const Mesh& y : parts_b)
      if (ConvexDepth(x, y) > 0) return false;
  return true;
}

// The far UTM-like offset of the "far" variant (integers: exact in double).
constexpr double kFarX = 500000, kFarY = 5700000, kFarZ = 100;

void ExpectTouch(const Mesh& a, const Mesh& b, const char* what) {
  SCOPED_TRACE(what);
  ASSERT_TRUE(IsClosedMesh(a));
  ASSERT_TRUE(IsClosedMesh(b));
  const ClashShape sa(a), sb(b);
  for (const bool swap : {false, true}) {
    SeparateOptions o;
    o.depth_lower_enough = 0.002;
    const Separation r = swap ? Separate(sb, sa, 0, nullptr, o) : Separate(sa, sb, 0, nullptr, o);
    EXPECT_EQ(r.meeting, Meeting::kSurfacesMeet);
    EXPECT_EQ(r.depth_upper, 0);
    EXPECT_EQ(r.depth_lower, 0);
    EXPECT_EQ(r.distance, 0);
  }
}

// Planted touches: face on face, edge on face, vertex on face, on axis and inclined planes, near the
// origin and far from it. The oracle confirms each is a touch; the engine must prove it exactly.
TEST(TouchCertificate, PlantedTouchesAreExactlyZeroDeep) {
  for (const Vec3d at : {Vec3d{0, 0, 0}, Vec3d{kFarX, kFarY, kFarZ}}) {
    const Mesh base = Box({0, 0, 0}, {10, 10, 10}, at);
    std::vector<std::pair<const char*, Mesh>> planted = {
        {"box on top face, inside its outline", Box({2, 3, 10}, {5, 7, 12}, at)},
        {"box on top face, flush with two sides", Box({0, 0, 10}, {4, 4, 11}, at)},
        {"box on top face, overhanging", Box({8, -2, 10}, {13, 3, 14}, at)},
        {"rotated box on top face", ConvexPrism({{5, 2}, {8, 5}, {5, 8}, {2, 5}}, 10, 13, at)},
        {"prism edge on side face", ConvexPrism({{10, 5}, {13, 3}, {13, 7}}, 2, 6, at)},
        {"prism face on top face, overhanging", ConvexPrism({{9, 4}, {12, 2}, {12, 6}}, 10, 10.5, at)},
        {"tetrahedron vertex on top face", Tetra({{{4, 4, 10}, {2, 2, 12}, {7, 3, 12}, {4, 8, 12.5}}}, at)},
        {"tetrahedron vertex on a corner",
         Tetra({{{10, 10, 10}, {11, 10, 12}, {12, 13, 11}, {13, 11, 11}}}, at)},
    };
    for (const auto& [what, b] : planted) {
      EXPECT_EQ(ConvexDepth(base, b), 0) << what;
      ExpectTouch(base, b, what);
    }
    // Inclined plane 2x + y = 20 (not a 26-DOP direction): a wedge and a square lying on its slope.
    const Mesh wedge = ConvexPrism({{0, 0}, {10, 0}, {0, 20}}, 0, 5, at);
    const Mesh on_slope = ConvexPrism({{6, 8}, {8, 4}, {12, 6}, {10, 10}}, 1, 4, at);
    EXPECT_EQ(ConvexDepth(wedge, on_slope), 0);
    ExpectTouch(wedge, on_slope, "square face on an inclined face");
    const Mesh edge_on_slope = ConvexPrism({{7, 6}, {12, 7}, {11, 10}}, 1, 4, at);  // 2*7 + 6 = 20
    EXPECT_EQ(ConvexDepth(wedge, edge_on_slope), 0);
    ExpectTouch(wedge, edge_on_slope, "prism edge on an inclined face");
  }
}

// A plate in the inner corner of an angle section, touching both legs: no plane separates them; the
// convex piece certificate does.
TEST(TouchCertificate, PlateInTheCornerOfAnAngle) {
  for (const Vec3d at : {Vec3d{0, 0, 0}, Vec3d{kFarX, kFarY, kFarZ}}) {
    // The L: x in [0, 10], y in [0, 1] leg and x in [0, 1], y in [0, 10] leg, z in [0, 20].
    const std::vector<Pt> l = {{0, 0}, {10, 0}, {10, 1}, {1, 1}, {1, 10}, {0, 10}};
    const Mesh angle = Prism(l, {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 5}}, 0, 20, at);
    const std::vector<Mesh> angle_parts = {Box({0, 0, 0}, {10, 1, 20}, at), Box({0, 1, 0}, {1, 10, 20}, at)};
    const Mesh plate = Box({1, 1, 5}, {6, 6, 6}, at);
    EXPECT_TRUE(InteriorsDisjoint(angle_parts, {plate}));
    ExpectTouch(angle, plate, "plate in the corner");
    const Mesh cleat = ConvexPrism({{1, 1}, {4, 1}, {1, 4}}, 2, 3, at);  // a triangular stiffener
    EXPECT_TRUE(InteriorsDisjoint(angle_parts, {cleat}));
    ExpectTouch(angle, cleat, "triangular cleat in the corner");
    // The angle's own corner block: every vertex on the angle's surface, no triangle of it crossing a
    // facet of the block, but the block lies inside: no certificate (the interior point decides).
    const Mesh block = Box({0, 0, 0}, {1, 1, 20}, at);
    EXPECT_FALSE(InteriorsDisjoint(angle_parts, {block}));
    const ClashShape sa(angle), sb(block);
    for (const bool swap : {false, true}) {
      const Separation r = swap ? Separate(sb, sa, 0, nullptr) : Separate(sa, sb, 0, nullptr);
      EXPECT_EQ(r.meeting, Meeting::kSurfacesMeet);
      EXPECT_GT(r.depth_upper, 0.002);
    }
  }
}

// Triangles that meet with each one's corners strictly on both sides of the other's plane may still meet
// only on their edges: a square prism standing on a box's top face, across the box's side face x = 1,
// makes such pairs of side triangles. Given one of them, the search still finds the plane z = 1.
TEST(TouchCertificate, SearchGoesOnFromTrianglesMeetingOnTheirEdges) {
  for (const Vec3d at : {Vec3d{0, 0, 0}, Vec3d{kFarX, kFarY, kFarZ}}) {
    const Mesh a = Box({0, 0, 0}, {1, 1, 1}, at);
    const Mesh b = ConvexPrism({{1.1, 0.8}, {0.8, 0.5}, {1.1, 0.2}, {1.4, 0.5}}, 1, 2, at);
    EXPECT_EQ(ConvexDepth(a, b), 0);
    ExpectTouch(a, b, "prism on the top face across a side");
    auto corners = [](const Mesh& m, size_t t) {
      std::array<Vec3d, 3> c;
      for (int k = 0; k < 3; ++k) {
        const double* v = &m.vertices[3 * size_t{m.triangles[3 * t + k]}];
        c[k] = {v[0], v[1], v[2]};
      }
      return c;
    };
    auto straddles = [](const std::array<Vec3d, 3>& t, const std::array<Vec3d, 3>& u) {
      const double p[3][3] = {{t[0].x, t[0].y, t[0].z}, {t[1].x, t[1].y, t[1].z}, {t[2].x, t[2].y, t[2].z}};
      bool below = false, above = false;
      for (const Vec3d& v : u) {
        const double q[3] = {v.x, v.y, v.z};
        const int sign = Orient3dSign(p[0], p[1], p[2], q);
        below |= sign < 0;
        above |= sign > 0;
      }
      return below && above;
    };
    const TriangleHierarchy ha(a), hb(b);
    const Kdop ka = Kdop::Of(a), kb = Kdop::Of(b);
    const SolidClassifier ca(a), cb(b);
    const double slack = 16 * DBL_EPSILON * 3 * 2 * (kFarY + 10);
    const TouchObject oa{&a, &ha, &ka, slack, &ca}, ob{&b, &hb, &kb, slack, &cb};
    int straddling = 0;
    for (size_t i = 0; i < a.triangle_count(); ++i)
      for (size_t j = 0; j < b.triangle_count(); ++j) {
        const std::array<Vec3d, 3> ta = corners(a, i), tb = corners(b, j);
        if (!TrianglesMeet(ta.data(), tb.data()) || !straddles(ta, tb) || !straddles(tb, ta)) continue;
        ++straddling;
        const TouchResult r = FindTouchCertificate(oa, ob, ta.data(), tb.data(), TouchStage::kSearch);
        EXPECT_TRUE(r.separated) << i << " " << j;
      }
    EXPECT_GT(straddling, 0);
  }
}

// A shallow crossing stays a crossing: 1 mm deep (a touch at T = 2 mm) and 3 mm (hard); never depth 0.
TEST(TouchCertificate, ShallowCrossingsKeepTheirDepth) {
  for (const Vec3d at : {Vec3d{0, 0, 0}, Vec3d{kFarX, kFarY, kFarZ}}) {
    const Mesh base = Box({0, 0, 0}, {10, 10, 10}, at);
    const std::vector<Pt> l = {{0, 0}, {10, 0}, {10, 1}, {1, 1}, {1, 10}, {0, 10}};
    const Mesh angle = Prism(l, {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 5}}, 0, 20, at);
    const std::vector<Mesh> angle_parts = {Box({0, 0, 0}, {10, 1, 20}, at), Box({0, 1, 0}, {1, 10, 20}, at)};
    for (const double depth : {0.001, 0.003}) {
      const double z = 10 - depth;
      const Mesh on_top = Box({2, 3, z}, {5, 7, z + 2}, at);
      const Mesh rotated = ConvexPrism({{5, 2}, {8, 5}, {5, 8}, {2, 5}}, z, z + 3, at);
      const Mesh in_corner = Box({1 - depth, 1, 5}, {6, 6, 6}, at);  // into one leg
      struct Planted {
        const char* what;
        const Mesh *a, *b;
        double truth;
      };
      for (const Planted& p :
           {Planted{"box into top face", &base, &on_top, ConvexDepth(base, on_top)},
            Planted{"rotated box into top face", &base, &rotated, ConvexDepth(base, rotated)},
            Planted{"plate into a leg", &angle, &in_corner, depth}}) {
        SCOPED_TRACE(p.what);
        SCOPED_TRACE(depth);
        if (p.a == &angle) {
          EXPECT_FALSE(InteriorsDisjoint(angle_parts, {in_corner}));
        }
        EXPECT_NEAR(p.truth, depth, 1e-6);
        const ClashShape sa(*p.a), sb(*p.b);
        SeparateOptions o;
        o.depth_lower_enough = 0.002;
        const Separation r = Separate(sa, sb, 0, nullptr, o);
        EXPECT_EQ(r.meeting, Meeting::kSurfacesMeet);
        EXPECT_GT(r.depth_upper, 0);
        EXPECT_LE(r.depth_lower, p.truth + 1e-9);
        EXPECT_GE(r.depth_upper, p.truth - 1e-9);
        // The class at T = 2 mm is a touch only with depth_upper <= T: the convex pairs' bounds are
        // exact; the plate in the angle is reported hard with an interval that holds the depth.
        if (p.a != &angle) {
          EXPECT_EQ(r.depth_upper <= 0.002, depth < 0.002);
        }
        if (depth > 0.002) {
          EXPECT_GT(r.depth_upper, 0.002);
        }
      }
    }
  }
}

// Random placements of a small convex solid around a box and an angle, on an integer grid (exact
// contacts are common): whenever the engine reports depth 0 the oracle must agree (the interiors are
// disjoint), and meeting pairs are never reported apart.
TEST(TouchCertificate, RandomContactsAgainstTheOracle) {
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> coord(-2, 12), size(1, 4), shape(0, 2);
  const Mesh base = Box({0, 0, 0}, {10, 10, 10});
  const std::vector<Pt> l = {{0, 0}, {10, 0}, {10, 1}, {1, 1}, {1, 10}, {0, 10}};
  const Mesh angle = Prism(l, {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 5}}, 0, 10);
  const std::vector<Mesh> angle_parts = {Box({0, 0, 0}, {10, 1, 10}), Box({0, 1, 0}, {1, 10, 10})};
  const ClashShape s_base(base), s_angle(angle);
  int certified = 0, meeting = 0;
  for (int i = 0; i < 3000; ++i) {
    const double x = coord(rng), y = coord(rng), z = coord(rng);
    const double w = size(rng), h = size(rng), d = size(rng);
    Mesh b;
    switch (shape(rng)) {
      case 0:
        b = Box({x, y, z}, {x + w, y + h, z + d});
        break;
      case 1:
        b = ConvexPrism({{x, y}, {x + w, y + h}, {x - h, y + w}}, z, z + d);  // inclined sides
        break;
      default:
        b = Tetra({{{x, y, z}, {x + w, y, z + d}, {x, y + h, z + d}, {x + w, y + h, z}}});
        break;
    }
    const ClashShape sb(b);
    const bool use_angle = i % 2 == 1;
    const ClashShape& sa = use_angle ? s_angle : s_base;
    const Separation r = Separate(sa, sb, 0, nullptr);
    const bool disjoint = use_angle ? InteriorsDisjoint(angle_parts, {b}) : ConvexDepth(base, b) == 0;
    if (!disjoint) {
      EXPECT_NE(r.meeting, Meeting::kApart) << i;
      EXPECT_GT(r.depth_upper, 0) << i;
    }
    if (r.meeting != Meeting::kApart) {
      ++meeting;
      if (r.depth_upper == 0) {
        EXPECT_TRUE(disjoint) << i;
        ++certified;
      }
    }
  }
  EXPECT_GT(meeting, 500);
  EXPECT_GT(certified, 100);
}

TEST(TouchCertificate, DirectionSideSignIsExact) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  const int dirs[4][3] = {{1, 0, 0}, {1, -1, 0}, {1, 1, 1}, {0, 1, -1}};
  for (int i = 0; i < 20000; ++i) {
    const int* d = dirs[i % 4];
    const double scale = i % 3 == 0 ? 5e6 : 1;
    double p[3], v[3];
    for (int k = 0; k < 3; ++k) p[k] = scale * u(rng);
    // Often exactly on the plane, or a few ulp off it.
    for (int k = 0; k < 3; ++k) v[k] = p[k];
    if (i % 2 == 0) {
      const double t = std::ldexp(std::round(u(rng) * 8), -3);
      v[0] += d[1] * t;
      v[1] -= d[0] * t;
    }
    if (i % 5 == 0) v[2] = std::nextafter(v[2], 1e300);
    const K::FT exact = K::FT(d[0]) * (K::FT(v[0]) - p[0]) + K::FT(d[1]) * (K::FT(v[1]) - p[1]) +
                        K::FT(d[2]) * (K::FT(v[2]) - p[2]);
    EXPECT_EQ(DirectionSideSign(d, v, p), CGAL::sign(exact)) << i;
  }
}

}  // namespace
}  // namespace mktree
