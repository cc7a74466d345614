// Shared by the reader tests: temp scene files, reading a source to the end, and the check of a real
// scene against the counts of /work/shared/data/README.md.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "engine/scene/assimp_reader.h"
#include "engine/scene/scene_source.h"
#include "test_dirs.h"

namespace mktree {

// Writes `content` to `name` in a per-test folder (named after the test, in the program's folder, removed
// when it ends) and returns its path.
inline std::string WriteTemp(const std::string& content, const std::string& name) {
  namespace fs = std::filesystem;
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = testing::ProgramDir() / (std::string(info->test_suite_name()) + "_" + info->name());
  fs::create_directories(dir);
  fs::path p = dir / name;
  std::ofstream(p, std::ios::binary) << content;
  return p.string();
}

// Every object of an opened source, or the first error.
inline Result<std::vector<SceneObject>> ReadAllFrom(Result<std::unique_ptr<SceneSource>> src) {
  if (!src.ok()) return src.status();
  std::vector<SceneObject> objects;
  while (true) {
    SceneObject o;
    auto more = (*src)->Next(&o);
    if (!more.ok()) return more.status();
    if (!*more) return objects;
    objects.push_back(std::move(o));
  }
}

// Every object of a file read through assimp, or the first error.
inline Result<std::vector<SceneObject>> ReadAssimp(const std::string& path, ObjectId first_id = 0) {
  return ReadAllFrom(OpenAssimpFile(path, first_id));
}

// Real scenes: the file under MKTREE_SHARED_DATA and its expected counts.

struct RealFile {
  const char* path;
  size_t objects;
  size_t triangles;
};

// Reads the source to the end; checks ids (consecutive from `first_id`), names, indices, bounds and the
// counts.
inline void CheckRealFile(Result<std::unique_ptr<SceneSource>> src, ObjectId first_id, const RealFile& f) {
  ASSERT_TRUE(src.ok()) << src.status().ToString();
  size_t objects = 0, triangles = 0;
  SceneObject o;
  while (true) {
    auto more = (*src)->Next(&o);
    ASSERT_TRUE(more.ok()) << more.status().ToString();
    if (!*more) break;
    EXPECT_EQ(o.id, first_id + objects);
    ASSERT_FALSE(o.name.empty());
    ASSERT_GT(o.mesh.triangle_count(), 0u);
    for (uint32_t i : o.mesh.triangles) ASSERT_LT(i, o.mesh.vertex_count()) << o.name;
    ASSERT_FALSE(o.Aabb().empty());
    ++objects;
    triangles += o.mesh.triangle_count();
  }
  EXPECT_EQ(objects, f.objects);
  EXPECT_EQ(triangles, f.triangles);
}

}  // namespace mktree
