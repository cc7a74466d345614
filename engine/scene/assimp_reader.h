// Scene reader for every format the Open Asset Import Library (assimp) reads: glTF/GLB, PLY, STL, OFF,
// AC3D, FBX, 3DS, Collada, ...
//
// What it produces
//   - One object per node of the node graph that holds triangle geometry, in depth-first pre-order (a
//     node before its children, children in file order). All triangle meshes a node references are merged
//     into that node's object: importers split one modelling object into several meshes per material (and
//     AC3D per back-face-culling flag, SortByPType per primitive type), so the node, not the mesh, is the
//     object the file's author made. A mesh referenced by several nodes gives one object per node.
//   - The world transform (the product of the node's and its ancestors' transforms, in double precision)
//     is applied to the vertices. Debian's assimp holds coordinates and transforms in float32, so objects
//     far from 0 for their size (UTM-sized coordinates) have lost detail before mktree sees them: such
//     objects are counted and reported as a warning (SceneSource::TakeWarnings) naming the worst.
//   - Line and point primitives (e.g. AC3D SURF type 1/2 line surfaces) are dropped; a node left without
//     triangles gives no object and consumes no id. Polygons are triangulated by assimp (ear clipping,
//     which omits zero-area ears, so a polygon with collinear vertices may give fewer than n - 2 triangles).
//   - Each mesh holds only the vertices its triangles use; assimp joins identical positions within a
//     source mesh (normals, colours and texture coordinates are removed first, so only positions count).
//   - Names: the node's name, or "object_<id>" when the node has none.
//
// Memory: assimp loads the whole file into RAM when the source is opened (the scene stays resident until
// the source is destroyed); objects are then converted one at a time. Use the OBJ reader for scenes that do
// not fit in memory.
//
// Errors: a missing file is NotFound; a file assimp cannot read (unknown format, malformed) is Corruption
// carrying assimp's message. AC3D, OFF, PLY and glTF files are checked before assimp sees them
// (assimp_input_checks.h: the malformed files assimp reads silently wrong or crashes on are refused,
// naming file and line). The imported scene is validated before any post-processing step: a non-finite
// vertex, an index out of range or nodes nested deeper than kMaxNodeDepth are Corruption; so is a
// coordinate that is not finite after the transform (naming the node). Every message names the file.
// assimp runs on a thread with a 512 MiB stack (address space), so that formats without a check of their
// own do not overflow the caller's stack on deeply nested files.
//
// Thread-safety: a source is used by one thread at a time; distinct sources are independent.
#pragma once

#include <memory>
#include <string>

#include "engine/scene/scene_source.h"

namespace mktree {

// Loads `path` with assimp. The first object gets id `first_id`, the next first_id + 1, and so on.
Result<std::unique_ptr<SceneSource>> OpenAssimpFile(const std::string& path, ObjectId first_id = 0);

}  // namespace mktree
