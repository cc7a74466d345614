#include "engine/geometry/triangle_hierarchy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "engine/geometry/triangle_pair.h"
#include "geometry/test_meshes.h"

namespace mktree {
namespace {

// n random small triangles in the cube [0, size]^3 (a soup: every triangle its own three vertices).
Mesh Soup(size_t n, double size, double edge, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  Mesh m;
  for (size_t t = 0; t < n; ++t) {
    const Vec3d c{u(rng) * size, u(rng) * size, u(rng) * size};
    for (int k = 0; k < 3; ++k)
      testing::AddVertex(&m, c.x + (u(rng) - 0.5) * edge, c.y + (u(rng) - 0.5) * edge,
                         c.z + (u(rng) - 0.5) * edge);
    const uint32_t v = static_cast<uint32_t>(3 * t);
    m.triangles.insert(m.triangles.end(), {v, v + 1, v + 2});
  }
  return m;
}

TEST(TriangleHierarchy, StructureCoversEveryTriangleOnce) {
  std::mt19937_64 rng(1);
  for (size_t n : {size_t{1}, size_t{4}, size_t{5}, size_t{37}, size_t{1000}}) {
    const Mesh m = Soup(n, 10, 1, rng);
    const TriangleHierarchy h(m);
    ASSERT_EQ(h.triangle_count(), n);
    std::vector<int> seen(n, 0);
    for (size_t i = 0; i < n; ++i) ++seen[h.mesh_triangle(static_cast<uint32_t>(i))];
    for (int s : seen) EXPECT_EQ(s, 1);
    // Each leaf's box holds its triangles; each inner box holds its children's.
    for (const auto& node : h.nodes()) {
      if (node.leaf()) {
        EXPECT_LE(node.count, TriangleHierarchy::kLeafTriangles);
        for (uint32_t t = node.first; t < node.first + node.count; ++t)
          for (const Vec3d& v : h.triangle(t)) EXPECT_TRUE(node.box.Contains(v));
      } else {
        for (uint32_t c = node.first; c < node.first + 2; ++c)
          for (int k = 0; k < 3; ++k) {
            EXPECT_LE(node.box.min[k], h.nodes()[c].box.min[k]);
            EXPECT_GE(node.box.max[k], h.nodes()[c].box.max[k]);
          }
      }
    }
  }
  EXPECT_TRUE(TriangleHierarchy(Mesh{}).nodes().empty());
}

TEST(TriangleHierarchy, QueriesAgreeWithAllPairs) {
  std::mt19937_64 rng(2);
  int met = 0, near = 0;
  for (int round = 0; round < 40; ++round) {
    const double edge = round % 2 ? 0.3 : 1.0;
    const Mesh a = Soup(150 + 10 * round, 10, edge, rng), b = Soup(120, 10, edge, rng);
    const TriangleHierarchy ha(a), hb(b);
    bool want_meet = false;
    double want_gap2 = INFINITY;
    for (size_t i = 0; i < a.triangle_count(); ++i)
      for (size_t j = 0; j < b.triangle_count(); ++j) {
        const Vec3d ta[3] = {testing::VertexOf(a, 3 * i), testing::VertexOf(a, 3 * i + 1),
                             testing::VertexOf(a, 3 * i + 2)};
        const Vec3d tb[3] = {testing::VertexOf(b, 3 * j), testing::VertexOf(b, 3 * j + 1),
                             testing::VertexOf(b, 3 * j + 2)};
        want_meet |= TrianglesMeet(ta, tb);
        want_gap2 = std::min(want_gap2, TriangleFeatureClosest(ta, tb).distance_squared);
      }
    TriangleHierarchy::Pair pair;
    uint64_t tests = 0;
    ASSERT_EQ(TriangleHierarchy::FindMeeting(ha, hb, &pair, &tests), want_meet) << round;
    if (want_meet) {
      EXPECT_TRUE(TrianglesMeet(ha.triangle(pair.a).data(), hb.triangle(pair.b).data()));
      ++met;
      continue;
    }
    EXPECT_LT(tests, a.triangle_count() * b.triangle_count() / 10);  // the hierarchy prunes
    for (double bound : {0.5 * std::sqrt(want_gap2), 2 * std::sqrt(want_gap2), 100.0}) {
      ClosestPoints c;
      const bool found = TriangleHierarchy::ClosestBelow(ha, hb, bound, &c, nullptr);
      ASSERT_EQ(found, want_gap2 < bound * bound) << round;
      if (found) {
        EXPECT_NEAR(c.distance_squared, want_gap2, 1e-12);
      }
    }
    ++near;
    // Point queries against a scan.
    std::uniform_real_distribution<double> u(-2, 12);
    for (int q = 0; q < 20; ++q) {
      const Vec3d p{u(rng), u(rng), u(rng)};
      double want = INFINITY;
      for (size_t i = 0; i < a.triangle_count(); ++i)
        want = std::min(want,
                        PointTriangleClosest(p, testing::VertexOf(a, 3 * i), testing::VertexOf(a, 3 * i + 1),
                                             testing::VertexOf(a, 3 * i + 2))
                            .distance_squared);
      EXPECT_EQ(ha.PointDistanceSquared(p), want);
    }
  }
  EXPECT_GT(met, 5);
  EXPECT_GT(near, 5);
}

}  // namespace
}  // namespace mktree
