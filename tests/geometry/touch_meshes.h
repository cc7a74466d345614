// Test-only solids with exact double vertices (no float rounding, unlike test_meshes.h): prisms over
// polygons and tetrahedra, for planted touches (tests/geometry/touch_certificate_test.cc, tests/clash).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "engine/geometry/exact_predicates.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree::testing {

struct Pt {
  double x, y;
};

// A prism: the counterclockwise polygon `poly` (in the xy plane, convex or not) between z0 and z1, closed
// and consistently oriented; `fan` triangulates the caps (index triples into poly). Coordinates are used as
// given (doubles: integers stay exact far from the origin).
inline Mesh Prism(const std::vector<Pt>& poly, const std::vector<std::array<uint32_t, 3>>& fan, double z0,
                  double z1, const Vec3d& at = {0, 0, 0}) {
  Mesh m;
  const uint32_t n = static_cast<uint32_t>(poly.size());
  for (double z : {z0, z1})
    for (const Pt& p : poly) m.vertices.insert(m.vertices.end(), {at.x + p.x, at.y + p.y, at.z + z});
  for (const auto& t : fan) {
    m.triangles.insert(m.triangles.end(), {t[0], t[2], t[1]});              // bottom, facing -z
    m.triangles.insert(m.triangles.end(), {n + t[0], n + t[1], n + t[2]});  // top, facing +z
  }
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t j = (i + 1) % n;
    m.triangles.insert(m.triangles.end(), {i, j, n + j, i, n + j, n + i});
  }
  return m;
}
inline std::vector<std::array<uint32_t, 3>> Fan(size_t n) {
  std::vector<std::array<uint32_t, 3>> f;
  for (uint32_t i = 1; i + 1 < n; ++i) f.push_back({0, i, i + 1});
  return f;
}
inline Mesh ConvexPrism(const std::vector<Pt>& poly, double z0, double z1, const Vec3d& at = {0, 0, 0}) {
  return Prism(poly, Fan(poly.size()), z0, z1, at);
}
inline Mesh Box(const Vec3d& lo, const Vec3d& hi, const Vec3d& at = {0, 0, 0}) {
  return ConvexPrism({{lo.x, lo.y}, {hi.x, lo.y}, {hi.x, hi.y}, {lo.x, hi.y}}, lo.z, hi.z, at);
}
// A tetrahedron, consistently oriented whatever the corners' order.
inline Mesh Tetra(const std::array<Vec3d, 4>& c, const Vec3d& at = {0, 0, 0}) {
  Mesh m;
  for (const Vec3d& v : c) m.vertices.insert(m.vertices.end(), {at.x + v.x, at.y + v.y, at.z + v.z});
  const double p[4][3] = {
      {c[0].x, c[0].y, c[0].z}, {c[1].x, c[1].y, c[1].z}, {c[2].x, c[2].y, c[2].z}, {c[3].x, c[3].y, c[3].z}};
  const bool positive = Orient3dSign(p[0], p[1], p[2], p[3]) < 0;  // CGAL's positive orientation
  m.triangles = positive ? std::vector<uint32_t>{0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3}
                         : std::vector<uint32_t>{0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
  return m;
}

}  // namespace mktree::testing
