// Nearest, within-distance and ray queries (docs/nearest_and_ray.md): what is nearest this point and how
// far, what lies within D of this point, box or mesh, what does this ray hit first.
//
//   DistanceQuery   k nearest objects to a point, a box or a mesh (world coordinates), each at most
//                   max_distance away; k = kAll and a finite max_distance is "within distance"
//   NearestHit      an answer: the id, the exact distance to the object's geometry and its closest point
//   NearestCursor   the answer nearest first, one object a call, stoppable and resumable
//   RayQuery        a ray (origin, direction, max_length): its first hit, or every object hit in order
//   RayHit          an answer: the id, t (distance from the origin along the ray), the hit point and the
//                   hit triangle's unit normal
//
// Distances are exact to the stored geometry (float32 vertices, computed in double): 0 inside a closed
// solid (or meeting it); an object that is not closed is a surface, at its surfaces' distance. Answers are
// ordered by distance (t), ties by id. Database (mktree/database.h) runs them: OpenNearest, VisitNearest,
// Nearest, VisitRay, Ray; Query::Nearest and Query::Ray build them.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <utility>

#include "mktree/geometry.h"
#include "mktree/query_stats.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// The k objects nearest a point, a box (a closed solid box) or a mesh (a solid if closed, else a surface),
// in world coordinates, at distance <= max_distance.
// REQUIRES (else InvalidArgument naming the query): finite coordinates, k >= 1, max_distance >= 0 (not
// NaN; +infinity: no limit), min <= max on every axis of a box, a mesh with triangles and valid indices.
struct DistanceQuery {
  enum class Kind { kPoint, kBox, kMesh };
  static constexpr uint64_t kAll = UINT64_MAX;

  Kind kind = Kind::kPoint;
  Vec3d point;  // kPoint
  Box3d box;    // kBox
  Mesh mesh;    // kMesh
  uint64_t k = 1;
  double max_distance = std::numeric_limits<double>::infinity();

  static DistanceQuery Nearest(const Vec3d& p, uint64_t k,
                               double max_distance = std::numeric_limits<double>::infinity()) {
    DistanceQuery q;
    q.point = p;
    q.k = k;
    q.max_distance = max_distance;
    return q;
  }
  // Every object within `distance` of the point, box or mesh.
  static DistanceQuery Within(const Vec3d& p, double distance) { return Nearest(p, kAll, distance); }
  static DistanceQuery WithinBox(const Box3d& b, double distance) {
    DistanceQuery q = Within({}, distance);
    q.kind = Kind::kBox;
    q.box = b;
    return q;
  }
  static DistanceQuery WithinMesh(Mesh m, double distance) {
    DistanceQuery q = Within({}, distance);
    q.kind = Kind::kMesh;
    q.mesh = std::move(m);
    return q;
  }
};

struct NearestHit {
  ObjectId id = 0;
  double distance = 0;  // exact, to the object's solid (closed) or surface
  Vec3d point;          // the object's point at that distance (world); the query point inside a solid
};

// Receives a nearest answer in order; returns false to stop.
using NearestVisitor = std::function<bool(const NearestHit&)>;

// An answer of a DistanceQuery, nearest first, computed as it is asked for: a leaf page is read only when
// its region is nearer than the k-th answer (Next reads only what the next answer needs). Stopping is not
// calling Next again; calling it again resumes where it stopped: the same sequence as a visitor that never
// stops. Thread safety: one thread at a time; the Database must outlive it; other queries may run.
class NearestCursor {
 public:
  virtual ~NearestCursor() = default;
  // The next answer into *hit and true; false at the end (k given, nothing else within max_distance).
  // After an error the cursor answers that error again.
  virtual Result<bool> Next(NearestHit* hit) = 0;
  // What the answers so far cost (pages read and touched, leaves, nodes; hits: answers given).
  virtual const QueryStats& stats() const = 0;
};

// A ray from `origin` along `direction` (any non-zero length; t is measured in scene units), up to
// max_length. First hit, or (all_hits) every object the ray hits, each once at its first hit, in order of
// t, ties by id. Objects are hit on their surfaces: a ray starting inside a solid hits it where it leaves.
// REQUIRES (else InvalidArgument naming the query): finite origin and direction, a non-zero direction,
// max_length >= 0 (not NaN; +infinity: no limit).
struct RayQuery {
  Vec3d origin;
  Vec3d direction;
  double max_length = std::numeric_limits<double>::infinity();
  bool all_hits = false;
};

struct RayHit {
  ObjectId id = 0;
  double t = 0;  // distance from the origin along the ray
  Vec3d point;   // origin + t * unit direction (world)
  Vec3d normal;  // the hit triangle's unit normal, as its corners turn
};

// Receives a ray's hits in order; returns false to stop.
using RayVisitor = std::function<bool(const RayHit&)>;

}  // namespace mktree
