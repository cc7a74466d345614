// Two closed triangles: do they meet (exactly), and how far apart are they (with the closest points).
//
// Meeting is decided by exact orientation predicates only (Orient3dSign, Orient2dSign), so the answer is
// that of the triangles with the given double coordinates, with no tolerance:
//   - closed sets: touching at a vertex, along an edge or face to face counts as meeting;
//   - coplanar triangles are tested in 2D, in a coordinate projection that is one-to-one on their plane;
//   - zero-area triangles are the segments (or points) they are.
// Method: two closed convex sets T1, T2 (triangles, segments or points) meet iff some edge of one meets the
// other (the intersection, when not empty, has a point on the boundary of T1 or of T2, and a degenerate
// triangle is the union of its edges). A plane-side filter (all three corners strictly on one side)
// rejects most pairs with three filtered orientation tests.
//
// Distance: the minimum over the 9 edge-edge pairs and the 6 vertex-face pairs (the vertex's projection
// when it falls inside the face), in double precision; 0 when the triangles meet (exact test first).
//
// Thread-safety: pure functions.
#pragma once

#include "mktree/geometry.h"

namespace mktree {

// Do the closed triangles (a0, a1, a2) and (b0, b1, b2) share a point? Exact.
bool TrianglesMeet(const Vec3d a[3], const Vec3d b[3]);

// Does the closed segment pq meet the closed triangle abc (possibly zero-area)? Exact.
bool SegmentMeetsTriangle(const Vec3d& p, const Vec3d& q, const Vec3d& a, const Vec3d& b, const Vec3d& c);

// Do the closed segments pq and rs (possibly points) share a point? Exact.
bool SegmentsMeet(const Vec3d& p, const Vec3d& q, const Vec3d& r, const Vec3d& s);

struct ClosestPoints {
  double distance_squared = 0;
  Vec3d on_a;  // the closest point of the first set
  Vec3d on_b;  // ... and of the second
};

// Closest points of the closed segments pq and rs (points allowed).
ClosestPoints SegmentSegmentClosest(const Vec3d& p, const Vec3d& q, const Vec3d& r, const Vec3d& s);

// The closest point of the closed triangle abc (zero-area allowed) to p; on_a is p.
ClosestPoints PointTriangleClosest(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c);

// Distance between two closed triangles with the closest points. When they meet (TrianglesMeet) the
// distance is 0 and on_a == on_b is a common point (approximate: within rounding of the triangles).
ClosestPoints TriangleTriangleClosest(const Vec3d a[3], const Vec3d b[3]);

// The minimum over the 9 edge-edge and 6 vertex-face candidates, without the meeting test: the distance
// when the triangles do not meet (for triangles that cross it can exceed 0).
ClosestPoints TriangleFeatureClosest(const Vec3d a[3], const Vec3d b[3]);

}  // namespace mktree
