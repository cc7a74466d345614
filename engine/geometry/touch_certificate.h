// Touch certificate: a proof that two meeting objects only touch (penetration depth 0), or a small depth
// upper bound along a plane the other bounds do not try (docs/clash.md section 2, depth).
//
// Plane: if some plane weakly separates the vertex sets (all of A's vertices on one closed side, all of
// B's on the other), each object lies in its closed half-space (a triangle is in the hull of its corners),
// so the interiors are disjoint and the depth is 0. The sides are decided exactly (Orient3dSign on the
// stored doubles for a triangle's plane, an exact sum for a 26-DOP direction): a proof for the geometry as
// stored. Candidates, each one pass over both vertex sets: the planes of the meeting triangle pair the
// caller found and the 26-DOP directions on which the two bounds only touch (stage kCheap); the planes of
// more meeting triangles from a bounded dual traversal of the two hierarchies (kSearch). The smallest
// projection overlap on a candidate's normal (rounded up) is also a depth upper bound (moving one object
// that far along the normal separates them).
//
// Convex piece (kSearch, two solids): non-convex contacts (a plate in the corner of an angle, a cleat
// between flanges) have no separating plane. When one solid X is convex (every facet plane has all of X's
// vertices on one closed side, checked exactly) and each triangle of the other, Y, whose box reaches into
// X's box lies on the outer closed side of some facet plane of X, Y's surface misses X's (convex, so
// connected) interior, which is then wholly inside Y or wholly outside; a point strictly inside every
// facet that Y's classifier puts outside (it counts points near the surface as inside) decides it.
//
// Not decided: contacts that cross by rounding once stored (float32 vertices in different local frames),
// curved or non-convex pieces on both sides, anything past the budget. Those keep the other bounds.
//
// Thread-safety: pure functions.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>

#include "engine/geometry/kdop.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/geometry/triangle_hierarchy.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

// One object as the certificate reads it. `projection_slack` bounds the rounding of a projection of one of
// its vertices onto a unit vector (ClashShape keeps it).
struct TouchObject {
  const Mesh* mesh = nullptr;
  const TriangleHierarchy* hierarchy = nullptr;
  const Kdop* kdop = nullptr;
  double projection_slack = 0;
  const SolidClassifier* classifier = nullptr;  // solids only (closed meshes); null for a surface
};

struct TouchBudget {
  size_t triangle_tests = 256;   // exact triangle tests of the traversal collecting meeting triangles
  size_t meeting_pairs = 16;     // meeting triangle pairs collected
  size_t planes = 8;             // triangle planes tried (the 26-DOP directions come on top, at most 13)
  size_t convex_triangles = 64;  // convex piece test: the smaller solid at most this many triangles
  size_t convex_checks = 4096;   // and at most this many of the other's triangles checked against it
  // A plane's projection overlap above this is of no use (the caller's touch threshold): its pass over
  // the larger vertex set may stop early. Infinite: every overlap is computed.
  double useful_overlap = std::numeric_limits<double>::infinity();
};

struct TouchResult {
  bool separated = false;  // some plane weakly separates the vertex sets exactly: the depth is 0
  // The smallest projection overlap over the candidate planes' normals, rounded up (a depth upper bound);
  // 0 when separated, +infinity when no plane was tried.
  double depth_upper = std::numeric_limits<double>::infinity();
  uint64_t triangle_tests = 0;
  uint64_t planes_tried = 0;
};

// kCheap: the planes of `ta` and `tb` and the 26-DOP directions (one pass over both vertex sets each);
// kSearch: the planes of more meeting triangles, then the convex piece test (costlier:
// for pairs no vertex of which is inside the other).
enum class TouchStage : uint8_t { kCheap, kSearch };

// `ta`, `tb` (may be null): the corners of a meeting triangle of a and of b, tried first.
// REQUIRES: a and b meet (closed triangles share a point); both are in the same frame.
TouchResult FindTouchCertificate(const TouchObject& a, const TouchObject& b, const Vec3d* ta, const Vec3d* tb,
                                 TouchStage stage, const TouchBudget& budget = TouchBudget{});

// Exact sign (-1, 0, +1) of d . (v - p) for a direction d with components in {-1, 0, 1}.
int DirectionSideSign(const int d[3], const double v[3], const double p[3]);

}  // namespace mktree
