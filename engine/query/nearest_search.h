// Nearest and within-distance queries over the parts of a Database (docs/nearest_and_ray.md): the cursor
// behind Database::OpenNearest, a BestFirstSearch whose keys are distances from the query (a point, a box
// or a mesh) to boxes and, last, to objects' geometry (closest_point.h for a point; Separate for a box or a
// mesh, engine/geometry/mesh_separation.h), bounded by max_distance and the k-th distance found so far.
// Thread safety: a cursor belongs to one thread; the parts' Databases may serve other queries meanwhile.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "engine/query/best_first_search.h"
#include "mktree/nearest.h"

namespace mktree {

// InvalidArgument naming the query ("nearest query: ...") when it breaks DistanceQuery's REQUIRES.
Status CheckDistanceQuery(const DistanceQuery& q);

// The cursor of `q` over `parts` (errors name `name`, the Database's path). REQUIRES: the parts outlive it.
Result<std::unique_ptr<NearestCursor>> OpenNearestSearch(std::vector<SearchPart> parts,
                                                         const DistanceQuery& q, const std::string& name);

// The I/O floor of a best-first search that answers with distances up to `distance`: the pages of the
// leaves whose region (their objects' filter boxes, docs/nearest_and_ray.md) is at most that far from q,
// however those leaves are reached. For tests and benchmarks.
uint64_t NearestPageFloor(const std::vector<SearchPart>& parts, const DistanceQuery& q, double distance);

}  // namespace mktree
