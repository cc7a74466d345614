#include "engine/geometry/closest_point.h"

#include <algorithm>
#include <vector>

#include "engine/geometry/triangle_pair.h"

namespace mktree {

namespace {

Vec3d Corner(const Mesh& mesh, uint32_t v) {
  const double* c = mesh.vertices.data() + 3 * size_t{v};
  return {c[0], c[1], c[2]};
}

void Consider(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c, SurfacePoint* best) {
  const ClosestPoints cp = PointTriangleClosest(p, a, b, c);
  if (cp.distance_squared < best->distance_squared) {
    best->distance_squared = cp.distance_squared;
    best->point = cp.on_b;
  }
}

}  // namespace

double BoxPointDistanceSquared(const Box3d& box, const Vec3d& p) {
  if (box.empty()) return std::numeric_limits<double>::infinity();
  double d2 = 0;
  for (int i = 0; i < 3; ++i) {
    const double d = p[i] < box.min[i] ? box.min[i] - p[i] : (p[i] > box.max[i] ? p[i] - box.max[i] : 0.0);
    d2 += d * d;
  }
  return d2;
}

SurfacePoint ClosestOnSurface(const Mesh& mesh, const Vec3d& p, double bound_squared) {
  SurfacePoint best;
  const uint32_t* t = mesh.triangles.data();
  for (size_t i = 0; i < mesh.triangle_count(); ++i, t += 3) {
    const Vec3d a = Corner(mesh, t[0]), b = Corner(mesh, t[1]), c = Corner(mesh, t[2]);
    // A triangle whose box is no nearer than the best point cannot give a nearer one.
    Box3d box;
    box.Extend(a.x, a.y, a.z);
    box.Extend(b.x, b.y, b.z);
    box.Extend(c.x, c.y, c.z);
    if (BoxPointDistanceSquared(box, p) >= best.distance_squared) continue;
    Consider(p, a, b, c, &best);
  }
  if (best.distance_squared > bound_squared) return SurfacePoint{};
  return best;
}

SurfacePoint ClosestOnSurface(const TriangleHierarchy& h, const Vec3d& p, double bound_squared) {
  SurfacePoint best;
  const auto& nodes = h.nodes();
  if (nodes.empty()) return best;
  struct Item {
    uint32_t node;
    double d2;
  };
  std::vector<Item> stack;
  stack.push_back({0, BoxPointDistanceSquared(nodes[0].box, p)});
  // Pruned by the bound until a point is found, then by the best point.
  auto limit = [&] { return std::min(best.distance_squared, bound_squared); };
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    if (it.d2 > limit()) continue;
    const TriangleHierarchy::Node& n = nodes[it.node];
    if (n.leaf()) {
      for (uint32_t i = n.first; i < n.first + n.count; ++i) {
        const TriangleHierarchy::Triangle tr = h.triangle(i);
        Consider(p, tr[0], tr[1], tr[2], &best);
      }
      continue;
    }
    Item c0{n.first, BoxPointDistanceSquared(nodes[n.first].box, p)};
    Item c1{n.first + 1, BoxPointDistanceSquared(nodes[n.first + 1].box, p)};
    if (c0.d2 < c1.d2) std::swap(c0, c1);  // the nearer child is walked first
    if (c0.d2 <= limit()) stack.push_back(c0);
    if (c1.d2 <= limit()) stack.push_back(c1);
  }
  if (best.distance_squared > bound_squared) return SurfacePoint{};
  return best;
}

}  // namespace mktree
