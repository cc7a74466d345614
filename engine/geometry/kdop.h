// A k-DOP (discrete oriented polytope) bound of a point set: the interval of the points' projections on
// each of a fixed set of directions. The 13 directions are the 3 axes, the 6 face diagonals (1,+-1,0),
// (1,0,+-1), (0,1,+-1) and the 4 body diagonals (1,+-1,+-1): the first 3 give the AABB, the first 9 an
// 18-DOP, all 13 a 26-DOP.
//
// Rounding: axis projections are exact; diagonal ones are widened outward by a bound on their rounding
// error, so every interval contains the exact projections of the points (used as double coordinates).
// Hence Gap() is a valid lower bound on the Euclidean distance between the two point sets' convex hulls
// (a slab separating them), and -Gap() when it is <= 0 an upper bound on their penetration depth (moving
// one set by that length along the direction that gives it separates the projections).
//
// Thread-safety: a value type; const methods are pure.
#pragma once

#include <array>
#include <cstddef>

#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

inline constexpr int kKdopDirections = 13;
inline constexpr int kAabbDirections = 3;
inline constexpr int kDop18Directions = 9;

// The unnormalised directions (components in {-1, 0, 1}) and their inverse lengths.
extern const std::array<std::array<int, 3>, kKdopDirections> kKdopAxes;
extern const std::array<double, kKdopDirections> kKdopInverseLength;

struct Kdop {
  std::array<double, kKdopDirections> lo, hi;  // lo > hi on every direction: empty
  bool empty() const { return lo[0] > hi[0]; }

  // The k-DOP of the mesh's vertices (all of them, referenced or not: they bound the triangles).
  static Kdop Of(const Mesh& mesh);

  // The largest gap between the two bounds over the first `directions` directions (3: AABB, 9: 18-DOP,
  // 13: 26-DOP), normalised: <= the distance between the bounded sets. Negative when they overlap on
  // every direction (then -Gap is the smallest overlap). +infinity when either is empty.
  double Gap(const Kdop& other, int directions = kKdopDirections) const;

  // Does the point lie in the (closed) bound?
  bool Contains(const Vec3d& p) const;
};

}  // namespace mktree
