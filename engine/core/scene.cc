#include "mktree/scene.h"

namespace mktree {

Box3d Mesh::Bounds() const {
  Box3d b;
  for (size_t i = 0; i + 2 < vertices.size(); i += 3) b.Extend(vertices[i], vertices[i + 1], vertices[i + 2]);
  return b;
}

}  // namespace mktree
