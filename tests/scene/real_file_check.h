// Shared by the reader tests: read a real scene to the end and check it against the counts of
// /work/shared/data/README.md, plus ids (consecutive from `first_id`), names, indices and bounds.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "engine/scene/scene_source.h"

namespace mktree {

struct RealFile {
  const char* path;
  size_t objects;
  size_t triangles;
};

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
