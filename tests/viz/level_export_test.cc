// mktree export: the written PLY and GLB files, re-imported with assimp, hold exactly the objects,
// vertices, triangles and colours of the level-k colouring computed independently (GroupAtLevel over the
// scene's own objects and the store's object table), at several levels, as geometry and as boxes.
#include "engine/viz/level_export.h"

#include <assimp/material.h>
#include <assimp/mesh.h>
#include <assimp/scene.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <assimp/Importer.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "engine/ingest/store_builder.h"
#include "engine/scene/vector_scene_source.h"
#include "query/scene_fixtures.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::TempPath;

struct Expected {
  GroupCounts objects{}, vertices{}, triangles{};
};

class LevelExportTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    objs_ = new std::vector<SceneObject>(testing::ClusteredScene(900, 7));
    store_path_ = new std::string(TempPath("scene.mkt"));
    IngestOptions o;
    o.store.backend = Backend::kPagedFile;
    o.store.params.block_size = 1024;  // small pages: a deep tree, and some multi-page leaves
    o.store.params.blocks_per_page = 2;
    const std::vector<SceneObject>* objs = objs_;
    std::vector<SceneOpener> in{[objs](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
      return std::unique_ptr<SceneSource>(new VectorSceneSource(objs, first));
    }};
    auto r = BuildStore(in, *store_path_, o);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
  }
  static void TearDownTestSuite() {
    fs::remove(*store_path_);
    delete store_path_;
    delete objs_;
  }
  void SetUp() override {
    auto r = StoreReader::Open(*store_path_);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    reader_ = std::move(*r);
  }

  // The colouring from the scene objects themselves: their AABBs and the store's leaf of each id.
  Expected Expect(int k, bool boxes) const {
    Expected e;
    for (const SceneObject& o : *objs_) {
      const int g = GroupIndex(GroupAtLevel(reader_->tree(), *reader_->ObjectLeaf(o.id), o.Aabb(), k));
      ++e.objects[g];
      e.vertices[g] += boxes ? 8 : o.mesh.vertex_count();
      e.triangles[g] += boxes ? 12 : o.mesh.triangle_count();
    }
    return e;
  }

  static std::vector<SceneObject>* objs_;
  static std::string* store_path_;
  std::unique_ptr<StoreReader> reader_;
};

std::vector<SceneObject>* LevelExportTest::objs_ = nullptr;
std::string* LevelExportTest::store_path_ = nullptr;

// The group whose colour is nearest to (r, g, b) in [0, 1]; `linear` for glTF material factors.
int GroupOfColour(double r, double g, double b, bool linear) {
  auto lin = [](uint8_t c) {
    const double s = c / 255.0;
    return s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4);
  };
  int best = -1;
  double best_d = 1e9;
  for (int i = 0; i < kLevelGroups; ++i) {
    const Rgb c = GroupColour(static_cast<LevelGroup>(i));
    const double cr = linear ? lin(c.r) : c.r / 255.0, cg = linear ? lin(c.g) : c.g / 255.0,
                 cb = linear ? lin(c.b) : c.b / 255.0;
    const double d = std::abs(cr - r) + std::abs(cg - g) + std::abs(cb - b);
    if (d < best_d) best_d = d, best = i;
  }
  EXPECT_LT(best_d, 0.01) << "colour " << r << "," << g << "," << b << " is no group's";
  return best;
}

TEST_F(LevelExportTest, GroupsCoverEveryLevel) {
  // The scene is deep enough that levels 0..2 have both sides, some overlap sets are not empty, and a
  // deep level is all grey: the tests below see every colour.
  uint64_t overlap = 0;
  for (int k = 0; k <= 2; ++k) {
    const Expected e = Expect(k, false);
    EXPECT_GT(e.objects[0], 0u) << k;
    EXPECT_GT(e.objects[1], 0u) << k;
    overlap += e.objects[2];
  }
  EXPECT_GT(overlap, 0u);
  EXPECT_EQ(Expect(200, false).objects[GroupIndex(LevelGroup::kAboveLevel)], objs_->size());
}

TEST_F(LevelExportTest, PlyReimportsWithTheColouring) {
  for (int k : {0, 1, 2, 200}) {
    for (bool boxes : {false, true}) {
      SCOPED_TRACE("level " + std::to_string(k) + (boxes ? " boxes" : " geometry"));
      const std::string path = TempPath("out.ply");
      ExportOptions opts;
      opts.level = k;
      opts.boxes = boxes;
      opts.format = ExportFormat::kPly;
      auto report = ExportLevel(*reader_, path, opts);
      ASSERT_TRUE(report.ok()) << report.status().ToString();
      const Expected e = Expect(k, boxes);
      EXPECT_EQ(report->objects, e.objects);
      EXPECT_EQ(report->vertices, e.vertices);
      EXPECT_EQ(report->triangles, e.triangles);
      EXPECT_EQ(report->bytes, fs::file_size(path));

      Assimp::Importer imp;
      const aiScene* s = imp.ReadFile(path, 0);
      ASSERT_NE(s, nullptr) << imp.GetErrorString();
      ASSERT_EQ(s->mNumMeshes, 1u);
      const aiMesh* m = s->mMeshes[0];
      ASSERT_TRUE(m->HasVertexColors(0));
      GroupCounts vertices{}, triangles{};
      for (unsigned v = 0; v < m->mNumVertices; ++v) {
        const aiColor4D& c = m->mColors[0][v];
        ++vertices[GroupOfColour(c.r, c.g, c.b, false)];
      }
      for (unsigned f = 0; f < m->mNumFaces; ++f) {
        ASSERT_EQ(m->mFaces[f].mNumIndices, 3u);
        const aiColor4D& c = m->mColors[0][m->mFaces[f].mIndices[0]];
        ++triangles[GroupOfColour(c.r, c.g, c.b, false)];
      }
      EXPECT_EQ(vertices, e.vertices);
      EXPECT_EQ(triangles, e.triangles);
      if (boxes) {
        // Boxes: each object's 8 corners are its stored AABB's, in the file's vertex order.
        const aiVector3D& lo = m->mVertices[0];
        const aiVector3D& hi = m->mVertices[7];
        EXPECT_LE(lo.x, hi.x);
        EXPECT_LE(lo.y, hi.y);
        EXPECT_LE(lo.z, hi.z);
      }
      fs::remove(path);
    }
  }
}

TEST_F(LevelExportTest, GlbReimportsWithOneMeshPerGroup) {
  for (int k : {0, 1, 2, 200}) {
    for (bool boxes : {false, true}) {
      SCOPED_TRACE("level " + std::to_string(k) + (boxes ? " boxes" : " geometry"));
      const std::string path = TempPath("out.glb");
      ExportOptions opts;
      opts.level = k;
      opts.boxes = boxes;
      opts.format = ExportFormat::kGlb;
      auto report = ExportLevel(*reader_, path, opts);
      ASSERT_TRUE(report.ok()) << report.status().ToString();
      const Expected e = Expect(k, boxes);
      EXPECT_EQ(report->objects, e.objects);

      // The GLB header: magic, version 2, and a length equal to the file's.
      std::ifstream in(path, std::ios::binary);
      uint32_t header[3] = {};
      in.read(reinterpret_cast<char*>(header), sizeof header);
      EXPECT_EQ(header[0], 0x46546C67u);
      EXPECT_EQ(header[1], 2u);
      EXPECT_EQ(header[2], fs::file_size(path));

      Assimp::Importer imp;
      const aiScene* s = imp.ReadFile(path, 0);
      ASSERT_NE(s, nullptr) << imp.GetErrorString();
      GroupCounts vertices{}, triangles{};
      unsigned nonempty = 0;
      for (int g = 0; g < kLevelGroups; ++g) nonempty += e.triangles[g] > 0;
      ASSERT_EQ(s->mNumMeshes, nonempty);
      for (unsigned i = 0; i < s->mNumMeshes; ++i) {
        const aiMesh* m = s->mMeshes[i];
        aiColor4D c;
        const aiMaterial* mat = s->mMaterials[m->mMaterialIndex];
        ASSERT_EQ(mat->Get(AI_MATKEY_BASE_COLOR, c), aiReturn_SUCCESS);
        const int g = GroupOfColour(c.r, c.g, c.b, true);
        EXPECT_EQ(std::string(m->mName.C_Str()), GroupName(static_cast<LevelGroup>(g)));
        vertices[g] += m->mNumVertices;
        triangles[g] += m->mNumFaces;
      }
      EXPECT_EQ(vertices, e.vertices);
      EXPECT_EQ(triangles, e.triangles);
      fs::remove(path);
    }
  }
}

TEST_F(LevelExportTest, ErrorsLeaveNothing) {
  ExportOptions opts;
  opts.level = -1;
  const std::string path = TempPath("neg.ply");
  auto r = ExportLevel(*reader_, path, opts);
  EXPECT_FALSE(r.ok());
  EXPECT_FALSE(fs::exists(path));

  opts.level = 1;
  const std::string bad = TempPath("no_such_dir") + "/out.ply";
  r = ExportLevel(*reader_, bad, opts);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(bad), std::string::npos) << r.status().message();

  EXPECT_FALSE(ExportFormatFor("scene.obj").ok());
  EXPECT_NE(ExportFormatFor("scene.obj").status().message().find("scene.obj"), std::string::npos);
  EXPECT_EQ(*ExportFormatFor("A.PLY"), ExportFormat::kPly);
  EXPECT_EQ(*ExportFormatFor("dir.v2/a.glb"), ExportFormat::kGlb);
}

TEST_F(LevelExportTest, CorruptPageIsAnErrorAndLeavesNothing) {
  // Flip a byte in the middle of the first leaf page of a copy of the store.
  const std::string copy = TempPath("corrupt.mkt");
  fs::copy_file(*store_path_, copy, fs::copy_options::overwrite_existing);
  const uint64_t page_bytes = reader_->tree().params.mem_page();
  {
    std::fstream f(copy, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(page_bytes + page_bytes / 2));  // page 0 follows the header page
    char c = 0;
    f.read(&c, 1);
    c = static_cast<char>(c ^ 0x5a);
    f.seekp(static_cast<std::streamoff>(page_bytes + page_bytes / 2));
    f.write(&c, 1);
  }
  auto reader = StoreReader::Open(copy);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  const std::string path = TempPath("corrupt.glb");
  ExportOptions opts;
  opts.format = ExportFormat::kGlb;
  auto r = ExportLevel(**reader, path, opts);
  EXPECT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(copy), std::string::npos) << r.status().message();
  // Neither the output nor its temporary file is left behind.
  for (const auto& entry : fs::directory_iterator(fs::path(path).parent_path()))
    EXPECT_NE(entry.path().string().rfind(path, 0), 0u) << entry.path();
  fs::remove(copy);
}

}  // namespace
}  // namespace mktree
