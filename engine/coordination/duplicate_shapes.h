// The duplicates test's comparison of two objects (mktree/clash_tests.h, ClashTestMode::kDuplicates):
// the same shape within a tolerance at the same place. Thread safety: pure functions.
#pragma once

#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree::coordination {

// Whether two boxes agree within `tolerance` on each of their six coordinates (plus the float32 rounding
// of stored boxes).
bool BoxesCoincide(const Box3d& a, const Box3d& b, double tolerance);

// Whether the meshes have the same vertex and triangle counts and each vertex of `a` has its own vertex
// of `b` within `tolerance` on every axis (a matching found greedily in x order). *deviation: the largest
// axis difference of the matching.
bool SameShape(const Mesh& a, const Mesh& b, double tolerance, double* deviation);

}  // namespace mktree::coordination
