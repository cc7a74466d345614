// The scene model: an object is an id (0-based input order), a name and a closed triangle mesh.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mktree/geometry.h"

namespace mktree {

using ObjectId = uint32_t;

// The largest coordinate magnitude a scene may hold (about 2.1e37): every offset a store keeps (a vertex
// from the store's origin, or from its object's box) then fits float32. Readers refuse larger ones,
// naming the file and line.
inline constexpr double kMaxCoordinate = 0x1p124;

// Triangle mesh: double-precision vertices (x, y, z interleaved), uint32 triangles (three vertex indices
// each). Readers give world coordinates at the precision of their input; a mesh decoded from a store is in
// the store's frame (world minus the store's origin, see engine/store_format/object_codec.h).
struct Mesh {
  std::vector<double> vertices;     // 3 * vertex_count()
  std::vector<uint32_t> triangles;  // 3 * triangle_count()
  size_t vertex_count() const { return vertices.size() / 3; }
  size_t triangle_count() const { return triangles.size() / 3; }
  // Bounds of the vertices, computed in double precision. Empty box for an empty mesh.
  Box3d Bounds() const;
  // Bytes of the raw (uncompressed) geometry encoding in a leaf entry: the two counts, float32 vertices
  // (in the object's local frame) and triangles.
  uint64_t RawGeometryBytes() const { return 8 + 4 * vertices.size() + 4 * triangles.size(); }
};

// What the input says about an object besides its geometry: an OBJ group, a glTF or assimp node's
// metadata, an IFC entity's GlobalId or type. Keys and values are any bytes; a key may repeat.
struct ObjectAttribute {
  std::string key;
  std::string value;
  bool operator==(const ObjectAttribute&) const = default;
};

struct SceneObject {
  ObjectId id = 0;
  std::string name;
  // The input file the object came from, as the reader was given it (empty for generated objects).
  std::string source;
  std::vector<ObjectAttribute> attributes;
  Mesh mesh;
  // Internal: how the mesh was judged (closed, even edges) when the object was first stored, so that a
  // store rebuilt from stored objects (a merge of changes, a compaction) keeps the judgement made on the
  // input's coordinates, not one made on float32-rounded ones. 0: judged from `mesh`; builds from callers'
  // objects ignore it.
  uint8_t stored_shape = 0;
  // Internal: the object's leaf entry as a store holds it, for a compaction that copies entries rather than
  // encoding meshes again (`mesh` is then empty); builds from callers' objects ignore it.
  std::vector<uint8_t> stored_entry;
  // Bounds() rounded outward to float32, in world coordinates (a store keeps boxes in its own frame).
  Box3f Aabb() const { return RoundOutward(mesh.Bounds()); }
};

}  // namespace mktree
