// What the query tests check answers against: a store built from objects in RAM, and brute force over
// the geometry that store keeps (tests/store_format/stored_geometry.h), in its frame (ChooseStoreOrigin of
// the scene's first object).
#pragma once

#include <vector>

#include "engine/geometry/exact_geometry.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/vector_scene_source.h"
#include "mktree/database.h"
#include "store_format/stored_geometry.h"

namespace mktree::testing {

inline Status BuildFromObjects(const std::vector<SceneObject>& objs, const std::string& path,
                               const IngestOptions& o) {
  std::vector<SceneOpener> in{[&objs](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(new VectorSceneSource(&objs, first));
  }};
  auto r = BuildStore(in, path, o);
  return r.ok() ? Status::Ok() : r.status();
}

class BruteForce {
 public:
  explicit BruteForce(const std::vector<SceneObject>& objs)
      : origin_(ChooseStoreOrigin(objs[0].mesh.Bounds())), stored_(StoredScene(objs, origin_)) {}

  std::vector<ObjectId> Point(const Vec3d& world, QueryMode mode) const {
    const Vec3d p{world.x - origin_.x, world.y - origin_.y, world.z - origin_.z};
    std::vector<ObjectId> out;
    for (const StoredObject& o : stored_) {
      if (!o.box.Contains(p)) continue;
      if (mode == QueryMode::kExact && !PointInSolid(o.mesh, p)) continue;
      out.push_back(o.id);
    }
    return out;
  }
  std::vector<ObjectId> Box(const Box3d& world, QueryMode mode) const {
    Box3d b;
    for (int a = 0; a < 3; ++a) {
      b.min[a] = world.min[a] - origin_[a];
      b.max[a] = world.max[a] - origin_[a];
    }
    std::vector<ObjectId> out;
    for (const StoredObject& o : stored_) {
      if (!o.box.Intersects(b)) continue;
      if (mode == QueryMode::kExact && !MeshMeetsBox(o.mesh, b)) continue;
      out.push_back(o.id);
    }
    return out;
  }
  std::vector<ObjectId> Answer(const Query& q) const {
    return q.kind == Query::Kind::kPoint ? Point(q.point, q.mode) : Box(q.box, q.mode);
  }

 private:
  Vec3d origin_;
  std::vector<StoredObject> stored_;
};

}  // namespace mktree::testing
