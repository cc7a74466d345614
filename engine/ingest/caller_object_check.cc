#include "engine/ingest/caller_object_check.h"

#include <cmath>

namespace mktree {

Status CheckCallerObject(const SceneObject& obj, const std::string& what) {
  const Mesh& m = obj.mesh;
  if (m.vertices.size() % 3 != 0)
    return Status::InvalidArgument(what + ": " + std::to_string(m.vertices.size()) +
                                   " vertex coordinates, not a multiple of 3");
  if (m.triangles.size() % 3 != 0)
    return Status::InvalidArgument(what + ": " + std::to_string(m.triangles.size()) +
                                   " triangle indices, not a multiple of 3");
  if (m.triangles.empty()) return Status::InvalidArgument(what + ": no triangle");
  for (size_t i = 0; i < m.vertices.size(); ++i) {
    const double c = m.vertices[i];
    if (!std::isfinite(c) || std::fabs(c) > kMaxCoordinate)
      return Status::InvalidArgument(what + ": vertex " + std::to_string(i / 3) + " has coordinate " +
                                     std::to_string(c) + ": not finite or beyond kMaxCoordinate");
  }
  const size_t vertex_count = m.vertex_count();
  for (size_t i = 0; i < m.triangles.size(); ++i) {
    if (m.triangles[i] >= vertex_count)
      return Status::InvalidArgument(what + ": triangle " + std::to_string(i / 3) + " refers to vertex " +
                                     std::to_string(m.triangles[i]) + " of " + std::to_string(vertex_count));
  }
  return Status::Ok();
}

}  // namespace mktree
