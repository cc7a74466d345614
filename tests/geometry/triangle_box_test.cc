#include "engine/geometry/triangle_box.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "geometry/test_meshes.h"

namespace mktree {
namespace {

using testing::MakeBox;

// Reference: Sutherland-Hodgman clipping of the triangle by the six closed half-spaces of the box;
// the triangle meets the box iff something is left. A different algorithm from the SAT under test.
bool ClipReference(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Box3d& box) {
  std::vector<Vec3d> poly = {a, b, c};
  for (int k = 0; k < 3 && !poly.empty(); ++k) {
    for (int side = 0; side < 2 && !poly.empty(); ++side) {
      // Keep s * (p[k] - bound) <= 0.
      const double bound = side == 0 ? box.max[k] : box.min[k];
      const double s = side == 0 ? 1 : -1;
      std::vector<Vec3d> out;
      for (size_t i = 0; i < poly.size(); ++i) {
        const Vec3d& p = poly[i];
        const Vec3d& q = poly[(i + 1) % poly.size()];
        const double dp = s * (p[k] - bound), dq = s * (q[k] - bound);
        if (dp <= 0) out.push_back(p);
        if ((dp < 0 && dq > 0) || (dp > 0 && dq < 0)) {
          const double t = dp / (dp - dq);
          Vec3d x{p.x + t * (q.x - p.x), p.y + t * (q.y - p.y), p.z + t * (q.z - p.z)};
          x[k] = bound;
          out.push_back(x);
        }
      }
      poly = std::move(out);
    }
  }
  return !poly.empty();
}

TEST(TriangleBoxTest, AgreesWithClippingOnRandomCasesAwayFromDegeneracy) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1), size(0.0, 0.8);
  int meets = 0, misses = 0;
  for (int it = 0; it < 200000; ++it) {
    const Vec3d a{u(rng), u(rng), u(rng)};
    // Mix of large and small triangles, so that edge-axis and normal-axis separations both occur.
    const double s = it % 2 ? 0.3 : 1.0;
    const Vec3d b{a.x + s * u(rng), a.y + s * u(rng), a.z + s * u(rng)};
    const Vec3d c{a.x + s * u(rng), a.y + s * u(rng), a.z + s * u(rng)};
    const double x = u(rng), y = u(rng), z = u(rng);
    const Box3d box = MakeBox(x, y, z, x + size(rng), y + size(rng), z + size(rng));
    // Away from degeneracy: the answer does not change when the box grows or shrinks by 1e-9.
    const double d = 1e-9;
    const bool inner = ClipReference(a, b, c,
                                     MakeBox(box.min[0] + d, box.min[1] + d, box.min[2] + d, box.max[0] - d,
                                             box.max[1] - d, box.max[2] - d));
    const bool outer = ClipReference(a, b, c,
                                     MakeBox(box.min[0] - d, box.min[1] - d, box.min[2] - d, box.max[0] + d,
                                             box.max[1] + d, box.max[2] + d));
    if (inner != outer) continue;
    ASSERT_EQ(TriangleMeetsBox(a, b, c, box), inner) << "iteration " << it;
    (inner ? meets : misses)++;
  }
  EXPECT_GT(meets, 3000);
  EXPECT_GT(misses, 20000);
}

TEST(TriangleBoxTest, TouchingIsMeetingAndAHairAwayIsNot) {
  const Box3d box = MakeBox(0, 0, 0, 1, 1, 1);
  const double h = 1e-9;
  // A vertex on a face, an edge lying on a face, a coplanar overlap with a face.
  EXPECT_TRUE(TriangleMeetsBox({1, 0.5, 0.5}, {2, 0.5, 0.5}, {2, 0.7, 0.2}, box));
  EXPECT_FALSE(TriangleMeetsBox({1 + h, 0.5, 0.5}, {2, 0.5, 0.5}, {2, 0.7, 0.2}, box));
  EXPECT_TRUE(TriangleMeetsBox({0.2, 0.3, 1}, {0.8, 0.3, 1}, {0.5, 0.3, 3}, box));
  EXPECT_TRUE(TriangleMeetsBox({-1, -1, 1}, {3, -1, 1}, {-1, 3, 1}, box));
  EXPECT_FALSE(TriangleMeetsBox({-1, -1, 1 + h}, {3, -1, 1 + h}, {-1, 3, 1 + h}, box));
  // Touching a box edge and a box corner.
  EXPECT_TRUE(TriangleMeetsBox({1, 1, -5}, {1, 1, 5}, {3, 2, 0}, box));
  EXPECT_FALSE(TriangleMeetsBox({1 + h, 1, -5}, {1 + h, 1, 5}, {3, 2, 0}, box));
  EXPECT_TRUE(TriangleMeetsBox({1, 1, 1}, {2, 1.5, 1.2}, {1.3, 2, 1.1}, box));
  EXPECT_FALSE(TriangleMeetsBox({1 + h, 1, 1}, {2, 1.5, 1.2}, {1.3, 2, 1.1}, box));
  // A plane cutting off exactly the corner (1,1,1): x + y + z = 3, only the normal axis can separate.
  EXPECT_TRUE(TriangleMeetsBox({3, 0, 0}, {0, 3, 0}, {0, 0, 3}, box));
  EXPECT_FALSE(TriangleMeetsBox({3 + 3 * h, 0, 0}, {0, 3 + 3 * h, 0}, {0, 0, 3 + 3 * h}, box));
  // Touching the box edge x = y = 1 at one point (1, 1, 0.5) where only an edge-cross axis separates:
  // the triangle lies in x + y >= 2 and meets x + y = 2 along its first edge.
  EXPECT_TRUE(TriangleMeetsBox({2, 0, 0.5}, {0, 2, 0.5}, {2, 2, 1.5}, box));
  EXPECT_FALSE(TriangleMeetsBox({2 + h, 0, 0.5}, {h, 2, 0.5}, {2 + h, 2, 1.5}, box));
  // The triangle's interior passing through the whole box, no vertex inside.
  EXPECT_TRUE(TriangleMeetsBox({-10, -10, 0.5}, {10, -10, 0.5}, {0, 10, 0.5}, box));
  // Box entirely inside a flat triangle? Impossible for a thick box; a flat box in its plane works.
  EXPECT_TRUE(TriangleMeetsBox({-10, -10, 0.5}, {10, -10, 0.5}, {0, 10, 0.5}, MakeBox(0, 0, 0.5, 1, 1, 0.5)));
  EXPECT_FALSE(
      TriangleMeetsBox({-10, -10, 0.5}, {10, -10, 0.5}, {0, 10, 0.5}, MakeBox(0, 0, 0.6, 1, 1, 0.6)));
}

TEST(TriangleBoxTest, DegenerateTrianglesAndBoxes) {
  const Box3d box = MakeBox(0, 0, 0, 1, 1, 1);
  // Zero-area triangles: a segment through the box, a segment passing its corner, a point.
  EXPECT_TRUE(TriangleMeetsBox({-1, 0.5, 0.5}, {2, 0.5, 0.5}, {0.5, 0.5, 0.5}, box));
  EXPECT_TRUE(TriangleMeetsBox({-1, -1, -1}, {2, 2, 2}, {2, 2, 2}, box));
  EXPECT_TRUE(TriangleMeetsBox({0, 2, 0.5}, {2, 0, 0.5}, {1, 1, 0.5}, box));  // x + y = 2 touches an edge
  EXPECT_FALSE(TriangleMeetsBox({0, 2.001, 0.5}, {2.001, 0, 0.5}, {1.0005, 1.0005, 0.5}, box));
  EXPECT_TRUE(TriangleMeetsBox({0.5, 0.5, 0.5}, {0.5, 0.5, 0.5}, {0.5, 0.5, 0.5}, box));
  EXPECT_TRUE(TriangleMeetsBox({1, 1, 1}, {1, 1, 1}, {1, 1, 1}, box));
  EXPECT_FALSE(TriangleMeetsBox({1, 1, 1.001}, {1, 1, 1.001}, {1, 1, 1.001}, box));
  // Zero-thickness boxes: a rectangle, a segment, a point.
  const Vec3d a{0, 0, 0}, b{2, 0, 0}, c{0, 2, 2};  // plane y = z
  EXPECT_TRUE(TriangleMeetsBox(a, b, c, MakeBox(0.2, 0.5, 0, 0.4, 0.5, 1)));
  EXPECT_TRUE(TriangleMeetsBox(a, b, c, MakeBox(0.2, 0.5, 0.5, 0.4, 0.5, 0.5)));
  EXPECT_TRUE(TriangleMeetsBox(a, b, c, MakeBox(0.5, 0.5, 0.5, 0.5, 0.5, 0.5)));
  EXPECT_FALSE(TriangleMeetsBox(a, b, c, MakeBox(0.5, 0.5, 0.6, 0.5, 0.5, 0.6)));
  // Empty and unbounded boxes.
  EXPECT_FALSE(TriangleMeetsBox(a, b, c, Box3d{}));
  EXPECT_TRUE(
      TriangleMeetsBox(a, b, c, MakeBox(-INFINITY, -INFINITY, -INFINITY, INFINITY, INFINITY, INFINITY)));
  EXPECT_FALSE(TriangleMeetsBox(a, b, c, MakeBox(-INFINITY, -INFINITY, 3, INFINITY, INFINITY, INFINITY)));
}

}  // namespace
}  // namespace mktree
