// Streaming OBJ reader: index forms, triangulation, object rules, every error with its line, real files.
#include "engine/scene/obj_reader.h"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cctype>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "scene/scene_test_util.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

// `content` as scene.obj in the test's folder.
std::string WriteObj(const std::string& content) { return WriteTemp(content, "scene.obj"); }

Result<std::vector<SceneObject>> ReadObj(const std::string& path, ObjectId first_id = 0) {
  return ReadAllFrom(OpenObjFile(path, first_id));
}

std::vector<SceneObject> ReadOk(const std::string& content, ObjectId first_id = 0) {
  auto r = ReadObj(WriteObj(content), first_id);
  EXPECT_TRUE(r.ok()) << r.status().ToString();
  return r.ok() ? std::move(r).value() : std::vector<SceneObject>{};
}

// Expects reading `content` to fail with a message naming "<file>:<line>:" and containing `what`.
void ExpectError(const std::string& content, int line, const std::string& what) {
  std::string path = WriteObj(content);
  auto r = ReadObj(path);
  ASSERT_FALSE(r.ok()) << "expected an error at line " << line << " (" << what << ")";
  const std::string& msg = r.status().message();
  EXPECT_NE(msg.find(path + ":" + std::to_string(line) + ": "), std::string::npos) << msg;
  EXPECT_NE(msg.find(what), std::string::npos) << msg;
}

const char kTriangleVertices[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n";

TEST(ObjReaderTest, EveryIndexFormGivesTheSameTriangle) {
  for (const char* face : {"f 1 2 3\n", "f 1/1 2/2 3/3\n", "f 1//1 2//1 3//1\n", "f 1/1/1 2/2/1 3/3/1\n",
                           "f -3/-3/-1 -2/-2/-1 -1/-1/-1\n", "f 1/1 2//1 3\n"}) {
    auto objs = ReadOk(std::string(kTriangleVertices) + face);
    ASSERT_EQ(objs.size(), 1u) << face;
    EXPECT_EQ(objs[0].mesh.vertices, (std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0})) << face;
    EXPECT_EQ(objs[0].mesh.triangles, (std::vector<uint32_t>{0, 1, 2})) << face;
  }
}

TEST(ObjReaderTest, NegativeIndicesAreRelativeToTheVerticesReadSoFar) {
  auto objs = ReadOk(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
      "o a\nf -1 -2 -3\n"
      "v 5 5 5\n"
      "o b\nf -1 -2 -3\n");  // -1 is now the fourth vertex
  ASSERT_EQ(objs.size(), 2u);
  EXPECT_EQ(objs[0].mesh.vertices, (std::vector<double>{0, 1, 0, 1, 0, 0, 0, 0, 0}));
  EXPECT_EQ(objs[1].mesh.vertices, (std::vector<double>{5, 5, 5, 0, 1, 0, 1, 0, 0}));
  EXPECT_EQ(objs[1].mesh.triangles, (std::vector<uint32_t>{0, 1, 2}));
}

TEST(ObjReaderTest, PolygonsAreTriangulatedAsAFan) {
  auto objs = ReadOk("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\nf 1 2 3 4\nf 1 2 3 4 5\n");
  ASSERT_EQ(objs.size(), 1u);
  EXPECT_EQ(objs[0].mesh.triangles, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 0, 1, 2, 0, 2, 3, 0, 3, 4}));
}

TEST(ObjReaderTest, MeshesKeepOnlyTheirVerticesReindexedInFirstUseOrder) {
  auto objs = ReadOk(
      "o first\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 9 9 9\nf 3 1 2\n"
      "o second\nv 2 0 0\nv 3 0 0\nv 2 1 0\nf 7 5 6 1\n");  // reuses vertex 1 of `first`
  ASSERT_EQ(objs.size(), 2u);
  EXPECT_EQ(objs[0].mesh.vertices, (std::vector<double>{0, 1, 0, 0, 0, 0, 1, 0, 0}));
  EXPECT_EQ(objs[0].mesh.triangles, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_EQ(objs[1].mesh.vertices, (std::vector<double>{2, 1, 0, 2, 0, 0, 3, 0, 0, 0, 0, 0}));
  EXPECT_EQ(objs[1].mesh.triangles, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
}

TEST(ObjReaderTest, ObjectLinesStartObjectsAndGroupsAreIgnoredThen) {
  // The `g` comes before any `o`: the reader must still learn that the file has `o` lines.
  auto objs = ReadOk(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
      "g early\nf 1 2 3\n"
      "o pipe 1\ng part\nf 1 2 3\ng other\nf 3 2 1\n"
      "o  plate  \nf 1 2 3\n");
  ASSERT_EQ(objs.size(), 3u);
  EXPECT_EQ(objs[0].name, "object_0");  // faces before the first `o`
  EXPECT_EQ(objs[1].name, "pipe 1");
  EXPECT_EQ(objs[1].mesh.triangle_count(), 2u);
  EXPECT_EQ(objs[2].name, "plate");
}

TEST(ObjReaderTest, GroupsStartObjectsWhenTheFileHasNoObjectLines) {
  auto objs = ReadOk(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
      "f 1 2 3\n"
      "g wall\nf 1 2 3\ng\nf 1 2 3\ng wall\nf 3 2 1\n"
      "# o commented out\nusemtl o\n");
  ASSERT_EQ(objs.size(), 4u);
  EXPECT_EQ(objs[0].name, "object_0");
  EXPECT_EQ(objs[1].name, "wall");
  EXPECT_EQ(objs[2].name, "object_2");
  EXPECT_EQ(objs[3].name, "wall");  // a repeated group is a new object: a stream cannot merge it back
  for (size_t i = 0; i < objs.size(); ++i) EXPECT_EQ(objs[i].id, i);
}

TEST(ObjReaderTest, IndentedObjectLineCountsForTheGroupRule) {
  auto objs = ReadOk("v 0 0 0\nv 1 0 0\nv 0 1 0\ng g1\nf 1 2 3\ng g2\nf 1 2 3\n\t o only\nf 1 2 3\n");
  ASSERT_EQ(objs.size(), 2u);
  EXPECT_EQ(objs[0].name, "object_0");
  EXPECT_EQ(objs[0].mesh.triangle_count(), 2u);
  EXPECT_EQ(objs[1].name, "only");
}

TEST(ObjReaderTest, ObjectsWithoutFacesAreSkippedAndConsumeNoId) {
  auto objs = ReadOk(
      "o empty1\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
      "o solid\nf 1 2 3\n"
      "o lines_only\nl 1 2\np 3\n"
      "o\nf 1 2 3\n"
      "o empty_at_end\n",
      100);
  ASSERT_EQ(objs.size(), 2u);
  EXPECT_EQ(objs[0].id, 100u);
  EXPECT_EQ(objs[0].name, "solid");
  EXPECT_EQ(objs[1].id, 101u);
  EXPECT_EQ(objs[1].name, "object_101");
}

TEST(ObjReaderTest, EmptyFileAndCommentsOnlyGiveNoObjects) {
  EXPECT_TRUE(ReadOk("").empty());
  EXPECT_TRUE(ReadOk("# nothing\n\n   \n").empty());
}

TEST(ObjReaderTest, AcceptsTheHarmlessDirectivesCrlfAndContinuations) {
  auto objs = ReadOk(
      "mtllib scene.mtl\r\n# comment\r\n\r\nv 0 0 0 1\r\nv 1 0 0 0.5 0.5 0.5\r\nv +0 1e0 -0\r\nv 1 1 0\r\n"
      "vt 0 0\r\nvn 0 0 1\r\nvp 0.5\r\ns off\r\nusemtl steel\r\nlod 1\r\nshadow_obj x.obj\r\n"
      "o  crlf \r\nf 1 2 \\\r\n  3 4\r\n");
  ASSERT_EQ(objs.size(), 1u);
  EXPECT_EQ(objs[0].name, "crlf");
  EXPECT_EQ(objs[0].mesh.triangles, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(objs[0].mesh.vertices[7], 1.0f);
}

TEST(ObjReaderTest, LastLineWithoutNewlineIsReadWhenComplete) {
  auto objs = ReadOk("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3");
  ASSERT_EQ(objs.size(), 1u);
  EXPECT_EQ(objs[0].mesh.triangle_count(), 1u);
}

TEST(ObjReaderTest, CoordinatesAreDoublesWithUnderflowToZero) {
  auto objs = ReadOk("v 0.1 -1e-400 2e37\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  ASSERT_EQ(objs.size(), 1u);
  EXPECT_EQ(objs[0].mesh.vertices[0], 0.1);
  EXPECT_EQ(objs[0].mesh.vertices[1], 0.0);
  EXPECT_EQ(objs[0].mesh.vertices[2], 2e37);
}

// Short decimals take a fast path (one division); every form must give strtod's correctly rounded double.
TEST(ObjReaderTest, DecimalCoordinatesReadAsStrtodReadsThem) {
  std::vector<std::string> numbers;
  std::istringstream forms(
      "0.1 -24.999 +5 5. .5 -.5 007.50 0.0 -0 1e3 -2.5E-3 123456789012345 1234567890123456 0.123456789012345 "
      "9999999.99999999 -0.000000000000001 3.14159265358979323846");
  for (std::string f; forms >> f;) numbers.push_back(f);
  uint64_t x = 88172645463325252ull;  // xorshift: fixed, so a failure repeats
  auto next = [&x] {
    x ^= x << 13, x ^= x >> 7, x ^= x << 17;
    return x;
  };
  for (int i = 0; i < 3000; ++i) {
    const int digits = 1 + static_cast<int>(next() % 17);
    const int point = static_cast<int>(next() % (digits + 2)) - 1;  // -1: no point
    const uint64_t sign = next() % 3;
    std::string d;
    if (sign < 2) d.push_back(sign == 0 ? '-' : '+');
    for (int k = 0; k <= digits; ++k) {
      if (k == point) d.push_back('.');
      if (k < digits) d.push_back(static_cast<char>('0' + next() % 10));
    }
    numbers.push_back(d);
  }
  while (numbers.size() % 3 != 0) numbers.push_back("1");
  std::string obj;
  for (size_t i = 0; i < numbers.size(); i += 3)
    obj += "v " + numbers[i] + " " + numbers[i + 1] + " " + numbers[i + 2] + "\nf -1 -1 -1\n";
  auto objs = ReadOk(obj);
  ASSERT_EQ(objs.size(), 1u);
  ASSERT_EQ(objs[0].mesh.vertices.size(), numbers.size());
  for (size_t i = 0; i < numbers.size(); ++i)
    EXPECT_EQ(objs[0].mesh.vertices[i], std::strtod(numbers[i].c_str(), nullptr)) << numbers[i];
}

// Vertices beyond the RAM budget go to the spill file and are read back when a face uses them: the same
// objects as with every vertex in RAM. 300k vertices (four and a half blocks) under a one-block budget;
// faces use recent vertices (relative), the first ones (absolute, spilled long ago) and some in between.
TEST(ObjReaderTest, VerticesPastTheRamBudgetAreSpilledAndReadBack) {
  std::string obj;
  const int n = 300000;
  for (int i = 0; i < n; ++i) {
    obj +=
        "v " + std::to_string(i) + ".25 " + std::to_string(i % 977) + " -" + std::to_string(i % 13) + ".5\n";
    if (i % 1000 == 999) {
      obj += "o part" + std::to_string(i / 1000) + "\nf -1 -2 -3\n";
      obj += "f 1 2 " + std::to_string(i / 2 + 1) + "\n";
      obj += "f " + std::to_string(i - 70000 > 0 ? i - 70000 : 3) + " -4 " + std::to_string(i + 1) + "\n";
    }
  }
  const std::string path = WriteObj(obj);
  testing::TempDir spill;
  ObjReadOptions small;
  small.vertex_ram_bytes = 1;  // one block
  small.spill_dir = spill.path().string();
  auto want = ReadAllFrom(OpenObjFile(path, 0));
  auto got = ReadAllFrom(OpenObjFile(path, 0, small));
  ASSERT_TRUE(want.ok()) << want.status().ToString();
  ASSERT_TRUE(got.ok()) << got.status().ToString();
  ASSERT_EQ(got->size(), want->size());
  ASSERT_EQ(got->size(), static_cast<size_t>(n / 1000));
  for (size_t i = 0; i < got->size(); ++i) {
    EXPECT_EQ((*got)[i].name, (*want)[i].name);
    EXPECT_EQ((*got)[i].mesh.vertices, (*want)[i].mesh.vertices) << (*got)[i].name;
    EXPECT_EQ((*got)[i].mesh.triangles, (*want)[i].mesh.triangles) << (*got)[i].name;
  }
  EXPECT_TRUE(fs::is_empty(spill.path()));  // the spill file has no name

  // A spill folder that cannot hold the file: an error naming the OBJ file and the line.
  small.spill_dir = (spill.path() / "missing").string();
  auto failed = ReadAllFrom(OpenObjFile(path, 0, small));
  ASSERT_FALSE(failed.ok());
  EXPECT_EQ(failed.status().code(), Status::Code::kIOError) << failed.status().ToString();
  EXPECT_EQ(failed.status().message().rfind(path + ":", 0), 0u) << failed.status().ToString();
  EXPECT_NE(failed.status().message().find("spill file for the vertices"), std::string::npos)
      << failed.status().ToString();

  // A spill that cannot grow (a full disk; here the file size limit, 1 MiB, under a 1.5 MiB block): an I/O
  // error naming the OBJ file and the spill.
  small.spill_dir = spill.path().string();
  struct sigaction ignore {
  }, old{};
  ignore.sa_handler = SIG_IGN;
  ASSERT_EQ(sigaction(SIGXFSZ, &ignore, &old), 0);
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  rlimit limit = saved;
  limit.rlim_cur = 1 << 20;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
  auto full = ReadAllFrom(OpenObjFile(path, 0, small));
  setrlimit(RLIMIT_FSIZE, &saved);
  sigaction(SIGXFSZ, &old, nullptr);
  ASSERT_FALSE(full.ok());
  EXPECT_EQ(full.status().code(), Status::Code::kIOError) << full.status().ToString();
  EXPECT_EQ(full.status().message().rfind(path + ":", 0), 0u) << full.status().ToString();
  EXPECT_NE(full.status().message().find("vertex spill"), std::string::npos) << full.status().ToString();
  EXPECT_TRUE(fs::is_empty(spill.path()));
}

// One mesh whose vertices all come before its faces, past the RAM budget: faces read the spilled vertices
// back in order, backwards and scattered, across read-back pages and blocks.
TEST(ObjReaderTest, OneMeshLargerThanTheRamBudgetReadsItsSpilledVerticesBack) {
  std::string obj = "o big\n";
  const int n = 200000;  // three 65,536-vertex blocks and part of a fourth
  for (int i = 0; i < n; ++i)
    obj += "v " + std::to_string(i % 1013) + ".5 " + std::to_string(i) + " " + std::to_string(i % 7) + "\n";
  for (int i = 1; i + 2 <= n; i += 97)
    obj += "f " + std::to_string(i) + " " + std::to_string(i + 1) + " " + std::to_string(i + 2) + "\n";
  for (int i = n; i > 2; i -= 131)
    obj += "f " + std::to_string(i) + " " + std::to_string(i - 1) + " " + std::to_string(i - 2) + "\n";
  uint64_t x = 12345;
  for (int k = 0; k < 3000; ++k) {
    int v[3];
    for (int& e : v) {
      x = x * 6364136223846793005ULL + 1442695040888963407ULL;
      e = static_cast<int>((x >> 33) % n) + 1;
    }
    obj +=
        "f " + std::to_string(v[0]) + " " + std::to_string(v[1]) + " -" + std::to_string(n - v[2] + 1) + "\n";
  }
  const std::string path = WriteObj(obj);
  testing::TempDir spill;
  ObjReadOptions small;
  small.vertex_ram_bytes = 1;
  small.spill_dir = spill.path().string();
  auto want = ReadAllFrom(OpenObjFile(path, 0));
  auto got = ReadAllFrom(OpenObjFile(path, 0, small));
  ASSERT_TRUE(want.ok()) << want.status().ToString();
  ASSERT_TRUE(got.ok()) << got.status().ToString();
  ASSERT_EQ(got->size(), 1u);
  ASSERT_EQ(want->size(), 1u);
  EXPECT_EQ((*got)[0].mesh.vertices, (*want)[0].mesh.vertices);
  EXPECT_EQ((*got)[0].mesh.triangles, (*want)[0].mesh.triangles);
  // Against the file itself: vertex i (0-based) has y = i, so face t of the forward walk has y 97t, 97t+1,
  // 97t+2, and face t of the backward walk has n-1-131t, n-2-131t, n-3-131t.
  const Mesh& m = (*got)[0].mesh;
  const size_t forward = (n - 2 + 96) / 97;
  ASSERT_GE(m.triangles.size() / 3, forward + 100);
  auto y = [&](size_t t, int c) { return m.vertices[3 * size_t{m.triangles[3 * t + c]} + 1]; };
  for (size_t t = 0; t < forward; ++t)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(y(t, c), 97.0 * t + c) << "face " << t;
  for (size_t t = 0; t < 100; ++t)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(y(forward + t, c), n - 1 - 131.0 * t - c) << "face " << forward + t;
}

// UTM-sized coordinates keep their millimetres: float32 would round 5000000.0001 to 5000000.
TEST(ObjReaderTest, CoordinatesFarFromZeroKeepTheirDetail) {
  auto objs = ReadOk(
      "v 500000.1234 5000000.0001 100\nv 500000.1244 5000000.0001 100\nv 500000.1234 5000000.0011 100\n"
      "f 1 2 3\n");
  ASSERT_EQ(objs.size(), 1u);
  EXPECT_EQ(objs[0].mesh.vertices[0], 500000.1234);
  EXPECT_EQ(objs[0].mesh.vertices[1], 5000000.0001);
  EXPECT_EQ(objs[0].mesh.vertices[3], 500000.1244);
  EXPECT_EQ(objs[0].mesh.vertices[7], 5000000.0011);
}

TEST(ObjReaderTest, LongLinesGrowTheBuffer) {
  // One polygon with 300k vertices: a 2+ MB line, longer than the 1 MiB read buffer.
  std::string s;
  const int n = 300000;
  for (int i = 0; i < n; ++i) s.append("v ").append(std::to_string(i)).append(" 0 0\n");
  s += "o big\nf";
  for (int i = 1; i <= n; ++i) s.append(" ").append(std::to_string(i));
  s += "\n";
  auto objs = ReadOk(s);
  ASSERT_EQ(objs.size(), 1u);
  EXPECT_EQ(objs[0].mesh.triangle_count(), static_cast<size_t>(n - 2));
  EXPECT_EQ(objs[0].mesh.vertex_count(), static_cast<size_t>(n));
}

const char kThree[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";  // lines 1-3

TEST(ObjReaderErrorTest, BadNumbers) {
  ExpectError(std::string(kThree) + "v 1 x 2\n", 4, "bad number 'x'");
  ExpectError(std::string(kThree) + "v 1 2.5.3 2\n", 4, "bad number '2.5.3'");
  ExpectError(std::string(kThree) + "\n\nv 1,0 2 3\n", 6, "bad number '1,0'");
  ExpectError(std::string(kThree) + "f 1 2 three\n", 4, "bad vertex reference 'three'");
  ExpectError(std::string(kThree) + "f 1 2 3x\n", 4, "bad vertex reference '3x'");
  ExpectError(std::string(kThree) + "f 1 2 3/\n", 4, "bad vertex reference '3/'");
  ExpectError(std::string(kThree) + "f 1 2 3/1/1/1\n", 4, "bad vertex reference '3/1/1/1'");
  ExpectError(std::string(kThree) + "f 1 2 /3\n", 4, "bad vertex reference '/3'");
}

TEST(ObjReaderErrorTest, CoordinateCounts) {
  ExpectError("v 1 2\n", 1, "too few coordinates (2, need x y z)");
  ExpectError("v\n", 1, "too few coordinates (0");
  ExpectError("v 1 2 3 4 5 6 7 8\n", 1, "too many values (8");
}

TEST(ObjReaderErrorTest, NonFiniteAndOutOfRangeCoordinates) {
  ExpectError(std::string(kThree) + "v nan 0 0\n", 4, "non-finite coordinate 'nan'");
  ExpectError(std::string(kThree) + "v 0 inf 0\n", 4, "non-finite coordinate 'inf'");
  ExpectError(std::string(kThree) + "v 0 0 -Infinity\n", 4, "non-finite coordinate '-Infinity'");
  ExpectError(std::string(kThree) + "v 0 0 1e309\n", 4, "coordinate out of range '1e309'");
  ExpectError(std::string(kThree) + "v 0 0 -1e400\n", 4, "coordinate out of range '-1e400'");
  // Finite doubles beyond 2^124 could not be kept as float32 offsets in a store (include/mktree/scene.h).
  ExpectError(std::string(kThree) + "v 0 3e37 0\n", 4,
              "coordinate out of range '3e37' (at most 2^124 in magnitude)");
}

TEST(ObjReaderErrorTest, IndexZeroAndOutOfRange) {
  ExpectError(std::string(kThree) + "f 0 1 2\n", 4, "vertex index 0");
  ExpectError(std::string(kThree) + "f 1 2 4\n", 4, "vertex index 4 out of range (3 defined so far)");
  ExpectError(std::string(kThree) + "f 1 2 -4\n", 4, "vertex index -4 out of range");
  // A forward reference to a vertex defined later is out of range too: vertices must precede their use.
  ExpectError(std::string(kThree) + "f 1 2 4\nv 1 1 1\n", 4, "out of range");
  ExpectError(std::string(kThree) + "vt 0 0\nf 1/1 2/2 3/1\n", 5, "texture coordinate index 2 out of range");
  ExpectError(std::string(kThree) + "f 1//1 2//1 3//1\n", 4, "normal index 1 out of range");
  ExpectError(std::string(kThree) + "vn 0 0 1\nf 1//0 2//1 3//1\n", 5, "normal index 0");
}

TEST(ObjReaderErrorTest, FacesNeedThreeVertices) {
  ExpectError(std::string(kThree) + "f 1 2\n", 4, "face: 2 vertices (a face needs at least 3)");
  ExpectError(std::string(kThree) + "f\n", 4, "face: 0 vertices");
}

TEST(ObjReaderErrorTest, UnknownAndUnsupportedDirectives) {
  ExpectError(std::string(kThree) + "vx 1 2 3\n", 4, "unknown directive 'vx'");
  ExpectError(std::string(kThree) + "\x01\x02garbage\n", 4, "unknown directive");
  ExpectError(std::string(kThree) + "cstype bspline\n", 4, "free-form geometry ('cstype') is not supported");
}

TEST(ObjReaderErrorTest, TruncatedLastLine) {
  ExpectError(std::string(kThree) + "f 1 2 3\nv 1 2", 5,
              "too few coordinates (2, need x y z) (the file ends inside");
  ExpectError(std::string(kThree) + "f 1 2", 4, "truncated?");
  ExpectError(std::string(kThree) + "f 1 2 3\nv 1 2 3e", 5, "bad number '3e'");
  ExpectError(std::string(kThree) + "f 1 2 \\\n", 4, "truncated?");  // continuation into end of file
}

TEST(ObjReaderErrorTest, ErrorsAreStickyAndComeAfterTheObjectsBeforeThem) {
  std::string path = WriteObj("o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nf 1 2 9\n");
  auto src = OpenObjFile(path);
  ASSERT_TRUE(src.ok());
  SceneObject o;
  auto r = (*src)->Next(&o);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(*r);
  EXPECT_EQ(o.name, "a");
  r = (*src)->Next(&o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(":7: "), std::string::npos) << r.status().message();
  auto again = (*src)->Next(&o);
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.status().message(), r.status().message());
}

TEST(ObjReaderErrorTest, MissingFileAndDirectory) {
  auto r = OpenObjFile("/nonexistent/dir/scene.obj");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kNotFound);
  EXPECT_NE(r.status().message().find("/nonexistent/dir/scene.obj"), std::string::npos);
  auto d = OpenObjFile(fs::temp_directory_path().string());
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.status().message().find("not a regular file"), std::string::npos);
}

// Mutated and truncated copies of a valid file either read or fail with an error naming the file and a
// line; none may crash or return an index outside its mesh.
TEST(ObjReaderErrorTest, MutatedFilesNeverCrashAndErrorsNameTheLine) {
  const std::string valid =
      "# test\nmtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
      "o a\nusemtl m\nf 1/1/1 2/1/1 3/1/1\nf -4//1 -3//1 -2//1 -1//1\ng grp\ns 1\nf 1 2 3 4\n"
      "o b\nv 0 0 1e-3\nf 5 1 2\nl 1 2\n";
  const std::string path = WriteObj(valid);
  const char alphabet[] = "0123456789 -+./\n\r\tvfognlsp#e\\x";
  uint64_t state = 12345;
  auto next = [&state]() {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<uint32_t>(state >> 33);
  };
  int failures = 0;
  for (int round = 0; round < 1500; ++round) {
    std::string text = valid;
    const int edits = 1 + next() % 3;
    for (int e = 0; e < edits; ++e) {
      size_t at = next() % text.size();
      switch (next() % 4) {
        case 0:
          text[at] = alphabet[next() % (sizeof(alphabet) - 1)];
          break;
        case 1:
          text.erase(at, 1 + next() % 4);
          break;
        case 2:
          text.insert(at, 1, alphabet[next() % (sizeof(alphabet) - 1)]);
          break;
        case 3:
          text.resize(at);
          break;
      }
      if (text.empty()) text = "v";
    }
    // A fresh file each round: rewriting one in place makes ext4 flush it to disk every time.
    fs::remove(path);
    std::ofstream(path, std::ios::binary) << text;
    auto r = ReadObj(path);
    if (!r.ok()) {
      ++failures;
      const std::string& msg = r.status().message();
      ASSERT_EQ(msg.rfind(path + ":", 0), 0u) << msg;
      ASSERT_TRUE(std::isdigit(static_cast<unsigned char>(msg[path.size() + 1]))) << msg;
      continue;
    }
    for (const SceneObject& o : *r) {
      ASSERT_GT(o.mesh.triangle_count(), 0u);
      for (uint32_t i : o.mesh.triangles) ASSERT_LT(i, o.mesh.vertex_count());
      for (double c : o.mesh.vertices) ASSERT_TRUE(std::isfinite(c));
    }
  }
  EXPECT_GT(failures, 100);  // the mutations do hit the error paths
}

// The real scenes: counts from /work/shared/data/README.md (one `o` line per object, every face a
// triangle in these files). Also checks ids, non-empty names and that every index is in range.

class ObjRealFileTest : public ::testing::TestWithParam<RealFile> {};

TEST_P(ObjRealFileTest, MatchesTheDataReadme) {
  const RealFile& f = GetParam();
  CheckRealFile(OpenObjFile(std::string(MKTREE_SHARED_DATA) + "/" + f.path, 7), 7, f);
}

INSTANTIATE_TEST_SUITE_P(SharedData, ObjRealFileTest,
                         ::testing::Values(RealFile{"buildings/steel_mini_project.obj", 2636, 261069},
                                           RealFile{"buildings/duplex.obj", 215, 26774},
                                           RealFile{"city/denhaag_01.obj", 1991, 41183}));

TEST(ObjRealFileNamesTest, NamesComeFromObjectLines) {
  auto src = OpenObjFile(std::string(MKTREE_SHARED_DATA) + "/buildings/duplex.obj");
  ASSERT_TRUE(src.ok());
  SceneObject o;
  auto more = (*src)->Next(&o);
  ASSERT_TRUE(more.ok() && *more);
  EXPECT_EQ(o.name, "IfcSlab_5165");
  EXPECT_EQ(o.id, 0u);
}

}  // namespace
}  // namespace mktree
