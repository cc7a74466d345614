// A bounding-volume hierarchy over one mesh's triangles: a binary tree of axis-aligned boxes in a flat
// array, built top-down by median splits of the triangle centroids on the longest axis (O(T log T)),
// leaves of at most kLeafTriangles triangles. The triangles are kept in leaf order as their mesh indices,
// and the corners read from the mesh (a copy of the corners' coordinates would take 72 bytes a triangle,
// of their vertex indices 12).
//
// Queries between two hierarchies walk pairs of nodes (a dual traversal), descending the larger box:
//   - FindMeeting: the first triangle pair that meets (exact TrianglesMeet), pruning node pairs whose
//     boxes are disjoint;
//   - ClosestBelow: the closest triangle pair at distance < a bound, pruning node pairs whose box distance
//     is >= the best found so far (the nearer child pair is visited first);
//   - PointDistanceSquared: the squared distance from a point to the surface.
//
// Thread-safety: immutable after construction; queries may run concurrently.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/geometry/triangle_pair.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

class TriangleHierarchy {
 public:
  static constexpr uint32_t kLeafTriangles = 4;

  // REQUIRES: every triangle index < mesh.vertex_count(); the mesh's vertices outlive the hierarchy
  // unchanged (it reads them).
  explicit TriangleHierarchy(const Mesh& mesh);
  // The hierarchy of `moved`, a copy of base's mesh with every vertex coordinate plus shift (each sum
  // rounded): base's tree with its boxes shifted the same way. Rounded addition is monotonic, so the
  // shifted boxes still hold the moved corners. REQUIRES: moved's triangles are base's mesh's.
  TriangleHierarchy(const TriangleHierarchy& base, const Mesh& moved, const Vec3d& shift);

  using Triangle = std::array<Vec3d, 3>;
  struct Node {
    Box3d box;
    uint32_t first = 0;  // leaf: first triangle (leaf order); inner: index of the left child (right: +1)
    uint32_t count = 0;  // leaf: number of triangles (> 0); inner: 0
    bool leaf() const { return count != 0; }
  };

  size_t triangle_count() const { return mesh_index_.size(); }
  const std::vector<Node>& nodes() const { return nodes_; }
  Triangle triangle(uint32_t i) const {  // leaf order
    const uint32_t* c = triangles_ + 3 * size_t{mesh_index_[i]};
    return {At(c[0]), At(c[1]), At(c[2])};
  }
  uint32_t mesh_triangle(uint32_t i) const { return mesh_index_[i]; }  // its index in the mesh
  Box3d bounds() const { return nodes_.empty() ? Box3d{} : nodes_[0].box; }
  size_t MemoryBytes() const;

  struct Pair {
    uint32_t a = 0, b = 0;  // leaf-order triangle indices
  };
  // A meeting triangle pair, or false. `tests` (may be null) counts exact triangle tests.
  static bool FindMeeting(const TriangleHierarchy& a, const TriangleHierarchy& b, Pair* found,
                          uint64_t* tests);
  // The same for a's mesh with every vertex coordinate plus `shift` (each sum rounded, as in a moved copy),
  // without making the copy: for trying translations.
  static bool FindMeetingMoved(const TriangleHierarchy& a, const Vec3d& shift, const TriangleHierarchy& b,
                               uint64_t* tests);

  // The closest triangle pair at distance < `bound` (> 0), or false when every pair is at >= bound.
  // REQUIRES: no triangle pair meets (the exact meeting test is skipped). `tests` counts distance tests.
  static bool ClosestBelow(const TriangleHierarchy& a, const TriangleHierarchy& b, double bound,
                           ClosestPoints* closest, uint64_t* tests);

  // Squared distance from p to the closest triangle (+infinity for an empty mesh). With `enough` > 0 it
  // may stop at any value <= enough once one is found (for callers that only need "more than enough?").
  double PointDistanceSquared(const Vec3d& p, double enough = 0) const;

  // Appends to `t` the parameters s in (0, 1) where the segment p + s (q - p) crosses a triangle's plane
  // inside the triangle (double precision, not exact: for sampling points, not for decisions).
  void SegmentCrossings(const Vec3d& p, const Vec3d& q, std::vector<double>* t) const;

 private:
  void Build(uint32_t self, uint32_t first, uint32_t count, const std::vector<double>& centroids);

  std::vector<Node> nodes_;
  Vec3d At(uint32_t v) const {
    const double* p = vertices_ + 3 * size_t{v};
    return {p[0], p[1], p[2]};
  }
  const double* vertices_;
  const uint32_t* triangles_;
  std::vector<uint32_t> mesh_index_;  // leaf order
};

// Squared distance between two boxes (0 when they meet).
double BoxDistanceSquared(const Box3d& a, const Box3d& b);

// Do the closed boxes share a point?
inline bool BoxesMeet(const Box3d& a, const Box3d& b) {
  for (int k = 0; k < 3; ++k)
    if (a.max[k] < b.min[k] || b.max[k] < a.min[k]) return false;
  return true;
}

inline Box3d TriangleBox(const TriangleHierarchy::Triangle& t) {
  Box3d b;
  for (const Vec3d& v : t) b.Extend(v.x, v.y, v.z);
  return b;
}

}  // namespace mktree
