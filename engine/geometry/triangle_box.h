// Triangle-box overlap by the separating-axis test (Akenine-Moller, "Fast 3D Triangle-Box Overlap
// Testing", 2001): 13 candidate axes, the 3 box normals, the triangle normal and the 9 cross products of
// a triangle edge with a box axis.
//
// Semantics: both sets are closed, so touching counts as meeting. An axis separates only when the gap
// exceeds a bound on the rounding error of the projections (a few ulps of the coordinates' magnitude),
// so the answer errs towards "meets" for gaps below ~1e-15 relative; it never misses a real contact.
// Degenerate input is fine: a zero-area triangle (a segment or a point) yields zero axes, which are
// skipped, and the remaining axes are still a complete set for it; a box with zero thickness on any axis
// (a rectangle, segment or point) is a closed box like any other. An empty box (min > max) meets nothing.
//
// Thread-safety: pure function.
#pragma once

#include "mktree/geometry.h"

namespace mktree {

bool TriangleMeetsBox(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Box3d& box);

}  // namespace mktree
