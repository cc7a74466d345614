// Closedness of a triangle mesh, decided on vertex positions: vertices with equal coordinates are the
// same point, so a triangle soup (binary STL, one vertex per corner) is judged like its welded form.
// Triangles with two equal corners (after welding) have no area and are ignored.
//
// Cost: O(V log V + T log T) (four sorts): measured 23 ms for armadillo (52k triangles), 12 ms for
// fandisk (13k), 22 us for 200 triangles. Cheap at ingest, where the result should be stored per
// object; at query time pass it to SolidClassifier (SolidClassifierOptions::edges): recomputing it
// costs ~50 brute-force point queries.
//
// Thread-safety: pure functions.
#pragma once

#include "mktree/scene.h"

namespace mktree {

struct EdgeCheck {
  // Every undirected edge is used by exactly two triangles, with opposite orientations: a closed,
  // consistently oriented 2-manifold surface (the mesh bounds a solid; what IsClosedMesh reports).
  bool closed = false;
  // Every undirected edge is used an even number of times (orientation ignored). Weaker than `closed`
  // (it admits non-manifold edges and inconsistent orientation) but exactly what ray parity needs to
  // give the same answer for every ray, so SolidClassifier uses parity whenever this holds.
  bool even = false;
  size_t border_edges = 0;  // undirected edges used exactly once
};

EdgeCheck CheckEdges(const Mesh& mesh);

inline bool IsClosedMesh(const Mesh& mesh) { return CheckEdges(mesh).closed; }

}  // namespace mktree
