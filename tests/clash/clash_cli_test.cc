// mktree clash and mktree collide: the JSON lines match the API's pairs, --summary adds up, errors are one
// line naming the file.
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "engine/ingest/store_builder.h"
#include "engine/scene/obj_writer.h"
#include "engine/scene/vector_scene_source.h"
#include "mktree/database.h"
#include "query/scene_fixtures.h"
#include "test_dirs.h"
#include "tool_runner.h"

namespace mktree {
namespace {

std::vector<std::string> Lines(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

class ClashCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir("mktree_clash_cli");
    scene_ = new std::vector<SceneObject>(testing::ClusteredScene(400, 21));
    IngestOptions o;
    o.store.params.block_size = 512;
    o.store.params.blocks_per_page = 2;
    std::vector<SceneOpener> in{[](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
      return std::unique_ptr<SceneSource>(new VectorSceneSource(scene_, first));
    }};
    ASSERT_TRUE(BuildStore(in, dir_->file("s.mkt"), o).ok());
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete dir_;
  }
  static testing::TempDir* dir_;
  static std::vector<SceneObject>* scene_;
};
testing::TempDir* ClashCli::dir_ = nullptr;
std::vector<SceneObject>* ClashCli::scene_ = nullptr;

TEST_F(ClashCli, ClashPrintsThePairsOfTheApiAndASummary) {
  auto db = Database::Open(dir_->file("s.mkt"));
  ASSERT_TRUE(db.ok());
  ClashOptions o;
  o.clearance = 0.1;
  std::vector<ClashPair> api;
  ClashStats s;
  ASSERT_TRUE((*db)
                  ->SelfClash(
                      o, [&](const ClashPair& p) { api.push_back(p); }, &s)
                  .ok());
  ASSERT_FALSE(api.empty());
  const auto r =
      testing::RunMktree("clash " + dir_->file("s.mkt") + " --clearance 0.1 --threads 3 --summary", *dir_);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto lines = Lines(r.out);
  ASSERT_EQ(lines.size(), api.size() + 1);
  for (size_t i = 0; i < api.size(); ++i) {
    const std::string head =
        "{\"a\": " + std::to_string(api[i].a) + ", \"b\": " + std::to_string(api[i].b) + ",";
    EXPECT_EQ(lines[i].rfind(head, 0), 0u) << lines[i];
    EXPECT_NE(lines[i].find("\"meeting\": "), std::string::npos);
  }
  EXPECT_EQ(lines.back().rfind(
                "{\"pairs\": " + std::to_string(api.size()) + ", \"hard\": " + std::to_string(s.hard), 0),
            0u)
      << lines.back();
  EXPECT_NE(lines.back().find("\"store_pages\": " + std::to_string(s.store_pages)), std::string::npos);

  const auto capped =
      testing::RunMktree("clash " + dir_->file("s.mkt") + " --clearance 0.1 --max-pairs 3 --summary", *dir_);
  ASSERT_EQ(capped.code, 0) << capped.err;
  EXPECT_EQ(Lines(capped.out).size(), 4u);
  EXPECT_NE(capped.out.find("\"capped_pairs\": " + std::to_string(api.size() - 3)), std::string::npos);
}

TEST_F(ClashCli, CollideReadsAnyScene) {
  // The object: the first three objects of the scene (moved there and back: a copy within rounding of each),
  // as an OBJ file, moved away and back.
  std::vector<SceneObject> obj(scene_->begin(), scene_->begin() + 3);
  for (auto& o : obj)
    for (size_t i = 0; i < o.mesh.vertices.size(); i += 3) o.mesh.vertices[i] -= 1000;
  auto w = ObjWriter::Create(dir_->file("o.obj"));
  ASSERT_TRUE(w.ok());
  for (const auto& o : obj) ASSERT_TRUE((*w)->Write(o).ok());
  ASSERT_TRUE((*w)->Finish().ok());
  const auto r = testing::RunMktree("collide " + dir_->file("s.mkt") + " --object " + dir_->file("o.obj") +
                                        " --translate 1000,0,0 --clearance 0.001 --summary",
                                    *dir_);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto lines = Lines(r.out);
  ASSERT_GE(lines.size(), 4u);  // the three objects themselves at least, and the summary
  for (ObjectId id : {0u, 1u, 2u})
    EXPECT_NE(r.out.find("{\"a\": " + std::to_string(id) + ", \"b\": -1, \"class\": "), std::string::npos);
}

TEST_F(ClashCli, ErrorsNameTheFile) {
  auto r = testing::RunMktree("clash " + dir_->file("missing.mkt"), *dir_);
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(r.err.rfind("error: ", 0), 0u);
  EXPECT_NE(r.err.find("missing.mkt"), std::string::npos);
  r = testing::RunMktree("collide " + dir_->file("s.mkt") + " --object " + dir_->file("nothing.obj"), *dir_);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("nothing.obj"), std::string::npos);
  r = testing::RunMktree("clash " + dir_->file("s.mkt") + " --clearance -1", *dir_);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("clearance"), std::string::npos);
  r = testing::RunMktree(
      "collide " + dir_->file("s.mkt") + " --object " + dir_->file("o.obj") + " --translate 1,2", *dir_);
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--translate"), std::string::npos);
}

}  // namespace
}  // namespace mktree
