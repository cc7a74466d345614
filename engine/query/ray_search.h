// Ray queries over the parts of a Database (docs/nearest_and_ray.md): a BestFirstSearch whose keys are
// where the ray enters boxes (RayBoxEnter) and, last, the t of each object's first hit (ray_cast.h): the
// tree is walked front to back along the ray, and a first-hit query stops at its first answer, having read
// only leaves whose region the ray enters before that hit.
// Thread safety: a free function; the parts' Databases may serve other queries meanwhile.
#pragma once

#include <string>
#include <vector>

#include "engine/query/best_first_search.h"
#include "mktree/nearest.h"

namespace mktree {

// InvalidArgument naming the query ("ray query: ...") when it breaks RayQuery's REQUIRES.
Status CheckRayQuery(const RayQuery& q);

// Runs `q` over `parts`, handing its hits to `visit` in order until it returns false; returns whether every
// hit was visited. `stats` (may be null) is reset and filled. Errors name `name`.
Result<bool> RunRaySearch(const std::vector<SearchPart>& parts, const RayQuery& q, const std::string& name,
                          const RayVisitor& visit, QueryStats* stats);

// The pages of the leaves whose region the ray enters at t <= `t` (the I/O floor of a front-to-back walk
// that ends at a hit at t). For tests and benchmarks.
uint64_t RayPageFloor(const std::vector<SearchPart>& parts, const RayQuery& q, double t);

}  // namespace mktree
