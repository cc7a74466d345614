#include "engine/geometry/triangle_box.h"

#include <algorithm>
#include <cfloat>
#include <cmath>

namespace mktree {
namespace {

// True when `axis` provably separates the triangle from the box [lo, hi]. The projections are dot
// products of three terms, each off by at most ~3 ulps of sum |axis_k| * |x_k|; the slack covers both
// sides. The axis itself may be rounded: any axis with a clear gap proves separation.
bool Separates(const double axis[3], const double v[3][3], const double lo[3], const double hi[3]) {
  if (axis[0] == 0 && axis[1] == 0 && axis[2] == 0) return false;
  double box_lo = 0, box_hi = 0, scale = 0;
  for (int k = 0; k < 3; ++k) {
    const double p = axis[k] * lo[k], q = axis[k] * hi[k];
    box_lo += std::min(p, q);
    box_hi += std::max(p, q);
    const double m = std::max(
        {std::fabs(lo[k]), std::fabs(hi[k]), std::fabs(v[0][k]), std::fabs(v[1][k]), std::fabs(v[2][k])});
    scale += std::fabs(axis[k]) * m;
  }
  double tri_lo = 0, tri_hi = 0;
  for (int i = 0; i < 3; ++i) {
    const double p = axis[0] * v[i][0] + axis[1] * v[i][1] + axis[2] * v[i][2];
    tri_lo = i == 0 ? p : std::min(tri_lo, p);
    tri_hi = i == 0 ? p : std::max(tri_hi, p);
  }
  const double slack = 4 * DBL_EPSILON * scale;
  return tri_lo > box_hi + slack || tri_hi < box_lo - slack;
}

}  // namespace

bool TriangleMeetsBox(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Box3d& box) {
  if (box.empty()) return false;
  const double v[3][3] = {{a.x, a.y, a.z}, {b.x, b.y, b.z}, {c.x, c.y, c.z}};
  // The 3 box normals: comparisons of coordinates, exact. Afterwards clip the box to the triangle's
  // bounds, which changes nothing (the triangle lies in them) but keeps magnitudes finite and small
  // for the remaining axes even when the query box is huge or unbounded.
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    const double tmin = std::min({v[0][k], v[1][k], v[2][k]});
    const double tmax = std::max({v[0][k], v[1][k], v[2][k]});
    if (tmax < box.min[k] || tmin > box.max[k]) return false;
    lo[k] = std::max(tmin, box.min[k]);
    hi[k] = std::min(tmax, box.max[k]);
  }
  double e[3][3];
  for (int k = 0; k < 3; ++k) {
    e[0][k] = v[1][k] - v[0][k];
    e[1][k] = v[2][k] - v[1][k];
    e[2][k] = v[0][k] - v[2][k];
  }
  // Triangle normal.
  const double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                       e[0][0] * e[1][1] - e[0][1] * e[1][0]};
  if (Separates(n, v, lo, hi)) return false;
  // Edge x box axis: e x X = (0, ez, -ey), e x Y = (-ez, 0, ex), e x Z = (ey, -ex, 0).
  for (int i = 0; i < 3; ++i) {
    const double ax[3] = {0, e[i][2], -e[i][1]};
    const double ay[3] = {-e[i][2], 0, e[i][0]};
    const double az[3] = {e[i][1], -e[i][0], 0};
    if (Separates(ax, v, lo, hi) || Separates(ay, v, lo, hi) || Separates(az, v, lo, hi)) return false;
  }
  return true;
}

}  // namespace mktree
