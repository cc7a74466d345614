// The point of a mesh nearest a query point, and the distance from a point to a box: the exact part of a
// nearest query (engine/query/nearest_search.h).
//
// The surface is the union of the closed triangles (zero-area ones are their segments or points); the
// distance is computed in double precision from the given vertices (PointTriangleClosest), the minimum
// over all triangles: by a scan that skips triangles whose box is no nearer than the best point (one query
// never repays building a hierarchy), or by a walk of a TriangleHierarchy the caller keeps. Whether a point
// inside a closed solid is at distance 0 is the caller's decision (SolidClassifier::Contains): this measures
// the surface only.
//
// Thread-safety: pure functions.
#pragma once

#include <limits>

#include "engine/geometry/triangle_hierarchy.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

struct SurfacePoint {
  double distance_squared = std::numeric_limits<double>::infinity();  // +inf: none within the bound
  Vec3d point;  // the nearest point of the surface (valid when distance_squared is finite)
};

// The point of the mesh's surface nearest p, if it is at squared distance <= bound_squared (the nearest
// of several at the same distance: the first in triangle order). REQUIRES: every triangle
// index < vertex_count().
SurfacePoint ClosestOnSurface(const Mesh& mesh, const Vec3d& p,
                              double bound_squared = std::numeric_limits<double>::infinity());
// The same through a hierarchy over the mesh's triangles.
SurfacePoint ClosestOnSurface(const TriangleHierarchy& hierarchy, const Vec3d& p,
                              double bound_squared = std::numeric_limits<double>::infinity());

// Squared distance from p to the closed box (0 inside; +inf for an empty box).
double BoxPointDistanceSquared(const Box3d& box, const Vec3d& p);

}  // namespace mktree
