// Narrow phase of clash detection: how two objects' triangle meshes meet, or how far apart they are.
//
// The separation s(A, B) of two objects (docs/clash.md):
//   s > 0   the solids are apart; s is the Euclidean gap between them (the smallest distance between
//           their surfaces), exact up to double rounding of the stored float32 vertices.
//   s <= 0  they meet: surfaces cross or touch (closed triangles share a point), or one solid is wholly
//           inside the other (no triangles cross; found by point-in-solid). -s is an upper bound on the
//           penetration depth, the length of the shortest translation that separates the solids.
// Objects whose mesh is not closed (some edge not used by exactly two triangles) are surfaces: they meet
// what their triangles meet, and nothing is inside them (a surface lying inside a solid does not meet it).
//
// Method (docs/clash.md section 2): the 26-DOP bounds reject the pair (Kdop::Gap); then any meeting triangle
// pair (exact, engine/geometry/triangle_pair.h) through the triangle hierarchies, or all filtered pairs
// when one mesh is small and the other not large (kBruteForceTriangles, kScanTriangles); then, for two
// solids, one vertex of each connected component against the other's solid (SolidClassifier); then the gap
// (hierarchy distance). Depth bounds of meeting pairs: depth_upper = the smallest overlap of the two objects'
// projection intervals over the 13 26-DOP directions and the face normals of small meshes, depth_lower = the
// largest distance to the other's surface of a point of one solid's surface inside the other solid (vertices,
// and edge points between the other surface's crossings; 0 when none is inside, or when either is a surface),
// clamped to depth_upper. A touch certificate (engine/geometry/touch_certificate.h: a plane weakly
// separating the vertex sets, or a convex piece the other's surface misses) makes both 0, exactly. With a
// finite depth_lower_enough, a pair still undecided gets the translation certificate: a translation no
// longer than it after which the two meet nowhere bounds depth_upper (docs/clash.md section 2).
//
// Thread-safety: a ClashShape may be shared by threads; its lazily built parts are built once
// (std::call_once) and the same whichever thread builds them. Separate is a pure function of its
// arguments.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>

#include "engine/geometry/kdop.h"
#include "engine/geometry/mesh_edges.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

struct NarrowStats {
  uint64_t bound_rejects = 0;      // pairs decided apart by the per-object bounds, before any triangle
  uint64_t triangle_tests = 0;     // triangle-triangle intersection and distance tests
  uint64_t containment_tests = 0;  // point-in-solid tests
  // ClashShape parts built on first use by these calls (each shape builds each part once).
  uint64_t hierarchies_built = 0;
  uint64_t classifiers_built = 0;
  void Add(const NarrowStats& o) {
    bound_rejects += o.bound_rejects;
    triangle_tests += o.triangle_tests;
    containment_tests += o.containment_tests;
    hierarchies_built += o.hierarchies_built;
    classifiers_built += o.classifiers_built;
  }
};

// One object prepared for the narrow phase: its mesh, its tight bound (cheap rejection before any
// triangle), a hierarchy over its triangles and its point-in-solid classifier, built once, the last two
// on the first pair that needs them, and used for every pair the object is in. Both shapes of a pair must be
// in the same frame (a store's frame).
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
  // The 26-DOP of the vertices (the bound Separate rejects with).
  const Kdop& kdop() const;
  // Heap bytes held by what is built so far (hierarchy, classifier, vertex lists, directions), for
  // caches that budget their memory. Not while a Separate on this shape runs on another thread.
  size_t MemoryBytes() const;
  // Which lazily built parts exist (the constructor builds only the bound; Separate the rest on first
  // use).
  struct Built {
    bool hierarchy = false;
    bool classifier = false;
  };
  Built built() const;

  struct Impl;
  const Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

enum class Meeting : uint8_t {
  kApart,         // s > 0
  kSurfacesMeet,  // some triangle of A meets some triangle of B (crossing, touching or coplanar overlap)
  kAInsideB,      // no triangles meet; A's solid (or a component of it) lies wholly inside B's
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

// One mesh at most kBruteForceTriangles triangles and the other at most kScanTriangles: Separate tests all
// pairs of triangles whose boxes meet the other mesh's box, straight on the meshes, instead of building and
// walking the hierarchies.
inline constexpr size_t kBruteForceTriangles = 32;
inline constexpr size_t kScanTriangles = 256;

// Meshes with at most this many triangles and vertices keep up to kMaxDepthDirections distinct face
// normals as extra directions for depth_upper (each costs a pass over the other mesh's vertices).
inline constexpr size_t kMaxDepthDirectionTriangles = 512;
inline constexpr size_t kMaxDepthDirectionVertices = 1024;
inline constexpr size_t kMaxDepthDirections = 64;

// OK when ClashShape's preconditions hold (finite vertices, indices in range, whole triangles); else
// InvalidArgument naming the first bad vertex or triangle (the caller adds the file or object name).
Status ValidateClashMesh(const Mesh& mesh);

// The separation of `a` and `b`. The gap of pairs apart is computed only when it is < `max_distance`
// (the clearance C; 0 asks only whether they meet); pairs farther report +infinity. `stats` may be null.
Separation Separate(const ClashShape& a, const ClashShape& b, double max_distance, NarrowStats* stats);

// Options; the defaults are what Separate above uses. The first two exist for measurements
// (bench/narrow_bench.cc); the clash traversal should pass depth_lower_enough = T.
struct SeparateOptions {
  int bound_directions = kKdopDirections;  // 3: AABB, 9: 18-DOP, 13: 26-DOP (the rejection test only)
  size_t brute_force_triangles = kBruteForceTriangles;
  // Stop raising depth_lower once it exceeds this: a caller that only needs to know whether the depth
  // exceeds the touch tolerance T passes T (the pair is then hard, and the search for deeper points,
  // the costliest part of a meeting pair, ends). depth_lower is then still a valid lower bound, but may
  // depend on the order of the arguments. A pair whose bounds straddle it tries the translation
  // certificate, which may lower depth_upper to at most this (also depending on the order).
  double depth_lower_enough = std::numeric_limits<double>::infinity();
};
Separation Separate(const ClashShape& a, const ClashShape& b, double max_distance, NarrowStats* stats,
                    const SeparateOptions& options);

}  // namespace mktree
