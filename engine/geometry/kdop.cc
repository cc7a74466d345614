#include "engine/geometry/kdop.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <limits>

namespace mktree {

const std::array<std::array<int, 3>, kKdopDirections> kKdopAxes = {{{1, 0, 0},
                                                                    {0, 1, 0},
                                                                    {0, 0, 1},
                                                                    {1, 1, 0},
                                                                    {1, -1, 0},
                                                                    {1, 0, 1},
                                                                    {1, 0, -1},
                                                                    {0, 1, 1},
                                                                    {0, 1, -1},
                                                                    {1, 1, 1},
                                                                    {1, 1, -1},
                                                                    {1, -1, 1},
                                                                    {1, -1, -1}}};

// 1/sqrt(2) and 1/sqrt(3) rounded down: normalised gaps are then never overstated (see Gap for the sign).
const std::array<double, kKdopDirections> kKdopInverseLength = {1.0,
                                                                1.0,
                                                                1.0,
                                                                0.70710678118654746,
                                                                0.70710678118654746,
                                                                0.70710678118654746,
                                                                0.70710678118654746,
                                                                0.70710678118654746,
                                                                0.70710678118654746,
                                                                0.57735026918962573,
                                                                0.57735026918962573,
                                                                0.57735026918962573,
                                                                0.57735026918962573};

namespace {

double Project(int d, double x, double y, double z) {
  const auto& a = kKdopAxes[d];
  return a[0] * x + a[1] * y + a[2] * z;
}

}  // namespace

Kdop Kdop::Of(const Mesh& mesh) {
  Kdop k;
  k.lo.fill(std::numeric_limits<double>::infinity());
  k.hi.fill(-std::numeric_limits<double>::infinity());
  double largest = 0;  // max |x| + |y| + |z|: bounds the rounding error of every diagonal projection
  const double* v = mesh.vertices.data();
  for (size_t i = 0; i < mesh.vertex_count(); ++i, v += 3) {
    largest = std::max(largest, std::fabs(v[0]) + std::fabs(v[1]) + std::fabs(v[2]));
    for (int d = 0; d < kKdopDirections; ++d) {
      const double p = Project(d, v[0], v[1], v[2]);
      k.lo[d] = std::min(k.lo[d], p);
      k.hi[d] = std::max(k.hi[d], p);
    }
  }
  if (k.empty()) return k;
  // A sum of two or three doubles is off by at most 2 ulp of the magnitude of its terms' sum.
  const double slack = 4 * DBL_EPSILON * largest;
  for (int d = kAabbDirections; d < kKdopDirections; ++d) {
    k.lo[d] -= slack;
    k.hi[d] += slack;
  }
  return k;
}

double Kdop::Gap(const Kdop& o, int directions) const {
  if (empty() || o.empty()) return std::numeric_limits<double>::infinity();
  double gap = -std::numeric_limits<double>::infinity();
  for (int d = 0; d < directions; ++d) {
    const double g = std::max(o.lo[d] - hi[d], lo[d] - o.hi[d]) * kKdopInverseLength[d];
    gap = std::max(gap, g);
  }
  // Shrink positive gaps and grow overlaps by a few ulps for the rounding of the difference and scale.
  return gap > 0 ? gap * (1 - 4 * DBL_EPSILON) : gap * (1 + 4 * DBL_EPSILON);
}

bool Kdop::Contains(const Vec3d& p) const {
  for (int d = 0; d < kKdopDirections; ++d) {
    const double x = Project(d, p.x, p.y, p.z);
    if (x < lo[d] || x > hi[d]) return false;
  }
  return true;
}

}  // namespace mktree
