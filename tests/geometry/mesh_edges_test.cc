#include "engine/geometry/mesh_edges.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace mktree
