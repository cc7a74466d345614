// The public build API (mktree/build.h): stores built from a vector, a callback and files answer as brute
// force does; bad input is an error naming the file and line or the object, and leaves nothing behind.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>

#include "mktree/build.h"
#include "mktree/database.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

constexpr uint32_t kCubeTriangles[36] = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                         2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};

// Axis-aligned boxes of random place and size; coordinates are multiples of 1/8 (exact in float32), so
// each object's solid is its AABB exactly and brute force needs no tolerance.
std::vector<SceneObject> RandomBoxes(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> pos(0, 800), size(1, 40);
  std::vector<SceneObject> objs;
  for (int i = 0; i < n; ++i) {
    SceneObject o;
    o.name = "box_" + std::to_string(i);
    o.attributes = {{"kind", "box"}};
    double lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = pos(rng) / 8.0;
      hi[a] = lo[a] + size(rng) / 8.0;
    }
    for (int v = 0; v < 8; ++v)
      o.mesh.vertices.insert(o.mesh.vertices.end(),
                             {(v & 1) ? hi[0] : lo[0], (v & 2) ? hi[1] : lo[1], (v & 4) ? hi[2] : lo[2]});
    o.mesh.triangles.assign(std::begin(kCubeTriangles), std::end(kCubeTriangles));
    objs.push_back(std::move(o));
  }
  return objs;
}

std::vector<ObjectId> BruteForce(const std::vector<SceneObject>& objs, const Box3d& q) {
  std::vector<ObjectId> ids;
  for (size_t i = 0; i < objs.size(); ++i) {
    const Box3d b = objs[i].mesh.Bounds();
    bool meets = true;
    for (int a = 0; a < 3; ++a) meets = meets && b.min[a] <= q.max[a] && q.min[a] <= b.max[a];
    if (meets) ids.push_back(static_cast<ObjectId>(i));
  }
  return ids;
}

std::vector<Box3d> RandomQueries(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(-2, 105), side(0, 12);
  std::vector<Box3d> qs;
  for (int i = 0; i < n; ++i) {
    Box3d q;
    const double s = i % 4 == 0 ? 0 : side(rng);  // every fourth a point
    for (int a = 0; a < 3; ++a) {
      q.min[a] = pos(rng);
      q.max[a] = q.min[a] + s;
    }
    qs.push_back(q);
  }
  return qs;
}

// Every query in both modes, point queries where the box is a point, against brute force.
void ExpectBruteForce(const std::string& store, const std::vector<SceneObject>& objs) {
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  ASSERT_EQ((*db)->object_count(), objs.size());
  int nonempty = 0;
  for (const Box3d& q : RandomQueries(300, 7)) {
    const std::vector<ObjectId> expected = BruteForce(objs, q);
    nonempty += !expected.empty();
    for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
      const bool point = q.min == q.max;
      QueryResult r;
      ASSERT_TRUE(
          (*db)
              ->Run(point ? Query::Point({q.min[0], q.min[1], q.min[2]}, mode) : Query::Box(q, mode), &r)
              .ok());
      EXPECT_EQ(r.hits, expected);
    }
  }
  EXPECT_GT(nonempty, 100);  // the queries do meet the scene
  for (size_t i = 0; i < objs.size(); i += 97) EXPECT_EQ(*(*db)->ObjectName(i), objs[i].name);
}

// The scene as OBJ text: one `o` per object, 1-based vertex indices continuing across objects.
void WriteObj(const std::vector<SceneObject>& objs, const std::string& path) {
  std::ofstream out(path);
  size_t base = 1;
  for (const SceneObject& o : objs) {
    out << "o " << o.name << "\n";
    for (size_t v = 0; v < o.mesh.vertex_count(); ++v)
      out << "v " << o.mesh.vertices[3 * v] << " " << o.mesh.vertices[3 * v + 1] << " "
          << o.mesh.vertices[3 * v + 2] << "\n";
    for (size_t t = 0; t < o.mesh.triangle_count(); ++t)
      out << "f " << base + o.mesh.triangles[3 * t] << " " << base + o.mesh.triangles[3 * t + 1] << " "
          << base + o.mesh.triangles[3 * t + 2] << "\n";
    base += o.mesh.vertex_count();
  }
}

std::set<std::string> Listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

BuildOptions SmallPages(BuildOptions::Backend backend) {
  BuildOptions opts;
  opts.backend = backend;
  opts.block_size = 1024;
  opts.blocks_per_page = 1;
  return opts;
}

class BuildApiTest : public ::testing::TestWithParam<BuildOptions::Backend> {};

TEST_P(BuildApiTest, FromVectorAnswersAsBruteForce) {
  const testing::TempDir dir("mktree_build_api");
  const auto objs = RandomBoxes(2000, 3);
  auto stats = BuildFromObjects(objs, dir.file("v.mkt"), SmallPages(GetParam()));
  ASSERT_TRUE(stats.ok()) << stats.status().ToString();
  EXPECT_EQ(stats->objects, objs.size());
  EXPECT_EQ(stats->triangles, 12 * objs.size());
  EXPECT_EQ(stats->page_bytes, 1024u);
  EXPECT_GT(stats->leaves, 10u);
  EXPECT_GE(stats->pages, stats->leaves);
  EXPECT_EQ(stats->store_bytes, fs::file_size(dir.file("v.mkt")));
  ExpectBruteForce(dir.file("v.mkt"), objs);
}

TEST_P(BuildApiTest, FromFileAndFromCallback) {
  const testing::TempDir dir("mktree_build_api");
  const auto objs = RandomBoxes(1500, 4);
  WriteObj(objs, dir.file("scene.obj"));
  auto from_file = BuildFromFiles({dir.file("scene.obj")}, dir.file("f.mkt"), SmallPages(GetParam()));
  ASSERT_TRUE(from_file.ok()) << from_file.status().ToString();
  ExpectBruteForce(dir.file("f.mkt"), objs);

  // The OBJ reader numbers vertices in order of use, so the file's entries differ from the vector's; the
  // callback form (on one thread, with progress) gives the vector's store (default threads) exactly.
  auto from_vector = BuildFromObjects(objs, dir.file("v.mkt"), SmallPages(GetParam()));
  ASSERT_TRUE(from_vector.ok()) << from_vector.status().ToString();
  size_t next = 0;
  std::vector<BuildStage> stages;
  BuildOptions opts = SmallPages(GetParam());
  opts.threads = 1;
  opts.progress = [&](BuildStage s, uint64_t, uint64_t) {
    if (stages.empty() || stages.back() != s) stages.push_back(s);
  };
  auto from_callback = BuildFromObjects(
      [&](SceneObject* out) -> Result<bool> {
        if (next == objs.size()) return false;
        *out = objs[next++];
        out->id = 12345;  // ignored: objects are numbered in order
        return true;
      },
      dir.file("c.mkt"), opts);
  ASSERT_TRUE(from_callback.ok()) << from_callback.status().ToString();
  EXPECT_EQ((std::vector<BuildStage>{BuildStage::kRead, BuildStage::kBuildTree, BuildStage::kWritePages,
                                     BuildStage::kWriteTable}),
            stages);
  EXPECT_EQ(from_callback->encoded_bytes, from_vector->encoded_bytes);
  EXPECT_EQ(from_callback->pages, from_vector->pages);
  EXPECT_EQ(from_callback->leaves, from_vector->leaves);
  EXPECT_EQ(from_callback->height, from_vector->height);
  ExpectBruteForce(dir.file("c.mkt"), objs);
}

INSTANTIATE_TEST_SUITE_P(Backends, BuildApiTest,
                         ::testing::Values(BuildOptions::Backend::kHdf5, BuildOptions::Backend::kPagedFile),
                         [](const auto& info) {
                           return info.param == BuildOptions::Backend::kHdf5 ? "hdf5" : "pagefile";
                         });

TEST(BuildApi, GeneratorAndSeveralInputsContinueOneNumbering) {
  const testing::TempDir dir("mktree_build_api");
  const auto objs = RandomBoxes(50, 5);
  WriteObj(objs, dir.file("a.obj"));
  auto stats = BuildFromFiles({"tanker:300:9", dir.file("a.obj")}, dir.file("t.mkt"));
  ASSERT_TRUE(stats.ok()) << stats.status().ToString();
  EXPECT_EQ(stats->objects, 350u);
  auto db = Database::Open(dir.file("t.mkt"));
  ASSERT_TRUE(db.ok());
  EXPECT_EQ(*(*db)->ObjectName(300), "box_0");
}

// A failed build leaves the directory as it was: the store before it unchanged, no temporary or spill.
void ExpectFailureLeavesNothing(const testing::TempDir& dir, const std::string& store,
                                const std::function<Status()>& build, const std::string& message_part) {
  const auto before = Listing(dir);
  const auto size_before = fs::exists(store) ? fs::file_size(store) : 0;
  const Status st = build();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find(message_part), std::string::npos) << st.ToString();
  EXPECT_EQ(Listing(dir), before) << st.ToString();
  if (size_before != 0) {
    EXPECT_EQ(fs::file_size(store), size_before);
    auto db = Database::Open(store);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
  }
}

TEST(BuildApi, BadFileNamesFileAndLineAndLeavesNothing) {
  const testing::TempDir dir("mktree_build_api");
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(BuildFromObjects(RandomBoxes(100, 6), store).ok());
  {
    std::ofstream bad(dir.file("bad.obj"));
    bad << "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 0 0 zz\n";
  }
  ExpectFailureLeavesNothing(
      dir, store,
      [&] {
        return BuildFromFiles({dir.file("bad.obj")}, store, SmallPages(BuildOptions::Backend::kHdf5))
            .status();
      },
      "bad.obj:6");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return BuildFromFiles({dir.file("missing.obj")}, store).status(); }, "missing.obj");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return BuildFromFiles({dir.path().string()}, store).status(); },
      "not a regular file");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return BuildFromFiles({"tanker:0"}, store).status(); }, "tanker:N");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return BuildFromFiles({}, store).status(); }, "no input");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return BuildFromFiles({store}, store).status(); }, "refusing to overwrite");
}

TEST(BuildApi, BadObjectsNameTheObjectAndLeaveNothing) {
  const testing::TempDir dir("mktree_build_api");
  const std::string store = dir.file("s.mkt");
  ASSERT_TRUE(BuildFromObjects(RandomBoxes(100, 6), store).ok());
  auto with = [&](const std::function<void(SceneObject&)>& spoil) {
    auto objs = RandomBoxes(300, 8);
    spoil(objs[250]);
    return BuildFromObjects(objs, store).status();
  };
  ExpectFailureLeavesNothing(
      dir, store, [&] { return with([](SceneObject& o) { o.mesh.triangles[7] = 8; }); },
      "object 250 'box_250': triangle 2 refers to vertex 8 of 8");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return with([](SceneObject& o) { o.mesh.vertices[4] = std::nan(""); }); },
      "object 250 'box_250': vertex 1");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return with([](SceneObject& o) { o.mesh.vertices[4] = 1e38; }); }, "vertex 1");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return with([](SceneObject& o) { o.mesh.triangles.clear(); }); }, "no triangle");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return with([](SceneObject& o) { o.mesh.vertices.pop_back(); }); },
      "not a multiple of 3");
  ExpectFailureLeavesNothing(
      dir, store, [&] { return BuildFromObjects(std::vector<SceneObject>{}, store).status(); },
      "empty scene");
  // The caller's own error ends the build as it is.
  ExpectFailureLeavesNothing(
      dir, store,
      [&] {
        int n = 0;
        return BuildFromObjects(
                   [&](SceneObject* out) -> Result<bool> {
                     if (++n == 200) return Status::IOError("my input: line 200: broken");
                     *out = RandomBoxes(1, n)[0];
                     return true;
                   },
                   store)
            .status();
      },
      "my input: line 200: broken");
  BuildOptions bad;
  bad.balance_r = 0.5;
  ExpectFailureLeavesNothing(
      dir, store, [&] { return BuildFromObjects(RandomBoxes(10, 1), store, bad).status(); }, "balance_r");
  bad = {};
  bad.block_size = 100;
  ExpectFailureLeavesNothing(
      dir, store, [&] { return BuildFromObjects(RandomBoxes(10, 1), store, bad).status(); }, "block_size");
}

}  // namespace
}  // namespace mktree
