// Scene model basics: outward rounding of stored boxes, mesh bounds, raw geometry size.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {
namespace {

Box3d BoxOf(double lo, double hi) {
  Box3d b;
  b.Extend(lo, lo, lo);
  b.Extend(hi, hi, hi);
  return b;
}

TEST(RoundOutwardTest, NonRepresentableDoublesRoundOutward) {
  // 0.1 and 1/3 are not floats; whichever way the cast rounds, the stored box must contain them.
  const double values[] = {0.1, 1.0 / 3.0, 123456.789, 1e-3, 2.0 / 3.0, 9.87654321e7};
  for (double v : values) {
    Box3f f = RoundOutward(BoxOf(v, v));
    for (int i = 0; i < 3; ++i) {
      EXPECT_LT(static_cast<double>(f.min[i]), v) << v;
      EXPECT_GT(static_cast<double>(f.max[i]), v) << v;
      // ...and by no more than one float step.
      EXPECT_EQ(std::nextafter(f.min[i], std::numeric_limits<float>::infinity()), f.max[i]) << v;
    }
  }
}

TEST(RoundOutwardTest, NegativeValuesRoundAwayFromTheBoxInterior) {
  const double values[] = {-0.1, -1.0 / 3.0, -123456.789, -9.87654321e7};
  for (double v : values) {
    Box3f f = RoundOutward(BoxOf(v, v));
    for (int i = 0; i < 3; ++i) {
      EXPECT_LT(static_cast<double>(f.min[i]), v) << v;
      EXPECT_GT(static_cast<double>(f.max[i]), v) << v;
    }
  }
  // A box spanning zero: min goes down (more negative), max goes up.
  Box3f f = RoundOutward(BoxOf(-0.1, 0.1));
  EXPECT_LT(static_cast<double>(f.min[0]), -0.1);
  EXPECT_GT(static_cast<double>(f.max[0]), 0.1);
}

TEST(RoundOutwardTest, ExactFloatsAreUnchanged) {
  const float values[] = {0.0f,
                          1.0f,
                          -2.5f,
                          0.125f,
                          1e30f,
                          -3.0e-20f,
                          std::numeric_limits<float>::max(),
                          std::numeric_limits<float>::denorm_min()};
  for (float v : values) {
    Box3f f = RoundOutward(BoxOf(v, v));
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(f.min[i], v);
      EXPECT_EQ(f.max[i], v);
    }
  }
}

TEST(RoundOutwardTest, DoublesBeyondFloatRangeBecomeInfinite) {
  Box3f f = RoundOutward(BoxOf(-1e300, 1e300));
  EXPECT_EQ(f.min[0], -std::numeric_limits<float>::infinity());
  EXPECT_EQ(f.max[0], std::numeric_limits<float>::infinity());
}

TEST(RoundOutwardTest, EmptyBoxStaysEmpty) { EXPECT_TRUE(RoundOutward(Box3d()).empty()); }

TEST(MeshTest, BoundsCoverEveryVertex) {
  Mesh m;
  m.vertices = {1, -2, 3, -4, 5, -6, 0.5f, 0.25f, 10};
  m.triangles = {0, 1, 2};
  Box3d b = m.Bounds();
  EXPECT_EQ(b.min[0], -4);
  EXPECT_EQ(b.min[1], -2);
  EXPECT_EQ(b.min[2], -6);
  EXPECT_EQ(b.max[0], 1);
  EXPECT_EQ(b.max[1], 5);
  EXPECT_EQ(b.max[2], 10);
  SceneObject o;
  o.mesh = m;
  EXPECT_EQ(o.Aabb(), RoundOutward(b));
}

TEST(MeshTest, EmptyMeshHasEmptyBounds) {
  Mesh m;
  EXPECT_TRUE(m.Bounds().empty());
  EXPECT_TRUE(SceneObject().Aabb().empty());
}

TEST(MeshTest, RawGeometryBytesCountsHeaderVerticesAndTriangles) {
  Mesh m;
  EXPECT_EQ(m.RawGeometryBytes(), 8u);
  m.vertices.assign(3 * 4, 0.0f);  // 4 vertices
  m.triangles.assign(3 * 2, 0u);   // 2 triangles
  EXPECT_EQ(m.vertex_count(), 4u);
  EXPECT_EQ(m.triangle_count(), 2u);
  EXPECT_EQ(m.RawGeometryBytes(), 8u + 4 * 12 + 4 * 6);
}

}  // namespace
}  // namespace mktree
