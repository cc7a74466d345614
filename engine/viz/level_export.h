// `mktree export`: the level-k colouring (engine/viz/level_colouring.h), or the clashes of a pairs file
// (`clashes`), written as coloured geometry that MeshLab, Blender and glTF viewers open.
//
//   PLY (.ply): binary little-endian; one vertex list (float x, y, z; uchar red, green, blue) and one face
//     list (uchar count, uint indices); each object's vertices carry its group colour. Streamed: vertices
//     go straight to the file, faces to a scratch file appended at the end, and the two counts in the
//     header are fixed-width (zero-padded) so they are patched in place once known.
//   GLB (.glb): glTF 2.0 binary; one mesh (one node) per non-empty group, named after the group, its
//     material's baseColorFactor the group colour (linear); float32 positions, uint32 indices. The binary
//     chunk is spooled per group to scratch files (glTF needs its sizes up front) and assembled at the end.
//   Geometry: each object's mesh, decoded from its leaf entry. Boxes (`boxes`): each object's stored AABB
//     as 8 vertices and 12 triangles. Positions are float32 in the store's frame (world minus the store's
//     origin, engine/store_format/object_codec.h), so that coordinates far from 0 keep their detail; the
//     origin is a PLY comment ("comment origin X Y Z") and the translation of every glTF node.
//
// Memory: one leaf (the store is read leaf by leaf through a page cache holding only the pinned leaf) plus
// a few I/O buffers, whatever the scene size. The output appears only when complete (temporary file and
// rename); on error nothing is left at the output path.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "engine/store_format/store_file.h"
#include "engine/viz/clash_pairs_file.h"
#include "engine/viz/level_colouring.h"
#include "mktree/status.h"

namespace mktree {

enum class ExportFormat { kPly, kGlb };

// By extension (case-insensitive): .ply or .glb; InvalidArgument naming the path otherwise.
Result<ExportFormat> ExportFormatFor(const std::string& path);

struct ExportOptions {
  int level = 0;  // k: colour by the group at the depth-k ancestor (>= 0)
  ExportFormat format = ExportFormat::kPly;
  bool boxes = false;  // AABBs instead of object geometry
  // Optional: colour by clash class instead of the level-k group (`level` is then unused): each object in
  // the colour of its worst class (clash_render.h's ClashColour), one glTF mesh per class ("hard",
  // "touch", "clearance", "no_clash"), and the report's counts indexed by ClashMark. Not owned.
  const ClashMarks* clashes = nullptr;
  // Optional: (leaves done, leaves total).
  std::function<void(uint64_t, uint64_t)> progress;
};

struct ExportReport {
  GroupCounts objects{};  // per group (GroupIndex), or per ClashMark with `clashes`
  GroupCounts vertices{};
  GroupCounts triangles{};
  uint64_t bytes = 0;  // size of the written file
  uint64_t total_objects() const { return objects[0] + objects[1] + objects[2] + objects[3]; }
  uint64_t total_vertices() const { return vertices[0] + vertices[1] + vertices[2] + vertices[3]; }
  uint64_t total_triangles() const { return triangles[0] + triangles[1] + triangles[2] + triangles[3]; }
};

// Writes the level-`options.level` colouring of `store` to `out_path`.
Result<ExportReport> ExportLevel(const StoreReader& store, const std::string& out_path,
                                 const ExportOptions& options);

// The 8 corners and 12 triangles (outward) of a box, as exported with `boxes`.
void BoxCorners(const Box3f& box, float out[24]);
extern const uint32_t kBoxTriangles[36];

}  // namespace mktree
