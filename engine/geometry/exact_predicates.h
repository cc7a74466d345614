// Exact orientation predicates (Shewchuk style): a floating-point filter decides the sign when the
// rounded determinant is clearly away from zero; otherwise the determinant is recomputed exactly with
// floating-point expansions. Inputs are arbitrary doubles (mesh vertices and query points). The sign
// returned is the sign of the exact determinant of the inputs as given, barring overflow and underflow
// (coordinates beyond ~1e150 or below ~1e-150 in magnitude, which no scene uses).
//
// Thread-safety: pure functions.
#pragma once

namespace mktree {

// Sign (-1, 0, +1) of the 2D determinant | ax-cx  ay-cy ; bx-cx  by-cy |, i.e. of the cross product
// (b - a) x (c - a): positive when a, b, c turn counterclockwise.
int Orient2dSign(double ax, double ay, double bx, double by, double cx, double cy);

// Sign (-1, 0, +1) of the triple product (a - d) . ((b - d) x (c - d)): zero iff the four points are
// coplanar; positive when d lies on the side of plane abc away from which a, b, c look clockwise
// (Shewchuk's orient3d).
int Orient3dSign(const double a[3], const double b[3], const double c[3], const double d[3]);

}  // namespace mktree
