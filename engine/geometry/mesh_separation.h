// Narrow phase of clash detection: how two objects' triangle meshes meet, or how far apart they are.
//
// The separation s(A, B) of two objects (docs/clash.md):
//   s > 0   the solids are apart; s is the Euclidean gap between them (the smallest distance between
//           their surfaces), exact up to double rounding of the stored float32 vertices.
//   s <= 0  they meet: surfaces cross or touch (closed triangles share a point), or one solid is wholly
//           inside the other (no triangles cross; found by point-in-solid). -s is an upper bound on the
//           penetration depth, the length of the shortest translation that separates the solids.
// Objects whose mesh is not closed (some edge not used by exactly two triangles) are surfaces: they meet
// what their triangles meet, and nothing is inside them.
//
// Thread-safety: a ClashShape is immutable after construction and may be shared by threads; Separate is
// a pure function of its arguments.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>

#include "engine/geometry/mesh_edges.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

struct NarrowStats {
  uint64_t bound_rejects = 0;      // pairs decided apart by the per-object bounds, before any triangle
  uint64_t triangle_tests = 0;     // triangle-triangle intersection and distance tests
  uint64_t containment_tests = 0;  // point-in-solid tests
  void Add(const NarrowStats& o) {
    bound_rejects += o.bound_rejects;
    triangle_tests += o.triangle_tests;
    containment_tests += o.containment_tests;
  }
};

// One object prepared for the narrow phase: its mesh, its tight bound (cheap rejection before any
// triangle), a hierarchy over its triangles and its point-in-solid classifier, built once and used for
// every pair the object is in. Both shapes of a pair must be in the same frame (a store's frame).
class ClashShape {
 public:
  // `edges`: the mesh's edge check as stored at ingest (computed when absent). REQUIRES: `mesh` outlives
  // the shape; finite vertices; every triangle index < vertex_count().
  explicit ClashShape(const Mesh& mesh, const std::optional<EdgeCheck>& edges = std::nullopt);
  ~ClashShape();
  ClashShape(ClashShape&&) noexcept;
  ClashShape& operator=(ClashShape&&) noexcept;

  const Mesh& mesh() const;
  // A closed mesh bounds a solid (containment is tested); otherwise the object is a surface.
  bool solid() const;
  Box3d bounds() const;
  // Heap bytes held (hierarchy, bound, classifier), for caches that budget their memory.
  size_t MemoryBytes() const;

  struct Impl;
  const Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

enum class Meeting : uint8_t {
  kApart,         // s > 0
  kSurfacesMeet,  // some triangle of A meets some triangle of B (crossing, touching or coplanar overlap)
  kAInsideB,      // no triangles meet; A's solid is wholly inside B's
  kBInsideA,
};

struct Separation {
  Meeting meeting = Meeting::kApart;
  // s as above. Apart: the gap when it is below the `max_distance` asked, else +infinity (not computed).
  // Meeting: -depth_upper.
  double distance = 0;
  // Meeting: the penetration depth lies in [depth_lower, depth_upper]; equal when known exactly.
  double depth_lower = 0;
  double depth_upper = 0;
  // Apart (gap computed): the closest points of A and of B. Meeting: a point where they meet (both the
  // same: a point common to both surfaces, or a point of the inner solid).
  Vec3d point_a;
  Vec3d point_b;
};

// The separation of `a` and `b`. The gap of pairs apart is computed only when it is < `max_distance`
// (the clearance C; 0 asks only whether they meet); pairs farther report +infinity. `stats` may be null.
Separation Separate(const ClashShape& a, const ClashShape& b, double max_distance, NarrowStats* stats);

}  // namespace mktree
