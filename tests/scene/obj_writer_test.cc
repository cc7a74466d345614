#include "engine/scene/obj_writer.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <charconv>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "engine/generator/tanker_generator.h"
#include "engine/scene/obj_reader.h"
#include "generator/mesh_checks.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;
using testing::Drain;

class ObjWriterTest : public ::testing::Test {
 protected:
  std::vector<SceneObject> WriteTanker(const std::string& path, uint64_t n, uint64_t seed = 5) {
    auto source = MakeTankerSource(n, seed);
    std::vector<SceneObject> objects = Drain(source.get());
    auto writer = ObjWriter::Create(path);
    EXPECT_TRUE(writer.ok()) << writer.status().ToString();
    for (const SceneObject& o : objects) EXPECT_TRUE((*writer)->Write(o).ok());
    EXPECT_TRUE((*writer)->Finish().ok());
    EXPECT_EQ((*writer)->bytes_written(), fs::file_size(path));
    return objects;
  }

  testing::TempDir dir_{"mktree_obj_writer"};
};

// A minimal independent parse: `o` starts an object, `v` adds a vertex, `f` has three relative indices
// that must land in the current object's vertices; the parsed scene must equal what was written.
TEST_F(ObjWriterTest, OutputParsesBackToTheSameScene) {
  const std::string path = dir_ / "scene.obj";
  const auto objects = WriteTanker(path, 600);
  std::ifstream in(path);
  std::string line;
  std::vector<SceneObject> parsed;
  uint64_t comments = 0;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string op;
    ls >> op;
    if (op == "#") {
      ++comments;
    } else if (op == "o") {
      parsed.emplace_back();
      parsed.back().name = line.substr(2);
    } else if (op == "v") {
      ASSERT_FALSE(parsed.empty());
      for (int d = 0; d < 3; ++d) {
        std::string tok;
        ls >> tok;
        double v;
        const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
        ASSERT_TRUE(r.ec == std::errc() && r.ptr == tok.data() + tok.size()) << line;
        parsed.back().mesh.vertices.push_back(v);
      }
    } else if (op == "f") {
      ASSERT_FALSE(parsed.empty());
      const long long nv = static_cast<long long>(parsed.back().mesh.vertex_count());
      for (int d = 0; d < 3; ++d) {
        long long idx = 0;
        ASSERT_TRUE(ls >> idx) << line;
        ASSERT_LT(idx, 0) << line;
        ASSERT_GE(idx, -nv) << line;
        parsed.back().mesh.triangles.push_back(static_cast<uint32_t>(nv + idx));
      }
      std::string extra;
      ASSERT_FALSE(ls >> extra) << line;
    } else {
      FAIL() << "unexpected line: " << line;
    }
  }
  EXPECT_EQ(comments, 1u);
  ASSERT_EQ(parsed.size(), objects.size());
  for (size_t i = 0; i < parsed.size(); ++i) {
    EXPECT_EQ(parsed[i].name, objects[i].name);
    EXPECT_EQ(parsed[i].mesh.vertices, objects[i].mesh.vertices) << i;  // to_chars round-trips doubles
    EXPECT_EQ(parsed[i].mesh.triangles, objects[i].mesh.triangles) << i;
  }
}

// Through the project's OBJ reader, which re-indexes each mesh in first-use order: compare each triangle's
// corner coordinates, in order.
TEST_F(ObjWriterTest, RoundTripThroughOpenObjFile) {
  const std::string path = dir_ / "scene.obj";
  const auto objects = WriteTanker(path, 800, 13);
  auto source = OpenObjFile(path, 40);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  const auto read = Drain(source->get());
  ASSERT_EQ(read.size(), objects.size());
  auto corner = [](const Mesh& m, size_t t, int c, int d) {
    return m.vertices[3 * m.triangles[3 * t + c] + d];
  };
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].id, 40 + i);
    EXPECT_EQ(read[i].name, objects[i].name);
    ASSERT_EQ(read[i].mesh.triangle_count(), objects[i].mesh.triangle_count()) << i;
    EXPECT_EQ(read[i].mesh.vertex_count(), objects[i].mesh.vertex_count()) << i;  // every vertex is used
    for (size_t t = 0; t < read[i].mesh.triangle_count(); ++t)
      for (int c = 0; c < 3; ++c)
        for (int d = 0; d < 3; ++d)
          ASSERT_EQ(corner(read[i].mesh, t, c, d), corner(objects[i].mesh, t, c, d));
  }
}

TEST_F(ObjWriterTest, SameSeedSameBytes) {
  WriteTanker(dir_ / "a.obj", 400, 8);
  WriteTanker(dir_ / "b.obj", 400, 8);
  WriteTanker(dir_ / "c.obj", 400, 9);
  auto slurp = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(slurp(dir_ / "a.obj"), slurp(dir_ / "b.obj"));
  EXPECT_NE(slurp(dir_ / "a.obj"), slurp(dir_ / "c.obj"));
}

TEST_F(ObjWriterTest, RejectsBadObjectsAndLeavesNoPartialFile) {
  const std::string path = dir_ / "scene.obj";
  {
    auto writer = ObjWriter::Create(path);
    ASSERT_TRUE(writer.ok());
    SceneObject o;
    o.name = "a\nb";
    EXPECT_EQ((*writer)->Write(o).code(), Status::Code::kInvalidArgument);
    o.name = "t";
    o.mesh.vertices = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    o.mesh.triangles = {0, 1, 3};
    EXPECT_EQ((*writer)->Write(o).code(), Status::Code::kInvalidArgument);
    o.mesh.triangles = {0, 1, 2};
    EXPECT_TRUE((*writer)->Write(o).ok());
    EXPECT_FALSE(fs::exists(path));
  }
  EXPECT_TRUE(fs::is_empty(dir_));
  const auto bad = ObjWriter::Create((dir_ / "no_such_dir" / "x.obj").string());
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("no_such_dir"), std::string::npos);
}

}  // namespace
}  // namespace mktree
