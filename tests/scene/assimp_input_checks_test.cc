// Malformed files in the formats read through assimp (assimp_input_checks.h, assimp_reader.cc): each is
// an error naming the file (and the line, for the text formats checked before assimp), never a crash
// or a scene other than the file's. Files are generated here, small; well-formed variants still read.
#include "engine/scene/assimp_input_checks.h"

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "engine/scene/assimp_reader.h"
#include "scene/scene_test_util.h"

namespace mktree {
namespace {

// Reading `content` as `name` fails with a message that starts with the file's path and holds `needle`
// (in which "@" stands for the path).
void ExpectRefused(const std::string& content, const std::string& name, std::string needle) {
  const std::string path = WriteTemp(content, name);
  SCOPED_TRACE(name + ": " + content.substr(0, 200));
  if (const size_t at = needle.find('@'); at != std::string::npos) needle.replace(at, 1, path);
  auto r = ReadAssimp(path);
  ASSERT_FALSE(r.ok()) << "read " << r->size() << " objects";
  EXPECT_EQ(r.status().message().rfind(path + ":", 0), 0u) << r.status().message();
  EXPECT_NE(r.status().message().find(needle), std::string::npos) << r.status().message();
}

size_t Triangles(const std::vector<SceneObject>& objects) {
  size_t n = 0;
  for (const SceneObject& o : objects) n += o.mesh.triangle_count();
  return n;
}

// ---- AC3D ----

const char kAcHeader[] =
    "AC3Db\nMATERIAL \"m\" rgb 1 1 1  amb 1 1 1  emis 0 0 0  spec 0 0 0  shi 1  trans 0\n";

// An AC3D poly object with a triangle (lines 1-12 of the object).
std::string AcTriangle(const std::string& name, const std::string& refs = "0 0 0\n1 0 0\n2 0 0\n") {
  return "OBJECT poly\nname \"" + name +
         "\"\nnumvert 3\n0 0 0\n1 0 0\n0 1 0\nnumsurf 1\nSURF 0x10\nmat 0\nrefs 3\n" + refs + "kids 0\n";
}

// world > (levels - 1) groups > a triangle: `levels` + 1 nested objects.
std::string DeepAc(int levels) {
  std::string s = std::string(kAcHeader) + "OBJECT world\nkids 1\n";
  for (int i = 0; i < levels - 1; ++i) s += "OBJECT group\nkids 1\n";
  return s + AcTriangle("t");
}

TEST(Ac3dCheckTest, AWellFormedFileStillReads) {
  auto r = ReadAssimp(WriteTemp(std::string(kAcHeader) + "OBJECT world\nkids 2\n" + AcTriangle("a") +
                                    "OBJECT group\nname \"g\"\nloc 1 2 3\nkids 1\n" + AcTriangle("b"),
                                "ok.ac"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->size(), 2u);
  EXPECT_EQ((*r)[1].name, "b");
}

TEST(Ac3dCheckTest, DeepNestingIsRefusedNotACrash) {
  // About 10,000 levels in 200 KB overflowed the stack inside assimp (rc 139).
  ExpectRefused(DeepAc(10000), "deep.ac", "@:2003: objects nested deeper than 1000 levels");
  // The bound itself: kMaxNodeDepth objects nested read; one more is refused.
  auto r = ReadAssimp(WriteTemp(DeepAc(kMaxNodeDepth - 1), "deepest.ac"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->size(), 1u);
  ExpectRefused(DeepAc(kMaxNodeDepth), "too_deep.ac", "nested deeper than 1000 levels");
}

TEST(Ac3dCheckTest, CountsAndReferencesThatAssimpWouldBendAreRefused) {
  const std::string world1 = std::string(kAcHeader) + "OBJECT world\nkids 1\n";
  const std::string world2 = std::string(kAcHeader) + "OBJECT world\nkids 2\n";
  std::string tri = AcTriangle("a");
  auto replace = [](std::string s, const std::string& from, const std::string& to) {
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  // assimp replaced an out-of-range reference by vertex 0.
  ExpectRefused(world1 + AcTriangle("a", "0 0 0\n1 0 0\n7 0 0\n"), "oor.ac",
                "@:17: vertex reference 7 out of range");
  // assimp read "numvert -3" as 0 and dropped the object; "-1" references as vertex 0.
  ExpectRefused(world2 + tri + replace(tri, "numvert 3", "numvert -3"), "neg_numvert.ac",
                "numvert: expected one count");
  ExpectRefused(world1 + AcTriangle("a", "0 0 0\n1 0 0\n-1 0 0\n"), "neg_ref.ac",
                "@:17: expected a reference");
  ExpectRefused(world1 + replace(tri, "kids 0", "kids -1"), "neg_kids.ac", "kids: expected one count");
  ExpectRefused(world1 + replace(tri, "numvert 3", "numvert 3x"), "junk_count.ac", "'3x'");
  ExpectRefused(world1 + replace(tri, "numvert 3", "numvert"), "no_count.ac", "numvert: expected one count");
  // More vertex lines than numvert: assimp ignored the rest.
  ExpectRefused(world1 + replace(tri, "numvert 3", "numvert 2"), "extra_vertex.ac",
                "numbers outside a vertex");
  // Fewer: the list ran into the next keyword.
  ExpectRefused(world1 + replace(tri, "numvert 3", "numvert 4"), "short_vertices.ac", "expected a vertex");
  ExpectRefused(world1 + replace(tri, "0 1 0\n", ".5 1 0\n"), "dot_vertex.ac", "expected a vertex");
  ExpectRefused(world1 + replace(tri, "0 1 0\n", "0 nan 0\n"), "nan_vertex.ac", "'nan' is not a number");
  ExpectRefused(world1 + replace(tri, "0 1 0\n", "0 1e999 0\n"), "inf_vertex.ac",
                "non-finite coordinate '1e999'");
  ExpectRefused(world1 + replace(tri, "numsurf 1", "numsurf 2"), "short_surfaces.ac",
                "expected 'SURF FLAGS'");
  ExpectRefused(world1 + replace(tri, "numsurf 1", "numsurf 0"), "surf_outside.ac",
                "'SURF' outside a surface");
  ExpectRefused(world1 + replace(tri, "refs 3", "refs 4"), "short_refs.ac", "expected a reference");
  ExpectRefused(world1 + replace(tri, "SURF 0x10", "SURF 0x13"), "surf_type.ac", "unknown surface type 3");
  // A strip of 2 references: an unsigned underflow in assimp.
  ExpectRefused(world1 + replace(replace(tri, "SURF 0x10", "SURF 0x14"), "refs 3\n0 0 0\n", "refs 2\n"),
                "strip.ac", "a triangle strip surface with 2 vertex references");
  ExpectRefused(world1 + replace(tri, "mat 0\nrefs 3\n0 0 0\n1 0 0\n2 0 0\n", "mat 0\n"), "no_refs.ac",
                "a polygon surface with 0 vertex references");
  // Structure: kids announced but missing, a second top-level object, nesting before kids.
  ExpectRefused(world2 + tri, "missing_kid.ac", "unexpected end of file");
  ExpectRefused(world1 + tri + tri, "second_root.ac", "a second top-level object");
  ExpectRefused(world1 + replace(tri, "kids 0\n", "") + tri, "object_in_object.ac",
                "OBJECT before the enclosing");
  ExpectRefused(world2 + tri + "numvert 1\n0 0 0\n" + tri, "stray_lines.ac", "expected OBJECT");
  ExpectRefused(world1 + replace(tri, "numsurf", "   \nnumsurf"), "spaces_line.ac", "a line of only spaces");
  ExpectRefused(world1 + replace(tri, "name \"a\"", "name a"), "unquoted.ac", "double quotes");
  ExpectRefused(world1 + replace(tri, "numsurf", "subdiv 9\nnumsurf"), "subdiv.ac", "subdiv 9");
  ExpectRefused(world1 + replace(tri, "numsurf", "data 7\nkids 5\nnumsurf"), "data.ac", "data block");
  ExpectRefused(world1 + replace(tri, "numsurf", "loc 1 2\nnumsurf"), "loc.ac", "loc X Y Z");
  ExpectRefused(world1 + replace(tri, "OBJECT poly", "OBJECT box"), "type.ac", "unknown object type");
  ExpectRefused(world1 + std::string("0 0 0\n", 2) + std::string(1, '\0') + tri, "nul.ac", "NUL byte");
  ExpectRefused("AC3Db\nkids 1\n", "nothing.ac", "expected MATERIAL or OBJECT");
}

// ---- OFF ----

TEST(OffCheckTest, WellFormedVariantsStillRead) {
  // Comments and blank lines in the header, CRLF, colours after a face, a quad, the counts after OFF.
  auto r = ReadAssimp(
      WriteTemp("# made by hand\r\nOFF\r\n\r\n# counts\r\n4 2 0\r\n0 0 0\r\n1 0 0\r\n\r\n1 1 0\r\n0 1 0\r\n"
                "3 0 1 2 255 0 0\r\n4 0 1 2 3\r\n# end\r\n",
                "ok.off"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(Triangles(*r), 3u);
  r = ReadAssimp(WriteTemp("COFF 3 1 0\n0 0 0 1 0 0 1\n1 0 0 1 0 0 1\n0 1 0 1 0 0 1\n3 0 1 2\n", "coff.off"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(Triangles(*r), 1u);
}

TEST(OffCheckTest, WhatAssimpReadsWrongIsRefused) {
  const std::string v3 = "0 0 0\n1 0 0\n0 1 0\n";
  // assimp replaced an out-of-range index by the last vertex.
  ExpectRefused("OFF\n3 1 0\n" + v3 + "3 0 1 9\n", "oor.off",
                "@:6: vertex index 9 out of range (3 vertices)");
  ExpectRefused("OFF\n3 1 0\n" + v3 + "3 0 1 -2\n", "neg_index.off", "@:6: vertex index '-2'");
  ExpectRefused("OFF\n3 -1 0\n" + v3 + "3 0 1 2\n", "neg_count.off", "@:2: expected the counts");
  ExpectRefused("OFF\n3 1\n" + v3 + "3 0 1 2\n", "no_edges.off", "@:2: expected the counts");
  ExpectRefused("OFF\n3 1 0\n0 0 0\n1 0 0\n", "short_vertices.off", "1 of 3 vertices missing");
  ExpectRefused("OFF\n3 2 0\n" + v3 + "3 0 1 2\n", "short_faces.off", "1 of 2 faces missing");
  ExpectRefused("OFF\n3 1 0\n" + v3 + "3 0 1 2\n3 0 1 2\n", "extra_face.off",
                "@:7: text after the last face");
  ExpectRefused("OFF\n3 1 0\n" + v3 + "10 0 1 2 0 1 2 0 1 2 0\n", "big_face.off",
                "@:6: a face of 10 vertices");
  ExpectRefused("OFF\n3 1 0\n" + v3 + "0\n", "empty_face.off", "@:6: a face of 0 vertices");
  ExpectRefused("OFF\n3 1 0\n" + v3 + "3 0 1\n", "short_face.off",
                "@:6: a face of 3 vertices lists 2 indices");
  ExpectRefused("OFF\n3 2 0\n" + v3 + "# a comment\n3 0 1 2\n", "comment_face.off", "@:6: a comment");
  ExpectRefused("OFF\n3 1 0\n" + v3 + "3 0 1 2 " + std::string(5000, '0') + "\n", "long.off",
                "@:6: line longer");
  ExpectRefused("OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", "nan.off", "@:4: 'nan' is not a number");
  ExpectRefused("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", "short_vertex.off",
                "@:4: a vertex needs 3 numbers");
  ExpectRefused("3 1 0\n" + v3 + "3 0 1 2\n", "no_header.off", "@:1: expected the OFF keyword");
  ExpectRefused("nOFF\n3\n3 1 0\n" + v3 + "3 0 1 2\n", "noff.off", "nOFF");
}

// ---- PLY, STL ----

const char kPlyHeader[] =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face FACES\nproperty list uchar int vertex_indices\nend_header\n";

std::string Ply(const std::string& faces, const std::string& body) {
  std::string h = kPlyHeader;
  h.replace(h.find("FACES"), 5, faces);
  return h + body;
}

std::string BinaryPly(uint32_t faces, const std::vector<float>& xyz, const std::vector<int32_t>& indices) {
  std::string h = Ply(std::to_string(faces), "");
  h.replace(h.find("ascii"), 5, "binary_little_endian");
  std::string body(reinterpret_cast<const char*>(xyz.data()), xyz.size() * 4);
  for (size_t i = 0; i < indices.size(); i += 3) {
    body.push_back(3);
    body.append(reinterpret_cast<const char*>(&indices[i]), 12);
  }
  return h + body;
}

TEST(PlyCheckTest, DataThatDisagreesWithTheHeaderIsRefused) {
  const std::string v3 = "0 0 0\n1 0 0\n0 1 0\n";
  ASSERT_TRUE(ReadAssimp(WriteTemp(Ply("1", v3 + "3 0 1 2\n"), "ok.ply")).ok());
  // assimp read a file cut short as a smaller scene, and a list longer than its line as zero indices.
  ExpectRefused(Ply("2", v3 + "3 0 1 2\n"), "short.ply", "element 'face' has 1 of its 2 instances");
  ExpectRefused(Ply("1", v3 + "255 0 1 2\n"), "long_list.ply", "@:13: element 'face' has fewer values");
  ExpectRefused(Ply("1", v3 + "3 0 1 2\n3 0 1 2\n"), "extra.ply", "@:14: data after the last element");
  ExpectRefused(Ply("1", "0 0 0\n1 0 0\n0 nan 0\n3 0 1 2\n"), "nan.ply", "@:12: 'nan' is not a float");
  ExpectRefused(Ply("1", v3 + "3 0 1 7\n"), "oor.ply", "out of range");
  const std::vector<float> xyz = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  ASSERT_TRUE(ReadAssimp(WriteTemp(BinaryPly(1, xyz, {0, 1, 2}), "ok_binary.ply")).ok());
  ExpectRefused(BinaryPly(2, xyz, {0, 1, 2}), "short_binary.ply", "element 'face' has 1 of its 2 instances");
  ExpectRefused(BinaryPly(1, xyz, {0, 1, 2, 0, 1, 2}), "extra_binary.ply", "data after the last element");
  // assimp's JoinIdenticalVertices merged a NaN vertex into another one: the validation runs before it.
  ExpectRefused(BinaryPly(1, {0, 0, 0, 1, 0, 0, std::nanf(""), 1, 0}, {0, 1, 2}), "nan_binary.ply",
                "non-finite vertex coordinate (vertex 2)");
}

TEST(StlCheckTest, NonFiniteCoordinatesAreRefused) {
  ExpectRefused(
      "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex nan 1 0\nendloop\n"
      "endfacet\nendsolid t\n",
      "nan.stl", "non-finite vertex coordinate");
  std::string binary(80, '\0');
  const uint32_t one = 1;
  binary.append(reinterpret_cast<const char*>(&one), 4);
  const float tri[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, std::nanf(""), 1, 0};
  binary.append(reinterpret_cast<const char*>(tri), sizeof tri);
  binary.append(2, '\0');
  ExpectRefused(binary, "nan_binary.stl", "non-finite vertex coordinate");
}

// ---- glTF ----

// One triangle in a buffer; `nodes` and the scene's root nodes given as JSON.
std::string Gltf(const std::string& nodes, const std::string& roots, const char* buffer_base64) {
  return std::string(R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": )") + roots +
         R"(}], "nodes": )" + nodes +
         R"(, "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "buffers": [{"byteLength": 44, "uri": "data:application/octet-stream;base64,)" +
         buffer_base64 + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]})";
}
const char kTriangle[] = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA=";
// x of vertex 2 is NaN: assimp's JoinIdenticalVertices merged that vertex into another one, so that the
// check of the vertices used (after post-processing) saw only finite ones.
const char kNanTriangle[] = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAADAfwAAgD8AAAAAAAABAAIAAAA=";

// A chain of `n` nodes, each the child of the one before, the last holding the mesh.
std::string Chain(int n) {
  std::string nodes = "[";
  for (int i = 0; i + 1 < n; ++i) nodes += "{\"children\": [" + std::to_string(i + 1) + "]}, ";
  return nodes + "{\"mesh\": 0}]";
}

TEST(GltfCheckTest, DeepOrCyclicNodesAndDeepJsonAreRefused) {
  auto r = ReadAssimp(WriteTemp(Gltf(Chain(kMaxNodeDepth), "[0]", kTriangle), "deepest.gltf"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->size(), 1u);
  // 200,000 levels crashed assimp's recursive importer.
  ExpectRefused(Gltf(Chain(200000), "[0]", kTriangle), "deep.gltf",
                "@: nodes nested deeper than 1000 levels");
  ExpectRefused(Gltf(Chain(kMaxNodeDepth + 1), "[0]", kTriangle), "too_deep.gltf", "nested deeper than 1000");
  ExpectRefused(Gltf(R"([{"children": [1]}, {"children": [0], "mesh": 0}])", "[0]", kTriangle), "cycle.gltf",
                "cycle");
  ExpectRefused(Gltf(R"([{"children": [2]}, {"children": [2]}, {"mesh": 0}])", "[0, 1]", kTriangle),
                "dag.gltf", "node 2 is a child of nodes 0 and 1");
  // JSON nested 200,000 deep overflowed the stack of assimp's JSON parser.
  ExpectRefused(R"({"asset": {"version": "2.0"}, "extras": )" + std::string(200000, '[') +
                    std::string(200000, ']') + "}",
                "deep_json.gltf", "@: JSON nested deeper than 256 levels");
  // Strings and escapes do not count as nesting.
  r = ReadAssimp(WriteTemp(Gltf(R"([{"name": "a[{\"]", "mesh": 0}])", "[0]", kTriangle), "names.gltf"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ((*r)[0].name, "a[{\"]");
}

TEST(GltfCheckTest, NonFiniteCoordinatesAreRefusedBeforeVerticesAreJoined) {
  ExpectRefused(Gltf(R"([{"mesh": 0}])", "[0]", kNanTriangle), "nan.gltf", "non-finite vertex coordinate");
}

}  // namespace
}  // namespace mktree
