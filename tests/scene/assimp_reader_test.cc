// Assimp reader: one object per node with triangles, world transforms, lines skipped, errors; the real
// AC3D, OFF and STL scenes against /work/shared/data/README.md.
#include "engine/scene/assimp_reader.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "scene/scene_test_util.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

// world > "parent" (loc 10 0 0) > "child" (loc 0 5 0) with one triangle; "wire" holds only a line
// surface; "two_materials" holds a quad and a triangle in two materials (assimp: two meshes, one node).
// No `rot`: assimp's AC3D importer applies a poly object's rotation after its translation, which the
// world-transform test below checks with glTF instead, where the semantics are unambiguous.
const char kNestedAc[] = R"(AC3Db
MATERIAL "red" rgb 1 0 0  amb 0.2 0.2 0.2  emis 0 0 0  spec 0.5 0.5 0.5  shi 10  trans 0
MATERIAL "blue" rgb 0 0 1  amb 0.2 0.2 0.2  emis 0 0 0  spec 0.5 0.5 0.5  shi 10  trans 0
OBJECT world
kids 3
OBJECT group
name "parent"
loc 10 0 0
kids 1
OBJECT poly
name "child"
loc 0 5 0
numvert 3
0 0 0
1 0 0
0 1 0
numsurf 1
SURF 0x10
mat 0
refs 3
0 0 0
1 0 0
2 0 0
kids 0
OBJECT poly
name "wire"
numvert 2
0 0 0
1 1 1
numsurf 1
SURF 0x2
mat 0
refs 2
0 0 0
1 0 0
kids 0
OBJECT poly
name "two_materials"
numvert 5
0 0 0
1 0 0
1 1 0
0 1 0
0 0 1
numsurf 2
SURF 0x10
mat 0
refs 4
0 0 0
1 0 0
2 0 0
3 0 0
SURF 0x10
mat 1
refs 3
0 0 0
1 0 0
4 0 0
kids 0
)";

std::vector<std::array<double, 3>> SortedPoints(const Mesh& m) {
  std::vector<std::array<double, 3>> pts;
  for (size_t i = 0; i < m.vertex_count(); ++i) {
    pts.push_back({m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]});
  }
  std::sort(pts.begin(), pts.end());
  return pts;
}

using Points = std::vector<std::array<double, 3>>;

TEST(AssimpReaderTest, AcObjectsWithTrianglesBecomeObjectsInNodeOrder) {
  auto r = ReadAssimp(WriteTemp(kNestedAc, "nested.ac"), 40);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const auto& objs = *r;
  ASSERT_EQ(objs.size(), 2u);  // "wire" has only a line surface: no object, no id
  EXPECT_EQ(objs[0].name, "child");
  EXPECT_EQ(objs[0].id, 40u);
  // Group and object translations both apply.
  EXPECT_EQ(SortedPoints(objs[0].mesh), (Points{{10, 5, 0}, {10, 6, 0}, {11, 5, 0}}));
  EXPECT_EQ(objs[0].mesh.triangle_count(), 1u);
  // Two materials: two assimp meshes in one node, merged into one object; the quad is triangulated.
  EXPECT_EQ(objs[1].name, "two_materials");
  EXPECT_EQ(objs[1].id, 41u);
  EXPECT_EQ(objs[1].mesh.triangle_count(), 3u);
  for (uint32_t i : objs[1].mesh.triangles) EXPECT_LT(i, objs[1].mesh.vertex_count());
  Box3d b = objs[1].mesh.Bounds();
  EXPECT_EQ(b.min, (std::array<double, 3>{0, 0, 0}));
  EXPECT_EQ(b.max, (std::array<double, 3>{1, 1, 1}));
}

TEST(AssimpReaderTest, AFileOfLinesOnlyGivesNoObjects) {
  std::string ac = kNestedAc;
  // Keep only the world and the "wire" object.
  std::string lines_only =
      ac.substr(0, ac.find("OBJECT world")) + "OBJECT world\nkids 1\n" +
      ac.substr(ac.find("OBJECT poly\nname \"wire\""),
                ac.find("OBJECT poly\nname \"two_materials\"") - ac.find("OBJECT poly\nname \"wire\""));
  auto r = ReadAssimp(WriteTemp(lines_only, "wire.ac"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->empty());
}

// One triangle (0,0,0) (1,0,0) (0,1,0) in a buffer, used by three nodes:
//   "parent" (translate 10,0,0; quarter turn about z) > "child" (translate 0,5,0) -> mesh 0
//   "scaled" (scale 2) -> mesh 0 again (an instance: a second object)
//   "two_prims" -> mesh 1: the triangle plus a point primitive (dropped)
//   "points" -> mesh 2: points only (no object)
const char kGltf[] = R"({
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0, 2, 3, 4]}],
  "nodes": [
    {"name": "parent", "translation": [10, 0, 0], "rotation": [0, 0, 0.70710678118654752, 0.70710678118654752],
     "children": [1]},
    {"name": "child", "translation": [0, 5, 0], "mesh": 0},
    {"name": "scaled", "scale": [2, 2, 2], "mesh": 0},
    {"name": "two_prims", "mesh": 1},
    {"name": "points", "mesh": 2}
  ],
  "meshes": [
    {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
    {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}, {"attributes": {"POSITION": 0}, "mode": 0}]},
    {"primitives": [{"attributes": {"POSITION": 0}, "mode": 0}]}
  ],
  "buffers": [{"byteLength": 44, "uri": "data:application/octet-stream;base64,BUFFER"}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
  ]
})";

std::string GltfWith(const std::string& buffer_base64) {
  std::string s = kGltf;
  s.replace(s.find("BUFFER"), 6, buffer_base64);
  return s;
}
const char kTriangleBuffer[] = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA=";
const char kNanBuffer[] =
    "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAwH8AAAAAAAABAAIAAAA=";  // y of vertex 2 = NaN

TEST(AssimpReaderTest, WorldTransformIsAccumulatedAlongTheNodePath) {
  auto r = ReadAssimp(WriteTemp(GltfWith(kTriangleBuffer), "scene.gltf"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const auto& objs = *r;
  ASSERT_EQ(objs.size(), 3u);
  EXPECT_EQ(objs[0].name, "child");
  EXPECT_EQ(objs[1].name, "scaled");
  EXPECT_EQ(objs[2].name, "two_prims");
  // child: p -> Rz(p + (0,5,0)) + (10,0,0), Rz(x, y) = (-y, x).
  Points child = SortedPoints(objs[0].mesh);
  Points expected = {{4, 0, 0}, {5, 0, 0}, {5, 1, 0}};
  ASSERT_EQ(child.size(), 3u);
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(child[i][k], expected[i][k], 1e-6) << i << "," << k;
  EXPECT_EQ(SortedPoints(objs[1].mesh), (Points{{0, 0, 0}, {0, 2, 0}, {2, 0, 0}}));
  EXPECT_EQ(objs[2].mesh.triangle_count(), 1u);  // the point primitive is gone
  EXPECT_EQ(objs[2].mesh.vertex_count(), 3u);
}

TEST(AssimpReaderTest, NonFiniteCoordinatesAreErrorsNamingTheFile) {
  std::string path = WriteTemp(GltfWith(kNanBuffer), "nan.gltf");
  auto r = ReadAssimp(path);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("non-finite"), std::string::npos) << r.status().message();
}

TEST(AssimpReaderTest, AsciiStlAndPly) {
  auto stl = ReadAssimp(WriteTemp(
      "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
      "facet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid "
      "t\n",
      "quad.stl"));
  ASSERT_TRUE(stl.ok()) << stl.status().ToString();
  ASSERT_EQ(stl->size(), 1u);
  EXPECT_EQ((*stl)[0].mesh.triangle_count(), 2u);
  EXPECT_EQ((*stl)[0].mesh.vertex_count(), 4u);  // STL repeats corners; joined by position

  auto ply = ReadAssimp(WriteTemp(
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 "
      "2 3\n",
      "quad.ply"));
  ASSERT_TRUE(ply.ok()) << ply.status().ToString();
  ASSERT_EQ(ply->size(), 1u);
  EXPECT_EQ((*ply)[0].mesh.triangle_count(), 2u);
  EXPECT_FALSE((*ply)[0].name.empty());
}

TEST(AssimpReaderTest, UnreadableFilesAreErrorsNamingTheFile) {
  auto missing = OpenAssimpFile("/nonexistent/scene.glb");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), Status::Code::kNotFound);
  EXPECT_NE(missing.status().message().find("/nonexistent/scene.glb"), std::string::npos);

  for (const char* name : {"garbage.ply", "garbage.glb", "garbage.unknownext", "empty.stl"}) {
    std::string path =
        WriteTemp(std::string(name) == "empty.stl" ? "" : "this is not a scene\n\x01\x02", name);
    auto r = OpenAssimpFile(path);
    ASSERT_FALSE(r.ok()) << name;
    // assimp's message, or that of our check of the format (assimp_input_checks.h).
    EXPECT_EQ(r.status().message().rfind(path + ":", 0), 0u) << r.status().message();
    EXPECT_GT(r.status().message().size(), path.size() + 10) << "the reason is missing";
  }
}

// The real scenes, against /work/shared/data/README.md.

class AssimpRealFileTest : public ::testing::TestWithParam<RealFile> {};

TEST_P(AssimpRealFileTest, MatchesTheDataReadme) {
  const RealFile& f = GetParam();
  CheckRealFile(OpenAssimpFile(std::string(MKTREE_SHARED_DATA) + "/" + f.path, 3), 3, f);
}

// truman.ac: the README says 280 objects and 99,160 triangles. 280 counts every AC3D object with
// surfaces, but 51 of them (the "wire-*" arresting wires) hold only SURF type 2 line surfaces (all 115
// of the file's lines), so 229 objects have triangles. 99,160 is the polygons' fan count; assimp's ear
// clipping omits 16 zero-area ears (collinear vertices in the "elev-rail-wire*" rails), giving 99,144.
// The other AC3D files have no degenerate polygons and match the README exactly.
INSTANTIATE_TEST_SUITE_P(
    SharedData, AssimpRealFileTest,
    ::testing::Values(RealFile{"ships/truman.ac", 229, 99144}, RealFile{"ships/ContainerShip.ac", 29, 2054},
                      RealFile{"ships/Freighter.ac", 26, 1573}, RealFile{"meshes/fandisk.off", 1, 12946},
                      RealFile{"meshes/armadillo.off", 1, 52000}, RealFile{"meshes/3torus.off", 1, 46},
                      RealFile{"meshes/gearwheel.bin.stl", 1, 2444},
                      RealFile{"meshes/bunny.bin.stl", 1, 69451}));

}  // namespace
}  // namespace mktree
