// Closedness of a triangle mesh, decided on vertex positions: vertices with equal coordinates are the
// same point, so a triangle soup (binary STL, one vertex per corner) is judged like its welded form.
// Triangles with two equal corners (after welding) have no area and are ignored.
//
// Cost: vertices are welded through a hash table (O(V)); edge uses are counted in a hash table up to
// a threshold of triangles (O(T)) and sorted once above (O(T log T)); bench/README.md has its cost.
// Ingest computes it for every object and stores it. At query time pass the stored result to SolidClassifier
// (SolidClassifierOptions::edges) rather than recomputing it.
//
// Thread-safety: pure functions (scratch buffers are per thread).
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
