// Exact-mode geometry of one object: is a point in its closed solid, does a box meet it.
//
// Method for closed meshes: ray parity along +x with exact predicates and simulation of simplicity.
//   The ray from p is cast along +x; a triangle is crossed when p's (y, z) lies in the triangle's
//   projection onto the yz plane and the crossing is ahead of p. Both decisions use exact signs
//   (Orient2dSign, Orient3dSign: a float filter, exact expansions when it is unsure), and a ray that
//   grazes an edge or a vertex is decided as for the ray from p + (0, e, e^2), e -> 0: a projected edge
//   that passes exactly through p's (y, z) counts p on the side that perturbation puts it. Every
//   triangle sharing an edge agrees on that side, so the parity is exactly that of a generic ray: no
//   random directions, no votes, no epsilon in the crossing test. Faces parallel to the ray (common in
//   CAD: axis-aligned walls) have a zero-area projection and are never crossed, which is also what the
//   perturbation says. Why parity rather than the winding number for closed meshes: it is exact, it
//   needs only an even edge count (tolerates non-manifold edges and flipped triangles), and it is cheap
//   (most triangles are rejected by two float comparisons; with the grid below a query tests a
//   handful of triangles).
//
// Method for meshes that are not closed (some edge used an odd number of times, e.g. the open Stanford
//   bunny): the generalized winding number w(p) = sum of signed solid angles / 4 pi (Jacobson et al.
//   2013). Inside iff |w(p)| >= 1/2. For a closed mesh this is the usual inside; for a mesh with small
//   holes it is the solid a user sees, with the holes "patched" smoothly (a point in the bunny's body has
//   w ~ 1, a point outside w ~ 0); an open sheet (a single plate face) encloses nothing (|w| < 1/2 off
//   the sheet) so only contact with the surface counts. |w| rather than w makes inverted orientation
//   irrelevant. Cost: one atan2 per triangle per query, no acceleration (bench/README.md).
//
// Surface contact (both methods): a point within `tolerance()` of a triangle is on the surface and
//   therefore inside (closed solid). tolerance = 1e-9 x bounding-box diagonal + 4 ulp(largest
//   coordinate): far below the float32 resolution of stored vertices (6e-8 of an object's size), far
//   above double rounding. Points farther than that from the surface are classified exactly (parity) or by
//   |w| (open meshes; w is accurate there because each solid angle is computed from vectors of length > tol).
//
// Boxes: MeetsBox(box) = some triangle meets the closed box (TriangleMeetsBox), or Contains(a corner of
//   the box). One point suffices: if no triangle meets the box, the box (connected) lies in one
//   connected component of space minus the surface, and parity (and w) is constant on such a
//   component, so every point of the box has the corner's answer. Using Contains for the corner makes a
//   zero-size box {p} answer exactly as the point query p.
//
// Thread-safety: a SolidClassifier is immutable after construction; Contains and MeetsBox may run
// concurrently. It keeps a reference to the mesh. REQUIRES: the mesh outlives the classifier and every
// triangle index is < vertex_count().
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "engine/geometry/mesh_edges.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

struct SolidClassifierOptions {
  // Queries the caller expects to run on this classifier. A yz grid over the triangles (O(T) to build)
  // is built only when it pays off; one brute-force parity query costs
  // about what building the grid costs / kGridBreakEven.
  size_t expected_queries = 1;
  // The mesh's edge check, if known (store it per object at ingest); computed (O(T log T)) otherwise.
  std::optional<EdgeCheck> edges;
};

class SolidClassifier {
 public:
  enum class Method { kRayParity, kWindingNumber };

  explicit SolidClassifier(const Mesh& mesh, const SolidClassifierOptions& options = {});

  // Is p in the closed solid (on the surface within tolerance() counts as inside)?
  bool Contains(const Vec3d& p) const;
  // Does the closed box meet the closed solid? An empty box meets nothing.
  bool MeetsBox(const Box3d& box) const;

  Method method() const { return method_; }
  double tolerance() const { return tol_; }
  bool has_grid() const { return !cell_start_.empty(); }
  // Heap bytes held (the grid).
  size_t MemoryBytes() const { return (cell_start_.capacity() + cell_tris_.capacity()) * sizeof(uint32_t); }

 private:
  struct CellRange {
    int y0, y1, z0, z1;
  };
  void BuildGrid();
  int CellY(double y) const;
  int CellZ(double z) const;
  bool ParityContains(const Vec3d& p) const;
  bool WindingContains(const Vec3d& p) const;
  bool SomeTriangleMeets(const Box3d& box) const;

  const Mesh& mesh_;
  Method method_;
  double tol_ = 0;
  Box3d reach_;  // mesh bounds grown by tol_: nothing outside it is inside

  // yz grid (parity only): triangles binned by their yz bounds grown by tol_, in CSR form.
  int ny_ = 0, nz_ = 0;
  double y0_ = 0, z0_ = 0, inv_cy_ = 0, inv_cz_ = 0;
  std::vector<uint32_t> cell_start_;  // ny_ * nz_ + 1 offsets into cell_tris_
  std::vector<uint32_t> cell_tris_;
};

// Grid pays off when expected_queries >= this: building the grid costs a handful to a few tens of
// brute-force parity queries, and a grid query far less than one (bench/README.md).
inline constexpr size_t kGridBreakEven = 8;
// Below this many triangles a brute-force query is as fast as a grid lookup.
inline constexpr size_t kGridMinTriangles = 256;

// The surface tolerance used for a mesh with these bounds (see above).
double SurfaceTolerance(const Box3d& bounds);

// Squared Euclidean distance from p to the closed triangle abc; zero-area triangles are segments
// (or points). Slivers thinner than 1e-10 x their longest edge are measured as their edges.
double PointTriangleDistanceSquared(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c);

// Generalized winding number of the mesh at p (sum of signed solid angles / 4 pi): +-1 inside and 0
// outside a closed oriented mesh; fractional for open meshes. Undefined on the surface.
double WindingNumber(const Mesh& mesh, const Vec3d& p);

// One-shot forms. PointInSolid builds a classifier (including the O(T log T) edge check); for repeated
// queries or when the edge check is stored, build a SolidClassifier once.
bool PointInSolid(const Mesh& mesh, const Vec3d& p);
// Tests the triangles first and runs the edge check and the corner classification only when none meets
// the box.
bool MeshMeetsBox(const Mesh& mesh, const Box3d& box);

}  // namespace mktree
