// Checks of a scene file made before assimp reads it, for the formats whose assimp importer (5.2) reads
// malformed files silently wrong or crashes on them. Each check streams the file once in bounded memory
// and accepts exactly the files that assimp reads as the file says; anything else is a Corruption error
// naming the file and line. What they refuse, and why:
//
//   AC3D: nesting deeper than kMaxNodeDepth (assimp recurses once per level: about 10,000 levels
//     overflow the stack); counts that are missing, negative, not decimal or not followed by as many
//     lines as they announce (assimp reads "-3" as 0, stops a vertex list early at a line it does not
//     take for a number, and then drops the object or shifts what follows); vertex references out of
//     range (assimp replaces them with vertex 0); unknown surface types (read as polygons); triangle
//     strips and lines with too few references (an unsigned underflow: a crash); a second top-level
//     object, OBJECT/SURF/mat/refs lines where assimp ignores them, lines of only spaces (they end an
//     object early), unquoted names (read as "ERROR"), subdivision deeper than kMaxAc3dSubdivision.
//   OFF: everything assimp's OFF reader gets wrong: missing or short counts, fewer vertex or face lines
//     than announced (zero vertices, empty faces), indices out of range (replaced by the last vertex) or
//     not decimal, faces of 0 or more than 9 vertices (dropped), comment or blank-looking lines inside
//     the face list (they drop faces at the end), lines of 4096 bytes or more (cut), a missing header
//     keyword, nOFF, non-finite coordinates, and anything after the last face.
//   glTF/GLB: JSON nested deeper than kMaxJsonDepth (assimp's JSON parser recurses per level) and node
//     hierarchies deeper than kMaxNodeDepth (its importer recurses per node level).
//   PLY: element data shorter or longer than the header declares (assimp reads a short file as a
//     shorter scene, and a list longer than its line as zero indices).
//
// Formats without a check (FBX, 3DS, Collada, ...) are read by assimp on a thread with a large stack and
// validated after import (assimp_reader.cc).
#pragma once

#include <cstdint>
#include <string>

#include "mktree/status.h"

namespace mktree {

// Node levels a scene may have, in the file and in the imported scene (real scenes have tens).
inline constexpr uint32_t kMaxNodeDepth = 1000;
inline constexpr uint32_t kMaxJsonDepth = 256;
// Catmull-Clark levels an AC3D object may ask for: each one multiplies its faces by 4.
inline constexpr uint32_t kMaxAc3dSubdivision = 4;

Status CheckAc3dFile(const std::string& path);
Status CheckOffFile(const std::string& path);
Status CheckGltfFile(const std::string& path);  // .gltf (JSON) or .glb (binary container)
Status CheckPlyFile(const std::string& path);

// Runs the check of the file's format, chosen by its extension or, failing that, by its first bytes
// (assimp, too, recognises these formats by content); Ok for formats without a check.
Status CheckBeforeAssimp(const std::string& path);

}  // namespace mktree
