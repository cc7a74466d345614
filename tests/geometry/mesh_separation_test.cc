#include "engine/geometry/mesh_separation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <thread>
#include <vector>

#include "engine/geometry/mesh_edges.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/geometry/triangle_hierarchy.h"
#include "engine/geometry/triangle_pair.h"
#include "geometry/mesh_files.h"
#include "geometry/test_meshes.h"
#include "geometry/touch_meshes.h"

namespace mktree {
namespace {

using testing::AddVertex;
using testing::BoxMesh;
using testing::Tri;
using testing::UvSphereMesh;

constexpr double kInf = std::numeric_limits<double>::infinity();

std::vector<Tri> Triangles(const Mesh& m) {
  std::vector<Tri> out(m.triangle_count());
  for (size_t t = 0; t < m.triangle_count(); ++t)
    for (int c = 0; c < 3; ++c) out[t].v[c] = testing::VertexOf(m, m.triangles[3 * t + c]);
  return out;
}
Box3d TriBox(const Tri& t) {
  Box3d b;
  for (const Vec3d& v : t.v) b.Extend(v.x, v.y, v.z);
  return b;
}
Box3d Grow(Box3d b, double r) {
  for (int k = 0; k < 3; ++k) b.min[k] -= r, b.max[k] += r;
  return b;
}

// The oracle: every triangle pair (only triangles whose boxes come within `reach` of the other mesh's
// box can matter), the exact pair test, point-in-solid for containment of solids.
struct Truth {
  Meeting meeting = Meeting::kApart;
  double gap = kInf;  // exact up to rounding, over the pairs within reach
};
Truth BruteForce(const Mesh& a, const Mesh& b, double reach) {
  Truth t;
  const std::vector<Tri> ta = Triangles(a), tb = Triangles(b);
  std::vector<const Tri*> na, nb;
  const Box3d ba = Grow(a.Bounds(), reach), bb = Grow(b.Bounds(), reach);
  for (const Tri& x : ta)
    if (BoxesMeet(TriBox(x), bb)) na.push_back(&x);
  for (const Tri& y : tb)
    if (BoxesMeet(TriBox(y), ba)) nb.push_back(&y);
  for (const Tri* x : na)
    for (const Tri* y : nb)
      if (TrianglesMeet(x->v, y->v)) {
        t.meeting = Meeting::kSurfacesMeet;
        t.gap = 0;
        return t;
      }
  const bool sa = IsClosedMesh(a) && a.triangle_count() > 0, sb = IsClosedMesh(b) && b.triangle_count() > 0;
  if (sa && sb) {
    // With no triangles meeting, each connected component is wholly in or out: test every vertex that is
    // clear of the other's surface (the classifier counts points within its tolerance as inside).
    auto inside = [](const Mesh& x, const Mesh& y) {
      SolidClassifierOptions many;
      many.expected_queries = x.vertex_count();
      const SolidClassifier in_y(y, many);
      const double clear = 2 * in_y.tolerance();
      for (size_t i = 0; i < x.vertex_count(); ++i) {
        const Vec3d v = testing::VertexOf(x, i);
        if (in_y.Contains(v) && testing::SurfaceDistance(y, v) > clear) return true;
      }
      return false;
    };
    if (inside(a, b)) return {Meeting::kAInsideB, 0};
    if (inside(b, a)) return {Meeting::kBInsideA, 0};
  }
  for (const Tri* x : na)
    for (const Tri* y : nb)
      t.gap = std::min(t.gap, std::sqrt(TriangleFeatureClosest(x->v, y->v).distance_squared));
  return t;
}

double Dist(const Vec3d& a, const Vec3d& b) { return std::hypot(a.x - b.x, a.y - b.y, a.z - b.z); }

// Separate against the oracle, both orders; returns Separate(a, b).
Separation Check(const Mesh& a, const Mesh& b, double c, const char* what) {
  SCOPED_TRACE(what);
  const ClashShape sa(a), sb(b);
  NarrowStats st;
  const Separation r = Separate(sa, sb, c, &st);
  const Separation s = Separate(sb, sa, c, &st);
  const Truth t = BruteForce(a, b, c);
  EXPECT_EQ(static_cast<int>(r.meeting), static_cast<int>(t.meeting));
  const Meeting swapped = t.meeting == Meeting::kAInsideB   ? Meeting::kBInsideA
                          : t.meeting == Meeting::kBInsideA ? Meeting::kAInsideB
                                                            : t.meeting;
  EXPECT_EQ(static_cast<int>(s.meeting), static_cast<int>(swapped));
  if (t.meeting == Meeting::kApart) {
    if (t.gap < c) {
      EXPECT_NEAR(r.distance, t.gap, 1e-12 * (1 + t.gap));
      EXPECT_NEAR(s.distance, t.gap, 1e-12 * (1 + t.gap));
      EXPECT_GT(r.distance, 0);
      EXPECT_NEAR(Dist(r.point_a, r.point_b), r.distance, 1e-12 * (1 + t.gap));
      // The closest points lie on their meshes.
      EXPECT_NEAR(testing::SurfaceDistance(a, r.point_a), 0, 1e-12);
      EXPECT_NEAR(testing::SurfaceDistance(b, r.point_b), 0, 1e-12);
    } else {
      EXPECT_EQ(r.distance, kInf);
      EXPECT_EQ(s.distance, kInf);
    }
  } else {
    EXPECT_LE(r.depth_lower, r.depth_upper);
    EXPECT_GE(r.depth_lower, 0);
    EXPECT_EQ(r.distance, -r.depth_upper);
    EXPECT_EQ(r.depth_upper, s.depth_upper);
    EXPECT_EQ(r.depth_lower, s.depth_lower);
    EXPECT_EQ(r.point_a.x, r.point_b.x);
    if (t.meeting == Meeting::kSurfacesMeet) {  // the contact point is on both surfaces
      const double tol = 1e-9 * (1 + testing::Diagonal(a.Bounds()) + testing::Diagonal(b.Bounds()));
      EXPECT_LT(testing::SurfaceDistance(a, r.point_a), tol);
      EXPECT_LT(testing::SurfaceDistance(b, r.point_a), tol);
    }
  }
  return r;
}

Mesh Transformed(const Mesh& m, double angle, const Vec3d& axis, const Vec3d& shift, double scale = 1) {
  const double l = std::hypot(axis.x, axis.y, axis.z);
  const double x = axis.x / l, y = axis.y / l, z = axis.z / l, c = std::cos(angle), s = std::sin(angle);
  const double r[3][3] = {{c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s},
                          {y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s},
                          {z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)}};
  Mesh out = m;
  for (size_t i = 0; i < m.vertex_count(); ++i) {
    const double* v = &m.vertices[3 * i];
    for (int k = 0; k < 3; ++k)
      out.vertices[3 * i + k] = scale * (r[k][0] * v[0] + r[k][1] * v[1] + r[k][2] * v[2]) + shift[k];
  }
  return out;
}
Mesh Shifted(const Mesh& m, const Vec3d& d) { return Transformed(m, 0, {0, 0, 1}, d); }

// A closed prism of `sides` around the z axis: radius r, z in [z0, z1].
Mesh PipeMesh(int sides, double r, double z0, double z1) {
  Mesh m;
  for (int i = 0; i < sides; ++i) {
    const double t = 2 * std::numbers::pi * i / sides;
    AddVertex(&m, r * std::cos(t), r * std::sin(t), z0);
    AddVertex(&m, r * std::cos(t), r * std::sin(t), z1);
  }
  const uint32_t c0 = AddVertex(&m, 0, 0, z0), c1 = AddVertex(&m, 0, 0, z1);
  for (uint32_t i = 0; i < uint32_t(sides); ++i) {
    const uint32_t j = (i + 1) % sides;
    m.triangles.insert(m.triangles.end(), {2 * i, 2 * j, 2 * j + 1, 2 * i, 2 * j + 1, 2 * i + 1, c0, 2 * j,
                                           2 * i, c1, 2 * i + 1, 2 * j + 1});
  }
  return m;
}

Mesh QuadMesh(const Vec3d& o, const Vec3d& u, const Vec3d& v) {  // an open sheet, two triangles
  Mesh m;
  AddVertex(&m, o.x, o.y, o.z);
  AddVertex(&m, o.x + u.x, o.y + u.y, o.z + u.z);
  AddVertex(&m, o.x + u.x + v.x, o.y + u.y + v.y, o.z + u.z + v.z);
  AddVertex(&m, o.x + v.x, o.y + v.y, o.z + v.z);
  m.triangles = {0, 1, 2, 0, 2, 3};
  return m;
}

TEST(Separate, BoxInsideBox) {
  const Mesh outer = BoxMesh({0, 0, 0}, {1, 1, 1}), inner = BoxMesh({0.25, 0.4, 0.4}, {0.75, 0.6, 0.6});
  const Separation r = Check(inner, outer, 0, "inner, outer");
  EXPECT_EQ(r.meeting, Meeting::kAInsideB);
  // Deepest inner vertex: 0.25 from the outer's x faces; the k-DOP's smallest overlap is on y: 0.6, which
  // is the exact depth (moving the inner box 0.6 along y takes it out).
  EXPECT_NEAR(r.depth_lower, 0.25, 1e-7);
  EXPECT_NEAR(r.depth_upper, 0.6, 1e-7);
  EXPECT_TRUE(outer.Bounds().Contains(r.point_a));
}

TEST(Separate, BoxesTouchingFaceToFace) {
  const Mesh a = BoxMesh({0, 0, 0}, {1, 1, 1}), b = BoxMesh({1, 0.5, 0.25}, {2, 1.5, 0.75});
  const Separation r = Check(a, b, 0.05, "face to face");
  EXPECT_EQ(r.meeting, Meeting::kSurfacesMeet);
  EXPECT_EQ(r.depth_upper, 0);  // exactly: the x intervals share one value
  EXPECT_EQ(r.depth_lower, 0);
  EXPECT_EQ(r.point_a.x, 1);
}

TEST(Separate, BoxesOverlappingByOneMillimetre) {
  const double T = 0.002;
  {
    const Mesh a = BoxMesh({0, 0, 0}, {1, 1, 1}), b = BoxMesh({0.999, 0, 0}, {2, 1, 1});
    const Separation r = Check(a, b, 0, "flush sides");
    EXPECT_EQ(r.meeting, Meeting::kSurfacesMeet);
    EXPECT_NEAR(r.depth_upper, 0.001, 1e-7);
    EXPECT_LE(r.depth_upper, T);  // a touch
    EXPECT_EQ(r.depth_lower, 0);  // every vertex inside lies on the other's boundary
  }
  {
    const Mesh a = BoxMesh({0, 0, 0}, {1, 1, 1}), b = BoxMesh({0.999, -1, -1}, {2, 2, 2});
    const Separation r = Check(a, b, 0, "into a larger box");
    EXPECT_NEAR(r.depth_upper, 0.001, 1e-7);
    EXPECT_NEAR(r.depth_lower, 0.001, 1e-7);  // the bounds coincide (up to float32 vertices)
  }
}

// A gap far below the point classifier's surface tolerance is still a gap, not containment.
TEST(Separate, GapBelowTheSurfaceToleranceIsApart) {
  const Mesh a = BoxMesh({0, 0, 0}, {1, 1, 1});
  for (double gap : {1e-12, 1e-14}) {
    const Mesh b = Shifted(BoxMesh({1, 0.25, 0.25}, {2, 0.75, 0.75}), {gap, 0, 0});
    const Separation r = Check(a, b, 0.01, "tiny gap");
    EXPECT_EQ(r.meeting, Meeting::kApart);
    EXPECT_NEAR(r.distance, gap, 1e-15);
    EXPECT_GT(r.distance, 0);
  }
}

TEST(Separate, PipeThroughPlate) {
  const Mesh pipe = PipeMesh(16, 0.05, -1, 1), plate = BoxMesh({-1, -1, -0.01}, {1, 1, 0.01});
  const Separation r = Check(pipe, plate, 0, "pipe, plate");
  EXPECT_EQ(r.meeting, Meeting::kSurfacesMeet);
  // No vertex of either is inside the other, but the plate's diagonal edges run through the pipe's axis:
  // their midpoint there is the pipe's inradius from its surface.
  EXPECT_NEAR(r.depth_lower, 0.05 * std::cos(std::numbers::pi / 16), 1e-6);
  EXPECT_GT(r.depth_upper, 0.9);
  EXPECT_NEAR(std::fabs(r.point_a.z), 0.01, 1e-6);
}

TEST(Separate, NearMissWithinClearance) {
  const Mesh a = BoxMesh({0, 0, 0}, {1, 1, 1}), b = BoxMesh({1.01, 0.2, 0.2}, {2, 0.8, 0.8});
  const Separation r = Check(a, b, 0.05, "C = 5 cm");
  EXPECT_EQ(r.meeting, Meeting::kApart);
  EXPECT_NEAR(r.distance, 0.01, 1e-7);
  EXPECT_NEAR(r.point_a.x, 1, 1e-7);
  EXPECT_NEAR(r.point_b.x, 1.01, 1e-7);
  NarrowStats st;
  const ClashShape sa(a), sb(b);
  EXPECT_EQ(Separate(sa, sb, 0, &st).distance, kInf);  // the bound decides: no triangle tested
  EXPECT_EQ(Separate(sa, sb, 0.005, &st).distance, kInf);
  EXPECT_EQ(st.bound_rejects, 2u);
  EXPECT_EQ(st.triangle_tests, 0u);
  Check(a, b, 0.005, "C = 5 mm");
  // A rotated near miss: the bound cannot reject it, the triangles decide.
  Check(a, Transformed(b, 0.3, {1, 1, 0}, {0.2, 0, 0}), 0.05, "rotated");
}

// The hierarchy and classifier are built by the first pair that needs them, once; the bound alone
// decides pairs apart.
TEST(Separate, PartsBuiltOnFirstUse) {
  const Mesh a = BoxMesh({0, 0, 0}, {1, 1, 1}), far = BoxMesh({3, 0, 0}, {4, 1, 1}),
             in = BoxMesh({0.2, 0.2, 0.2}, {0.8, 0.8, 0.8});
  const ClashShape sa(a), sf(far), si(in);
  const size_t bare = sa.MemoryBytes();
  NarrowStats st;
  EXPECT_EQ(Separate(sa, sf, 0, &st).meeting, Meeting::kApart);
  EXPECT_FALSE(sa.built().hierarchy);
  EXPECT_FALSE(sa.built().classifier);
  EXPECT_EQ(st.hierarchies_built, 0u);
  const Separation r = Separate(si, sa, 0, &st);
  EXPECT_EQ(r.meeting, Meeting::kAInsideB);
  EXPECT_TRUE(sa.built().hierarchy);
  EXPECT_TRUE(sa.built().classifier);
  EXPECT_EQ(st.hierarchies_built, 2u);
  EXPECT_GE(st.classifiers_built, 1u);
  EXPECT_GT(sa.MemoryBytes(), bare);
  // A second pair builds nothing more, and the answer is that of fresh shapes.
  const NarrowStats before = st;
  const Separation again = Separate(si, sa, 0, &st);
  EXPECT_EQ(st.hierarchies_built, before.hierarchies_built);
  EXPECT_EQ(st.classifiers_built, before.classifiers_built);
  EXPECT_EQ(again.meeting, r.meeting);
  EXPECT_EQ(again.depth_lower, r.depth_lower);
  EXPECT_EQ(again.depth_upper, r.depth_upper);
}

TEST(Separate, OpenSheetIsASurface) {
  const Mesh box = BoxMesh({0, 0, 0}, {1, 1, 1});
  const Mesh crossing = QuadMesh({-0.5, -0.5, 0.5}, {2, 0, 0}, {0, 2, 0});
  const Mesh inside = QuadMesh({0.25, 0.25, 0.5}, {0.5, 0, 0}, {0, 0.5, 0});
  const ClashShape sheet(inside);
  EXPECT_FALSE(sheet.solid());
  const Separation r = Check(crossing, box, 0, "crossing");
  EXPECT_EQ(r.meeting, Meeting::kSurfacesMeet);
  EXPECT_EQ(r.depth_lower, 0);
  const Separation s = Check(inside, box, 0.3, "inside");
  EXPECT_EQ(s.meeting, Meeting::kApart);  // nothing is inside a surface, and a surface meets by contact
  EXPECT_NEAR(s.distance, 0.25, 1e-7);
  Check(inside, box, 0, "inside, no clearance");
  Check(inside, crossing, 0, "two sheets, coplanar");
}

TEST(Separate, EmptyMeshMeetsNothing) {
  const Mesh empty, box = BoxMesh({0, 0, 0}, {1, 1, 1});
  const ClashShape se(empty), sb(box);
  EXPECT_EQ(Separate(se, sb, 1, nullptr).meeting, Meeting::kApart);
  EXPECT_EQ(Separate(sb, se, 1, nullptr).distance, kInf);
  EXPECT_FALSE(se.solid());
}

TEST(Separate, ValidateRejectsBadMeshes) {
  Mesh m = BoxMesh({0, 0, 0}, {1, 1, 1});
  EXPECT_TRUE(ValidateClashMesh(m).ok());
  m.vertices[4] = std::nan("");
  EXPECT_FALSE(ValidateClashMesh(m).ok());
  m = BoxMesh({0, 0, 0}, {1, 1, 1});
  m.triangles[5] = 99;
  EXPECT_NE(ValidateClashMesh(m).ToString().find("99"), std::string::npos);
}

// Random small solids and sheets, many meeting, touching, nested and near: every pair against the oracle.
TEST(Separate, RandomSmallMeshesAgainstBruteForce) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Mesh> meshes;
  for (int i = 0; i < 60; ++i) {
    const Vec3d at{u(rng) * 3, u(rng) * 3, u(rng) * 3};
    Mesh m;
    switch (i % 6) {
      case 0:  // an axis-aligned box on a 0.25 grid: faces touch and overlap exactly
        m = BoxMesh(
            {std::floor(at.x * 4) / 4, std::floor(at.y * 4) / 4, std::floor(at.z * 4) / 4},
            {std::floor(at.x * 4) / 4 + 0.5, std::floor(at.y * 4) / 4 + 0.75, std::floor(at.z * 4) / 4 + 1});
        break;
      case 1:
        m = Transformed(BoxMesh({0, 0, 0}, {0.6, 0.3, 0.9}), u(rng) * 3, {u(rng), u(rng), u(rng)}, at);
        break;
      case 2:
        m = Shifted(UvSphereMesh(6, 8, 0.2 + 0.5 * u(rng)), at);
        break;
      case 3:
        m = Shifted(BoxMesh({0, 0, 0}, {0.1, 0.1, 0.1}), at);  // small: often inside another
        break;
      case 4:
        m = Transformed(PipeMesh(8, 0.05, -1, 1), u(rng) * 3, {u(rng), u(rng), u(rng)}, at);
        break;
      default:
        m = QuadMesh(at, {u(rng), u(rng), 0}, {0, u(rng), u(rng)});
    }
    meshes.push_back(std::move(m));
  }
  // Planted: exactly nested and coplanar faces.
  meshes.push_back(BoxMesh({1, 1, 1}, {2, 2, 2}));
  meshes.push_back(BoxMesh({1.25, 1.25, 1.25}, {1.5, 1.5, 1.5}));
  meshes.push_back(BoxMesh({2, 1, 1}, {2.5, 2, 2}));
  meshes.push_back(BoxMesh({4, 4, 4}, {5, 5, 5}));
  meshes.push_back(Shifted(UvSphereMesh(6, 8, 0.3), {4.5, 4.5, 4.5}));
  meshes.push_back(BoxMesh({4.45, 4.45, 4.45}, {4.55, 4.55, 4.55}));
  int by_kind[4] = {0, 0, 0, 0}, near = 0;
  for (size_t i = 0; i < meshes.size(); ++i)
    for (size_t j = i + 1; j < meshes.size(); ++j) {
      const Separation r = Check(meshes[i], meshes[j], 0.3, "random pair");
      // The hierarchies' walk decides meeting as the small-mesh scan does (most pairs here take the scan).
      SeparateOptions walk;
      walk.brute_force_triangles = 0;
      EXPECT_EQ(Separate(ClashShape(meshes[i]), ClashShape(meshes[j]), 0.3, nullptr, walk).meeting,
                r.meeting);
      ++by_kind[static_cast<int>(r.meeting)];
      near += r.meeting == Meeting::kApart && r.distance < kInf;
      if (::testing::Test::HasFailure()) FAIL() << "pair " << i << ", " << j;
    }
  EXPECT_GT(by_kind[static_cast<int>(Meeting::kSurfacesMeet)], 30);
  EXPECT_GT(by_kind[static_cast<int>(Meeting::kAInsideB)] + by_kind[static_cast<int>(Meeting::kBInsideA)], 3);
  EXPECT_GT(near, 30);
}

// Two overlapping axis-aligned boxes: the penetration depth is exactly the smallest overlap of their
// x, y and z intervals. Both bounds must hold; the upper one is exact here.
TEST(Separate, DepthBoundsHoldForOverlappingBoxes) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  int exact = 0;
  for (int i = 0; i < 300; ++i) {
    Vec3d lo[2], hi[2];
    for (int k = 0; k < 2; ++k) {
      lo[k] = {u(rng), u(rng), u(rng)};
      hi[k] = {lo[k].x + 0.2 + u(rng), lo[k].y + 0.2 + u(rng), lo[k].z + 0.2 + u(rng)};
    }
    const Mesh a = BoxMesh(lo[0], hi[0]), b = BoxMesh(lo[1], hi[1]);
    // The depth of the boxes as stored (BoxMesh rounds corners to float).
    const Box3d ba = a.Bounds(), bb = b.Bounds();
    double depth = kInf;
    for (int k = 0; k < 3; ++k)
      depth = std::min(depth, std::min(ba.max[k] - bb.min[k], bb.max[k] - ba.min[k]));
    if (depth < 0) continue;
    const ClashShape sa(a), sb(b);
    const Separation r = Separate(sa, sb, 0, nullptr);
    ASSERT_NE(r.meeting, Meeting::kApart);
    EXPECT_LE(r.depth_lower, depth + 1e-12);
    EXPECT_GE(r.depth_upper, depth - 1e-12);
    EXPECT_NEAR(r.depth_upper, depth, 1e-12);
    exact += r.depth_lower > depth - 1e-9;
    // The options change the work, never the answer (depth_lower: only how far it is raised).
    SeparateOptions aabb;
    aabb.bound_directions = kAabbDirections;
    aabb.brute_force_triangles = 0;
    const Separation s = Separate(sa, sb, 0, nullptr, aabb);
    EXPECT_EQ(s.meeting, r.meeting);
    EXPECT_EQ(s.depth_upper, r.depth_upper);
    EXPECT_EQ(s.depth_lower, r.depth_lower);
    SeparateOptions enough;
    enough.depth_lower_enough = 0.002;
    const Separation e = Separate(sa, sb, 0, nullptr, enough);
    EXPECT_EQ(e.depth_upper, r.depth_upper);
    EXPECT_LE(e.depth_lower, r.depth_lower);
    if (r.depth_upper <= 0.002) {
      EXPECT_EQ(e.depth_lower, 0);  // already a touch by its bounds: no depth search
    } else {
      EXPECT_GE(e.depth_lower, std::min(r.depth_lower, 0.002));
    }
  }
  EXPECT_GT(exact, 10);  // a box corner deep inside the other makes the lower bound exact too
}

// An L-shaped prism (arms 1 thick, 10 long, z in [0, 1]) and a box in its inner corner pushed px into
// the upright arm and py into the lying one. No plane parts them and the projections overlap by 0.8 at
// least (the box can leave upward), but moving the box by (px, py) does: the depth is hypot(px, py).
struct CornerPair {
  Mesh l, box;
};
CornerPair BoxInCorner(double px, double py) {
  CornerPair c;
  c.l = testing::Prism({{0, 0}, {10, 0}, {10, 1}, {1, 1}, {1, 10}, {0, 10}}, testing::Fan(6), 0, 1);
  c.box = testing::Box({1 - px, 1 - py, 0.2}, {3, 3, 0.8});
  return c;
}

// The translation certificate: a box touching the corner (its vertices crossing by 1e-7, as float32
// rounding leaves touching members) is a touch at T = 2 mm, though no plane and no projection shows it.
TEST(Separate, TranslationCertificateDecidesACornerTouch) {
  const CornerPair c = BoxInCorner(1e-7, 1e-7);
  const ClashShape l(c.l), box(c.box);
  ASSERT_TRUE(l.solid() && box.solid());
  SeparateOptions t;
  t.depth_lower_enough = 0.002;
  for (const auto& [x, y] : {std::pair{&l, &box}, std::pair{&box, &l}}) {
    NarrowStats st;
    const Separation r = Separate(*x, *y, 0, &st, t);
    ASSERT_EQ(r.meeting, Meeting::kSurfacesMeet);
    EXPECT_GT(r.depth_lower, 0);
    EXPECT_LE(r.depth_lower, std::hypot(1e-7, 1e-7) + 1e-12);
    EXPECT_GE(r.depth_upper, std::hypot(1e-7, 1e-7));  // an upper bound on the true depth
    EXPECT_LE(r.depth_upper, 1e-6);                    // shortened along the diagonal that parted them
    EXPECT_EQ(r.distance, -r.depth_upper);
    EXPECT_LE(st.hierarchies_built, 2u);  // the moved copies' hierarchies are not the objects' parts
  }
  // Without a finite `enough` nothing asks the class: the projection bound stays.
  const Separation plain = Separate(l, box, 0, nullptr);
  EXPECT_GE(plain.depth_upper, 0.8 - 1e-12);
  EXPECT_EQ(plain.meeting, Meeting::kSurfacesMeet);
}

// The same with the L as a surface (one cap triangle left out: open): a surface has no inside, so only
// its triangles must part, and the translation decides it too.
TEST(Separate, TranslationCertificateDecidesASurfaceInACorner) {
  CornerPair c = BoxInCorner(1e-7, 1e-7);
  c.l.triangles.resize(c.l.triangles.size() - 3);
  const ClashShape l(c.l), box(c.box);
  ASSERT_FALSE(l.solid());
  SeparateOptions t;
  t.depth_lower_enough = 0.002;
  const Separation r = Separate(box, l, 0, nullptr, t);
  ASSERT_EQ(r.meeting, Meeting::kSurfacesMeet);
  EXPECT_EQ(r.depth_lower, 0);
  EXPECT_GE(r.depth_upper, std::hypot(1e-7, 1e-7));
  EXPECT_LE(r.depth_upper, 1e-6);
  // 5 mm into both arms: no translation of 2 mm parts them.
  CornerPair deep = BoxInCorner(0.005, 0.005);
  deep.l.triangles.resize(deep.l.triangles.size() - 3);
  const ClashShape dl(deep.l), dbox(deep.box);
  EXPECT_GT(Separate(dbox, dl, 0, nullptr, t).depth_upper, 0.002);
}

// Never a touch deeper than T: over pushes on both sides of T the certificate says touch only where the
// true depth hypot(px, py) is at most T, and every depth_upper bounds the true depth. The L is a surface
// here: two solids overlapping this deep do not try the certificate (kTranslationLowerShare).
TEST(Separate, TranslationCertificateNeverHidesAClash) {
  constexpr double kT = 0.002;
  SeparateOptions t;
  t.depth_lower_enough = kT;
  std::mt19937_64 rng(36);
  std::uniform_real_distribution<double> push(0, 2.5 * kT);
  int touches = 0, hard = 0;
  for (int i = 0; i < 60; ++i) {
    // The first four: one side only, or both at 0.7 T (parted only along the diagonal).
    const double px = i < 4 ? (i & 1 ? 0.0 : kT * 0.7) : push(rng);
    const double py = i < 4 ? (i & 2 ? 0.0 : kT * 0.7) : push(rng);
    if (px == 0 && py == 0) continue;
    CornerPair c = BoxInCorner(px, py);
    c.l.triangles.resize(c.l.triangles.size() - 3);
    const ClashShape l(c.l), box(c.box);
    const double depth = std::hypot(px, py);
    const Separation r = Separate(box, l, 0, nullptr, t);
    ASSERT_EQ(r.meeting, Meeting::kSurfacesMeet) << px << " " << py;
    EXPECT_GE(r.depth_upper, depth * (1 - 1e-9)) << px << " " << py;
    if (r.depth_upper <= kT) {
      ++touches;
      EXPECT_LE(depth, kT) << px << " " << py;
    } else {
      ++hard;
    }
    // The certificate finds the diagonal whenever it parts them at T.
    if (std::max(px, py) * std::sqrt(2.0) < kT * 0.999) {
      EXPECT_LE(r.depth_upper, kT) << px << " " << py;
    }
  }
  EXPECT_GT(touches, 5);
  EXPECT_GT(hard, 5);
}

TEST(Separate, TranslationInvariance) {
  const Mesh a = Transformed(BoxMesh({0, 0, 0}, {1, 0.5, 0.2}), 0.4, {1, 2, 3}, {0, 0, 0});
  const Mesh b = Transformed(UvSphereMesh(8, 12, 0.3), 0.1, {0, 0, 1}, {1.1, 0.3, 0.2});
  const ClashShape sa(a), sb(b);
  const Separation r = Separate(sa, sb, 1, nullptr);
  for (const Vec3d d : {Vec3d{100, -50, 3}, Vec3d{1e4, 1e4, -1e4}}) {
    const Mesh a2 = Shifted(a, d), b2 = Shifted(b, d);
    const ClashShape sa2(a2), sb2(b2);
    const Separation s = Separate(sa2, sb2, 1, nullptr);
    EXPECT_EQ(s.meeting, r.meeting);
    EXPECT_NEAR(s.distance, r.distance, 1e-11 * (1 + std::fabs(d.x)));
    EXPECT_NEAR(s.point_a.x - d.x, r.point_a.x, 1e-9 * (1 + std::fabs(d.x)));
  }
}

// Shapes are shared read-only by threads (the per-thread scratch must not leak between them).
TEST(Separate, ConcurrentCallsAgreeWithOneThread) {
  std::vector<Mesh> meshes;
  for (int i = 0; i < 12; ++i) {
    meshes.push_back(Transformed(UvSphereMesh(8, 10, 0.4), 0.1 * i, {1, 0, 1}, {0.3 * i, 0.1 * (i % 3), 0}));
    meshes.push_back(BoxMesh({0.3 * i, 0, 0}, {0.3 * i + 0.05, 0.05, 0.05}));  // small: brute-force path
  }
  std::vector<ClashShape> shapes;
  for (const Mesh& m : meshes) shapes.emplace_back(m);
  auto all = [&] {
    std::vector<Separation> out;
    for (size_t i = 0; i < shapes.size(); ++i)
      for (size_t j = i + 1; j < shapes.size(); ++j)
        out.push_back(Separate(shapes[i], shapes[j], 0.2, nullptr));
    return out;
  };
  const std::vector<Separation> want = all();
  std::vector<std::vector<Separation>> got(4);
  std::vector<std::thread> threads;
  for (auto& g : got) threads.emplace_back([&g, &all] { g = all(); });
  for (auto& t : threads) t.join();
  for (const auto& g : got) {
    ASSERT_EQ(g.size(), want.size());
    for (size_t k = 0; k < g.size(); ++k) {
      EXPECT_EQ(g[k].meeting, want[k].meeting);
      EXPECT_EQ(g[k].distance, want[k].distance);
      EXPECT_EQ(g[k].depth_lower, want[k].depth_lower);
    }
  }
}

// Real meshes: a copy translated to overlap, to a near miss, and a small solid inside.
class RealMeshSeparation : public ::testing::TestWithParam<const char*> {};

TEST_P(RealMeshSeparation, TranslatedCopies) {
  const Result<Mesh> read = testing::ReadSharedMesh(GetParam());
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  const Mesh& m = *read;
  const Box3d b = m.Bounds();
  const double w = b.max[0] - b.min[0], diag = testing::Diagonal(b);
  const double c = 0.02 * diag;
  // Overlapping by 5 % of the width: surfaces cross.
  const Separation over = Check(m, Shifted(m, {0.95 * w, 0.01 * w, 0}), c, "overlap");
  EXPECT_EQ(over.meeting, Meeting::kSurfacesMeet);
  EXPECT_GT(over.depth_upper, 0);
  // Beyond the width: a gap, found below the clearance or not.
  const Separation miss = Check(m, Shifted(m, {1.005 * w, 0, 0}), c, "near miss");
  EXPECT_EQ(miss.meeting, Meeting::kApart);
  EXPECT_LT(miss.distance, c);
  Check(m, Shifted(m, {1.2 * w, 0, 0}), c, "far");
  // A small box around a point deep inside: contained.
  const SolidClassifier sc(m);
  std::mt19937_64 rng(3);
  Vec3d p;
  double depth = 0;
  for (int i = 0; i < 2000; ++i) {
    const Vec3d q = testing::RandomIn(b, rng);
    const double d = testing::SurfaceDistance(m, q);
    if (d > depth && sc.Contains(q)) p = q, depth = d;
    if (depth > 0.03 * diag) break;
  }
  ASSERT_GT(depth, 0);
  const double h = depth / 4;
  const Mesh small = BoxMesh({p.x - h, p.y - h, p.z - h}, {p.x + h, p.y + h, p.z + h});
  const Separation in = Check(small, m, c, "inside");
  EXPECT_EQ(in.meeting, Meeting::kAInsideB);
  EXPECT_GT(in.depth_lower, depth - 2 * h);  // a corner is sqrt(3) h from the centre
}

INSTANTIATE_TEST_SUITE_P(Meshes, RealMeshSeparation,
                         ::testing::Values("gearwheel.bin.stl", "fandisk.off", "armadillo.off"));

}  // namespace
}  // namespace mktree
