#include "engine/coordination/duplicate_shapes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace mktree::coordination {

bool BoxesCoincide(const Box3d& a, const Box3d& b, double tolerance) {
  if (a.empty() || b.empty()) return false;
  for (int i = 0; i < 3; ++i) {
    // Stored boxes are float32 rounded outward: a few units of the last place on top of the tolerance.
    const double slack =
        tolerance + 4 * std::ldexp(1.0, -23) * std::max({1.0, std::abs(a.min[i]), std::abs(a.max[i])});
    if (std::abs(a.min[i] - b.min[i]) > slack || std::abs(a.max[i] - b.max[i]) > slack) return false;
  }
  return true;
}

bool SameShape(const Mesh& a, const Mesh& b, double tolerance, double* deviation) {
  *deviation = 0;
  if (a.vertex_count() != b.vertex_count() || a.triangle_count() != b.triangle_count()) return false;
  using P = std::array<double, 3>;
  auto points = [](const Mesh& m) {
    std::vector<P> p(m.vertex_count());
    for (size_t v = 0; v < p.size(); ++v)
      p[v] = {m.vertices[3 * v], m.vertices[3 * v + 1], m.vertices[3 * v + 2]};
    std::sort(p.begin(), p.end());
    return p;
  };
  const std::vector<P> pa = points(a), pb = points(b);
  std::vector<uint8_t> used(pb.size(), 0);
  size_t from = 0;  // the first vertex of b not below x - tolerance
  for (const P& p : pa) {
    while (from < pb.size() && pb[from][0] < p[0] - tolerance) ++from;
    bool found = false;
    for (size_t k = from; k < pb.size() && pb[k][0] <= p[0] + tolerance; ++k) {
      if (used[k]) continue;
      const double d =
          std::max({std::abs(pb[k][0] - p[0]), std::abs(pb[k][1] - p[1]), std::abs(pb[k][2] - p[2])});
      if (d > tolerance) continue;
      used[k] = 1;
      *deviation = std::max(*deviation, d);
      found = true;
      break;
    }
    if (!found) return false;
  }
  return true;
}

}  // namespace mktree::coordination
