#include "engine/geometry/mesh_edges.h"

#include <gtest/gtest.h>

#include <map>
#include <random>

#include "geometry/mesh_files.h"
#include "geometry/test_meshes.h"

namespace mktree {
namespace {

using testing::BoxMesh;
using testing::ReadSharedMesh;

TEST(MeshEdgesTest, SyntheticClosedAndOpenMeshes) {
  EXPECT_TRUE(IsClosedMesh(BoxMesh({0, 0, 0}, {1, 1, 1})));
  EXPECT_TRUE(IsClosedMesh(testing::TetrahedronMesh()));
  EXPECT_TRUE(IsClosedMesh(testing::UvSphereMesh(11, 10, 1.0)));

  Mesh open = BoxMesh({0, 0, 0}, {1, 1, 1});
  open.triangles.resize(open.triangles.size() - 6);  // drop one face (two triangles)
  const EdgeCheck e = CheckEdges(open);
  EXPECT_FALSE(e.closed);
  EXPECT_FALSE(e.even);
  EXPECT_EQ(e.border_edges, 4u);

  // One flipped triangle: every edge still used twice, but not with opposite orientations.
  Mesh flipped = BoxMesh({0, 0, 0}, {1, 1, 1});
  std::swap(flipped.triangles[0], flipped.triangles[1]);
  EXPECT_FALSE(CheckEdges(flipped).closed);
  EXPECT_TRUE(CheckEdges(flipped).even);

  // Two cubes sharing an edge: closed as a mod-2 surface, not a manifold.
  Mesh two = BoxMesh({0, 0, 0}, {1, 1, 1});
  const Mesh other = BoxMesh({1, 1, 0}, {2, 2, 1});
  const uint32_t base = static_cast<uint32_t>(two.vertex_count());
  two.vertices.insert(two.vertices.end(), other.vertices.begin(), other.vertices.end());
  for (uint32_t i : other.triangles) two.triangles.push_back(base + i);
  EXPECT_FALSE(CheckEdges(two).closed);
  EXPECT_TRUE(CheckEdges(two).even);

  // Degenerate triangles (a repeated corner) are ignored; an empty mesh is trivially closed.
  Mesh with_degenerate = BoxMesh({0, 0, 0}, {1, 1, 1});
  with_degenerate.triangles.insert(with_degenerate.triangles.end(), {0, 0, 1});
  EXPECT_TRUE(IsClosedMesh(with_degenerate));
  EXPECT_TRUE(IsClosedMesh(Mesh{}));

  // Out-of-range index: not closed.
  Mesh corrupt = BoxMesh({0, 0, 0}, {1, 1, 1});
  corrupt.triangles[5] = 99;
  EXPECT_FALSE(IsClosedMesh(corrupt));
}

TEST(MeshEdgesTest, TriangleSoupIsJudgedByPositions) {
  // Unshare every vertex, as binary STL stores meshes.
  const Mesh cube = BoxMesh({0, 0, 0}, {1, 1, 1});
  Mesh soup;
  for (uint32_t i : cube.triangles) {
    testing::AddVertex(&soup, cube.vertices[3 * i], cube.vertices[3 * i + 1], cube.vertices[3 * i + 2]);
    soup.triangles.push_back(static_cast<uint32_t>(soup.vertex_count() - 1));
  }
  EXPECT_TRUE(IsClosedMesh(soup));
}

TEST(MeshEdgesTest, RealMeshes) {
  for (const char* name : {"fandisk.off", "armadillo.off", "3torus.off", "gearwheel.bin.stl"}) {
    auto mesh = ReadSharedMesh(name);
    ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
    EXPECT_TRUE(IsClosedMesh(*mesh)) << name;
  }
  auto bunny = ReadSharedMesh("bunny.bin.stl");
  ASSERT_TRUE(bunny.ok()) << bunny.status().ToString();
  const EdgeCheck e = CheckEdges(*bunny);
  EXPECT_FALSE(e.closed);
  EXPECT_FALSE(e.even);
  EXPECT_EQ(e.border_edges, 223u);
}

// The definition, counted naively: weld by comparing every pair of positions, then count each undirected
// edge's uses per direction in a map.
EdgeCheck BruteForceEdges(const Mesh& m) {
  const size_t n = m.vertex_count();
  for (uint32_t i : m.triangles)
    if (i >= n) return EdgeCheck{};
  std::vector<uint32_t> canon(n);
  for (size_t i = 0; i < n; ++i) {
    canon[i] = static_cast<uint32_t>(i);
    for (size_t j = 0; j < i; ++j)
      if (m.vertices[3 * i] == m.vertices[3 * j] && m.vertices[3 * i + 1] == m.vertices[3 * j + 1] &&
          m.vertices[3 * i + 2] == m.vertices[3 * j + 2]) {
        canon[i] = canon[j];
        break;
      }
  }
  std::map<std::pair<uint32_t, uint32_t>, std::pair<int, int>> uses;  // (forward, backward)
  for (size_t t = 0; t + 2 < m.triangles.size(); t += 3) {
    const uint32_t c[3] = {canon[m.triangles[t]], canon[m.triangles[t + 1]], canon[m.triangles[t + 2]]};
    if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) continue;
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = c[k], b = c[(k + 1) % 3];
      auto& u = uses[{std::min(a, b), std::max(a, b)}];
      (a < b ? u.first : u.second)++;
    }
  }
  EdgeCheck r;
  r.closed = r.even = true;
  for (const auto& [edge, u] : uses) {
    r.closed = r.closed && u.first == 1 && u.second == 1;
    r.even = r.even && (u.first + u.second) % 2 == 0;
    r.border_edges += u.first + u.second == 1;
  }
  return r;
}

TEST(MeshEdgesTest, MatchesBruteForceOnRandomMeshes) {
  // Small coordinate sets so that positions repeat (welding matters), -0 next to +0, a NaN now and then,
  // repeated and flipped triangles, degenerate ones, and sizes on both sides of the hashed/sorted switch.
  std::mt19937 rng(11);
  const float coords[] = {0.0f, -0.0f, 1.0f, 2.5f, -3.0f};
  int closed = 0, even = 0;
  for (int trial = 0; trial < 400; ++trial) {
    Mesh m;
    const size_t vertices = 1 + rng() % (trial < 390 ? 40 : 3000);
    for (size_t i = 0; i < vertices; ++i)
      for (int k = 0; k < 3; ++k)
        m.vertices.push_back(rng() % 200 == 0 ? std::nanf("") : coords[rng() % std::size(coords)]);
    if (trial % 3 == 0) {
      m = testing::UvSphereMesh(3 + trial % 7, 4 + trial % 5, 1.0);  // closed, then damaged below
      if (trial % 6 == 0) std::swap(m.triangles[0], m.triangles[1]);
    }
    const size_t triangles = trial < 390 ? rng() % 60 : 25000 + rng() % 20000;
    for (size_t t = 0; t < triangles && trial % 3 != 0; ++t)
      for (int k = 0; k < 3; ++k) m.triangles.push_back(static_cast<uint32_t>(rng() % m.vertex_count()));
    if (trial % 5 == 0 && !m.triangles.empty()) {  // every triangle twice: even, and closed if flipped
      const size_t t = m.triangles.size();
      for (size_t i = 0; i < t; i += 3)
        m.triangles.insert(m.triangles.end(), {m.triangles[i], m.triangles[i + 2], m.triangles[i + 1]});
    }
    const EdgeCheck want = BruteForceEdges(m), got = CheckEdges(m);
    ASSERT_EQ(got.closed, want.closed) << "trial " << trial;
    ASSERT_EQ(got.even, want.even) << "trial " << trial;
    ASSERT_EQ(got.border_edges, want.border_edges) << "trial " << trial;
    closed += want.closed;
    even += want.even;
  }
  // The trials cover both answers.
  EXPECT_GT(closed, 20);
  EXPECT_LT(closed, 380);
  EXPECT_GT(even, closed);
}

}  // namespace
}  // namespace mktree
