// A ray against triangles, boxes and meshes: the exact part of a ray query (engine/query/ray_search.h).
//
// Whether the ray's line passes through a triangle is decided by exact signs (Orient3dSign of the line's
// two points and each directed edge, the Plücker side test): a line through a shared edge or vertex gets
// a zero sign there, and every triangle around that edge or vertex counts it as passing through, so a ray
// never slips between the triangles of a mesh (watertight). A mesh answers its first hit only, so such
// a ray hits the object once. Where along the ray (t, the point) is computed in double precision from the
// triangle's plane. A line lying in a triangle's plane (all three signs zero) meets it where its projection
// enters the triangle (2D clipping, double precision). Zero-area triangles are never hit: their edges are
// other triangles' edges in any mesh with area.
//
// t is the distance along the ray from its origin in scene units (the direction is normalised); the hit
// point is origin + t * direction; the normal is the triangle's unit normal as its corners turn
// (right-hand rule), not flipped toward the ray.
//
// Thread-safety: pure functions; a Ray is immutable.
#pragma once

#include <limits>

#include "engine/geometry/triangle_hierarchy.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

class PreparedRay {
 public:
  // REQUIRES: finite origin, finite non-zero direction (it is normalised here).
  PreparedRay(const Vec3d& origin, const Vec3d& direction);
  const Vec3d& origin() const { return origin_; }
  const Vec3d& direction() const { return dir_; }  // unit length
  // A second point of the line, origin + direction * (1 + |origin|): distinct from the origin even far from
  // 0.
  const Vec3d& far_point() const { return far_; }
  Vec3d At(double t) const {
    return {origin_.x + t * dir_.x, origin_.y + t * dir_.y, origin_.z + t * dir_.z};
  }

 private:
  Vec3d origin_, dir_, far_;
};

struct RayHit3 {
  double t = std::numeric_limits<double>::infinity();
  Vec3d point;
  Vec3d normal;
  bool hit() const { return t != std::numeric_limits<double>::infinity(); }
};

// The first point of the closed triangle abc on the ray at t in [0, max_t], if any.
bool RayTriangle(const PreparedRay& ray, const Vec3d& a, const Vec3d& b, const Vec3d& c, double max_t,
                 RayHit3* hit);

// The interval of t in [0, max_t] where the ray is in the closed box, widened by a few ulps so that it
// holds every hit of what the box contains: *enter is its start. False when it is empty (or the box is).
bool RayBoxEnter(const PreparedRay& ray, const Box3d& box, double max_t, double* enter);

// The mesh's first hit at t in [0, max_t] (of several at the same t, the first in triangle order); none:
// hit() is false. A scan, each triangle's box slab-tested before its exact signs (one query never repays
// building a hierarchy); the second form walks a TriangleHierarchy the caller keeps.
RayHit3 FirstHit(const Mesh& mesh, const PreparedRay& ray, double max_t);
RayHit3 FirstHit(const TriangleHierarchy& hierarchy, const PreparedRay& ray, double max_t);

}  // namespace mktree
