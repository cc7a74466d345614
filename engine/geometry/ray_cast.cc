#include "engine/geometry/ray_cast.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "engine/geometry/exact_predicates.h"

namespace mktree {

namespace {

Vec3d Sub(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3d Cross(const Vec3d& a, const Vec3d& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double Dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

int Orient(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3d& d) {
  const double pa[3] = {a.x, a.y, a.z}, pb[3] = {b.x, b.y, b.z}, pc[3] = {c.x, c.y, c.z},
               pd[3] = {d.x, d.y, d.z};
  return Orient3dSign(pa, pb, pc, pd);
}

// The line lies in the triangle's plane: the smallest t in [0, max_t] where the ray's projection onto the
// plane's best coordinate plane is in the projected triangle.
bool CoplanarEnter(const PreparedRay& ray, const Vec3d v[3], const Vec3d& n, double max_t, double* t) {
  const double an[3] = {std::fabs(n.x), std::fabs(n.y), std::fabs(n.z)};
  const int drop = an[0] >= an[1] && an[0] >= an[2] ? 0 : (an[1] >= an[2] ? 1 : 2);
  const int u = (drop + 1) % 3, w = (drop + 2) % 3;
  const double orient = n[drop] > 0 ? 1.0 : -1.0;  // the projected triangle turns this way
  const Vec3d& o = ray.origin();
  const Vec3d& d = ray.direction();
  double lo = 0, hi = max_t;
  for (int i = 0; i < 3; ++i) {
    const Vec3d& p = v[i];
    const Vec3d& q = v[(i + 1) % 3];
    const double eu = q[u] - p[u], ew = q[w] - p[w];
    // Inside the edge's half-plane: orient * (e x (x - p)) >= 0, along the ray f0 + t f1.
    const double f0 = orient * (eu * (o[w] - p[w]) - ew * (o[u] - p[u]));
    const double f1 = orient * (eu * d[w] - ew * d[u]);
    if (f1 == 0) {
      if (f0 < 0) return false;
    } else if (f1 > 0) {
      lo = std::max(lo, -f0 / f1);
    } else {
      hi = std::min(hi, -f0 / f1);
    }
    if (lo > hi) return false;
  }
  *t = lo;
  return true;
}

}  // namespace

PreparedRay::PreparedRay(const Vec3d& origin, const Vec3d& direction) : origin_(origin) {
  const double len = std::sqrt(Dot(direction, direction));
  dir_ = {direction.x / len, direction.y / len, direction.z / len};
  const double scale = 1 + std::max({std::fabs(origin.x), std::fabs(origin.y), std::fabs(origin.z)});
  far_ = {origin.x + dir_.x * scale, origin.y + dir_.y * scale, origin.z + dir_.z * scale};
}

bool RayTriangle(const PreparedRay& ray, const Vec3d& a, const Vec3d& b, const Vec3d& c, double max_t,
                 RayHit3* hit) {
  const Vec3d n = Cross(Sub(b, a), Sub(c, a));
  if (n.x == 0 && n.y == 0 && n.z == 0) return false;
  const Vec3d& o = ray.origin();
  const Vec3d& f = ray.far_point();
  const int s0 = Orient(o, f, a, b), s1 = Orient(o, f, b, c), s2 = Orient(o, f, c, a);
  if ((s0 > 0 || s1 > 0 || s2 > 0) && (s0 < 0 || s1 < 0 || s2 < 0)) return false;  // the line misses
  double t;
  if (s0 == 0 && s1 == 0 && s2 == 0) {
    const Vec3d v[3] = {a, b, c};
    if (!CoplanarEnter(ray, v, n, max_t, &t)) return false;
  } else if (Orient(a, b, c, o) == 0) {
    t = 0;  // the origin lies in the plane, where the line crosses it: inside the triangle
  } else {
    const double denom = Dot(ray.direction(), n);
    t = Dot(Sub(a, o), n) / denom;
    if (!std::isfinite(t) || t < 0 || t > max_t) return false;
  }
  const double len = std::sqrt(Dot(n, n));
  hit->t = t;
  hit->point = ray.At(t);
  hit->normal = {n.x / len, n.y / len, n.z / len};
  return true;
}

bool RayBoxEnter(const PreparedRay& ray, const Box3d& box, double max_t, double* enter) {
  if (box.empty()) return false;
  const Vec3d& o = ray.origin();
  const Vec3d& d = ray.direction();
  double lo = 0, hi = max_t;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0) {
      if (o[i] < box.min[i] || o[i] > box.max[i]) return false;
      continue;
    }
    double t0 = (box.min[i] - o[i]) / d[i], t1 = (box.max[i] - o[i]) / d[i];
    if (t0 > t1) std::swap(t0, t1);
    // Each quotient is within an ulp or two of the exact one: widen so that no hit inside is lost.
    lo = std::max(lo, t0 - 1e-12 * std::fabs(t0));
    hi = std::min(hi, t1 + 1e-12 * std::fabs(t1));
    if (lo > hi) return false;
  }
  *enter = lo;
  return true;
}

RayHit3 FirstHit(const Mesh& mesh, const PreparedRay& ray, double max_t) {
  RayHit3 best;
  const double* v = mesh.vertices.data();
  auto at = [v](uint32_t i) { return Vec3d{v[3 * size_t{i}], v[3 * size_t{i} + 1], v[3 * size_t{i} + 2]}; };
  const uint32_t* t = mesh.triangles.data();
  for (size_t i = 0; i < mesh.triangle_count(); ++i, t += 3) {
    const Vec3d a = at(t[0]), b = at(t[1]), c = at(t[2]);
    // The slab test of the triangle's box rejects most triangles for a few divisions, before the exact signs.
    Box3d box;
    box.Extend(a.x, a.y, a.z);
    box.Extend(b.x, b.y, b.z);
    box.Extend(c.x, c.y, c.z);
    double enter;
    const double limit = std::min(max_t, best.t);
    if (!RayBoxEnter(ray, box, limit, &enter)) continue;
    RayHit3 h;
    if (RayTriangle(ray, a, b, c, limit, &h) && h.t < best.t) best = h;
  }
  return best;
}

RayHit3 FirstHit(const TriangleHierarchy& h, const PreparedRay& ray, double max_t) {
  RayHit3 best;
  const auto& nodes = h.nodes();
  if (nodes.empty()) return best;
  std::vector<std::pair<uint32_t, double>> stack;
  double t0;
  if (!RayBoxEnter(ray, nodes[0].box, max_t, &t0)) return best;
  stack.push_back({0, t0});
  while (!stack.empty()) {
    const auto [node, enter] = stack.back();
    stack.pop_back();
    const double limit = std::min(max_t, best.t);
    if (enter > limit) continue;
    const TriangleHierarchy::Node& n = nodes[node];
    if (n.leaf()) {
      for (uint32_t i = n.first; i < n.first + n.count; ++i) {
        const TriangleHierarchy::Triangle tr = h.triangle(i);
        RayHit3 hit;
        if (RayTriangle(ray, tr[0], tr[1], tr[2], std::min(max_t, best.t), &hit) && hit.t < best.t)
          best = hit;
      }
      continue;
    }
    double e0, e1;
    const bool in0 = RayBoxEnter(ray, nodes[n.first].box, limit, &e0);
    const bool in1 = RayBoxEnter(ray, nodes[n.first + 1].box, limit, &e1);
    if (in0 && in1 && e0 < e1) {  // the nearer child is walked first
      stack.push_back({n.first + 1, e1});
      stack.push_back({n.first, e0});
    } else {
      if (in0) stack.push_back({n.first, e0});
      if (in1) stack.push_back({n.first + 1, e1});
    }
  }
  return best;
}

}  // namespace mktree
