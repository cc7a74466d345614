// What a store keeps of an object's geometry (engine/store_format/object_codec.h restates it; this is the
// tests' oracle): the mesh in the store frame, rounded to float32 in the object's local frame, and its box.
// Query tests compare answers with brute force over this stored geometry, and codec tests check that it
// lies within float32's precision of the object's own size from the input.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree::testing {

// The box a leaf entry holds for `m` from a store whose origin is `origin`: its store-frame bounds rounded
// outward.
inline Box3f StoredBox(const Mesh& m, const Vec3d& origin = {}) {
  Box3d b;
  for (size_t i = 0; i < m.vertices.size(); i += 3)
    b.Extend(m.vertices[i] - origin.x, m.vertices[i + 1] - origin.y, m.vertices[i + 2] - origin.z);
  return RoundOutward(b);
}

// The mesh DecodeObjectMesh gives back for `m`: per axis, each vertex in the store frame rounded to float32
// as box.min + (local - 2^k), local = vertex - box.min + 2^k, 2^k the power of two above the box's extent
// (2^-100 when it is 0), kept within the box.
inline Mesh StoredMesh(const Mesh& m, const Vec3d& origin = {}) {
  const Box3f box = StoredBox(m, origin);
  Mesh out = m;
  for (size_t i = 0; i < m.vertices.size(); ++i) {
    const int c = static_cast<int>(i % 3);
    const double lo = box.min[c], extent = double{box.max[c]} - lo;
    const double base = std::ldexp(1.0, extent > 0 ? std::max(std::ilogb(extent) + 1, -100) : -100);
    float l = static_cast<float>(((m.vertices[i] - origin[c]) - lo) + base);
    if (double{l} - base > extent) l = std::nextafter(l, 0.0f);
    out.vertices[i] = lo + (double{l} - base);
  }
  return out;
}

// `decoded` (from a leaf entry) is exactly what the store keeps of `input`.
inline bool SameMesh(const Mesh& decoded, const Mesh& input, const Vec3d& origin = {}) {
  const Mesh expected = StoredMesh(input, origin);
  return decoded.vertices == expected.vertices && decoded.triangles == expected.triangles;
}

// An object as a store with origin `origin` keeps it: its box and mesh in the store frame.
struct StoredObject {
  ObjectId id = 0;
  Box3f box;
  Mesh mesh;
};
inline std::vector<StoredObject> StoredScene(const std::vector<SceneObject>& objects,
                                             const Vec3d& origin = {}) {
  std::vector<StoredObject> out;
  out.reserve(objects.size());
  for (const SceneObject& o : objects)
    out.push_back({o.id, StoredBox(o.mesh, origin), StoredMesh(o.mesh, origin)});
  return out;
}

}  // namespace mktree::testing
