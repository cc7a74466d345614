#include "engine/geometry/touch_certificate.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "engine/geometry/exact_predicates.h"
#include "engine/geometry/triangle_pair.h"

namespace mktree {
namespace {

constexpr double kU = 0x1p-53;

// Exact sign of the sum of n doubles (n <= 6): Shewchuk's GROW-EXPANSION; the sign of a nonoverlapping
// expansion is the sign of its largest component.
int SumSign(const double* x, int n) {
  double e[8];
  int m = 0;
  for (int i = 0; i < n; ++i) {
    double q = x[i];
    int out = 0;
    for (int j = 0; j < m; ++j) {
      const double s = q + e[j];
      const double bv = s - q;
      const double av = s - bv;
      const double h = (q - av) + (e[j] - bv);
      q = s;
      if (h != 0) e[out++] = h;
    }
    e[out++] = q;
    m = out;
  }
  for (int j = m; j-- > 0;)
    if (e[j] != 0) return (e[j] > 0) - (e[j] < 0);
  return 0;
}

// Do the vertex sets lie on opposite closed sides of the plane `side` (an exact sign per point) describes?
template <typename Side>
bool WeaklySeparates(const Mesh& a, const Mesh& b, const Side& side) {
  int s = 0;  // the side of a's vertices off the plane
  for (size_t i = 0; i < a.vertex_count(); ++i) {
    const int k = side(&a.vertices[3 * i]);
    if (k == 0) continue;
    if (s == 0)
      s = k;
    else if (k != s)
      return false;
  }
  for (size_t i = 0; i < b.vertex_count(); ++i) {
    const int k = side(&b.vertices[3 * i]);
    if (k == 0) continue;
    if (s == 0)
      s = -k;
    else if (k != -s)
      return false;
  }
  return true;
}

struct Interval {
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  bool complete = true;
};

// Project, stopping (complete = false) once the interval overlaps `other` by more than `limit` both ways.
Interval ProjectUntil(const Mesh& m, const Vec3d& n, const Interval& other, double limit) {
  Interval r;
  const double* v = m.vertices.data();
  for (size_t i = 0; i < m.vertex_count(); ++i, v += 3) {
    const double p = v[0] * n.x + v[1] * n.y + v[2] * n.z;
    r.lo = std::min(r.lo, p);
    r.hi = std::max(r.hi, p);
    if ((i & 15) == 15 && other.hi - r.lo > limit && r.hi - other.lo > limit) {
      r.complete = false;
      return r;
    }
  }
  return r;
}
// The whole projection of `m`'s vertices on `n` (an empty `other` never stops it).
Interval Project(const Mesh& m, const Vec3d& n) {
  return ProjectUntil(m, n, Interval{}, std::numeric_limits<double>::infinity());
}

double Volume(const Box3d& b) {
  return (b.max[0] - b.min[0]) * (b.max[1] - b.min[1]) * (b.max[2] - b.min[2]);
}

// Meeting triangle pairs of the two hierarchies, up to the budget (a dual traversal as FindMeeting's that
// goes on after the first).
void MeetingTriangles(const TriangleHierarchy& a, const TriangleHierarchy& b, const TouchBudget& budget,
                      std::vector<TriangleHierarchy::Triangle>* out, uint64_t* tests) {
  struct NodePair {
    uint32_t a, b;
  };
  thread_local std::vector<NodePair> stack;
  stack.clear();
  if (a.nodes().empty() || b.nodes().empty()) return;
  stack.push_back({0, 0});
  size_t found = 0;
  while (!stack.empty() && found < budget.meeting_pairs && *tests < budget.triangle_tests) {
    const NodePair p = stack.back();
    stack.pop_back();
    const TriangleHierarchy::Node& na = a.nodes()[p.a];
    const TriangleHierarchy::Node& nb = b.nodes()[p.b];
    if (!BoxesMeet(na.box, nb.box)) continue;
    if (na.leaf() && nb.leaf()) {
      for (uint32_t i = na.first; i < na.first + na.count; ++i) {
        const Box3d bi = TriangleBox(a.triangle(i));
        if (!BoxesMeet(bi, nb.box)) continue;
        for (uint32_t j = nb.first; j < nb.first + nb.count; ++j) {
          if (!BoxesMeet(bi, TriangleBox(b.triangle(j)))) continue;
          ++*tests;
          const TriangleHierarchy::Triangle ti = a.triangle(i), tj = b.triangle(j);
          if (TrianglesMeet(ti.data(), tj.data())) {
            out->push_back(ti);
            out->push_back(tj);
            ++found;
          }
        }
      }
    } else if (!na.leaf() && (nb.leaf() || Volume(na.box) >= Volume(nb.box))) {
      stack.push_back({na.first + 1, p.b});
      stack.push_back({na.first, p.b});
    } else {
      stack.push_back({p.a, nb.first + 1});
      stack.push_back({p.a, nb.first});
    }
  }
}

// The unit normal of a triangle, or false when it has no area in double precision.
bool UnitNormal(const TriangleHierarchy::Triangle& t, Vec3d* n) {
  const Vec3d u{t[1].x - t[0].x, t[1].y - t[0].y, t[1].z - t[0].z};
  const Vec3d v{t[2].x - t[0].x, t[2].y - t[0].y, t[2].z - t[0].z};
  Vec3d c{u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x};
  const double len = std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z);
  if (!(len > 0) || !std::isfinite(len)) return false;
  c = {c.x / len, c.y / len, c.z / len};
  if (c.x < 0 || (c.x == 0 && (c.y < 0 || (c.y == 0 && c.z < 0)))) c = {-c.x, -c.y, -c.z};
  *n = c;
  return true;
}

// Box interiors disjoint: a triangle in `t` misses the interior of anything inside `x`.
bool InteriorsApart(const Box3d& t, const Box3d& x) {
  for (int k = 0; k < 3; ++k)
    if (t.max[k] <= x.min[k] || x.max[k] <= t.min[k]) return true;
  return false;
}

// The convex piece certificate (header): x convex and small, y a solid.
bool ConvexPieceApart(const TouchObject& x, const TouchObject& y, const TouchBudget& budget) {
  const Mesh& m = *x.mesh;
  const size_t nt = m.triangle_count(), nv = m.vertex_count();
  if (!x.classifier || !y.classifier || nt == 0 || nt > budget.convex_triangles) return false;
  auto corner = [&](size_t t, int k) { return &m.vertices[3 * size_t{m.triangles[3 * t + k]}]; };
  // The facets' inner sides (0: a zero-area facet, ignored); any vertex on a facet's outer side: not
  // convex.
  thread_local std::vector<int> inner;
  inner.assign(nt, 0);
  bool any = false;
  for (size_t t = 0; t < nt; ++t) {
    const double *p0 = corner(t, 0), *p1 = corner(t, 1), *p2 = corner(t, 2);
    for (size_t i = 0; i < nv; ++i) {
      const int k = Orient3dSign(p0, p1, p2, &m.vertices[3 * i]);
      if (k == 0) continue;
      if (inner[t] == 0)
        inner[t] = k;
      else if (k != inner[t])
        return false;
    }
    any |= inner[t] != 0;
  }
  if (!any) return false;
  // A point strictly inside every facet (the vertex mean; checked exactly).
  double q[3] = {0, 0, 0};
  for (size_t i = 0; i < nv; ++i)
    for (int k = 0; k < 3; ++k) q[k] += m.vertices[3 * i + k];
  for (double& c : q) c /= static_cast<double>(nv);
  for (size_t t = 0; t < nt; ++t)
    if (inner[t] != 0 && Orient3dSign(corner(t, 0), corner(t, 1), corner(t, 2), q) != inner[t]) return false;
  // Every triangle of y near x on the outer closed side of some facet (the last one that worked first).
  const Box3d xb = m.Bounds();
  const TriangleHierarchy& h = *y.hierarchy;
  if (h.nodes().empty()) return false;
  thread_local std::vector<uint32_t> stack;
  stack.clear();
  stack.push_back(0);
  size_t checks = 0, last = 0;
  while (!stack.empty()) {
    const TriangleHierarchy::Node& n = h.nodes()[stack.back()];
    stack.pop_back();
    if (InteriorsApart(n.box, xb)) continue;
    if (!n.leaf()) {
      stack.push_back(n.first);
      stack.push_back(n.first + 1);
      continue;
    }
    for (uint32_t i = n.first; i < n.first + n.count; ++i) {
      const TriangleHierarchy::Triangle& tri = h.triangle(i);
      if (InteriorsApart(TriangleBox(tri), xb)) continue;
      if (++checks > budget.convex_checks) return false;
      const double c[3][3] = {
          {tri[0].x, tri[0].y, tri[0].z}, {tri[1].x, tri[1].y, tri[1].z}, {tri[2].x, tri[2].y, tri[2].z}};
      bool outside = false;
      for (size_t s = 0; s < nt && !outside; ++s) {
        const size_t f = (last + s) % nt;
        if (inner[f] == 0) continue;
        outside = true;
        for (int k = 0; k < 3 && outside; ++k)
          outside = Orient3dSign(corner(f, 0), corner(f, 1), corner(f, 2), c[k]) != inner[f];
        if (outside) last = f;
      }
      if (!outside) return false;
    }
  }
  // y's surface misses x's interior: one interior point outside y puts all of it outside.
  return !y.classifier->Contains({q[0], q[1], q[2]});
}

}  // namespace

int DirectionSideSign(const int d[3], const double v[3], const double p[3]) {
  double t[3], s = 0, mag = 0;
  for (int k = 0; k < 3; ++k) {
    t[k] = v[k] - p[k];
    s += d[k] * t[k];
    mag += std::fabs(t[k]) * (d[k] != 0);
  }
  // Three rounded differences and two additions: the error is below 4u of the magnitude sum (8u: margin).
  if (std::fabs(s) > 8 * kU * mag) return (s > 0) - (s < 0);
  double x[6];
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0) continue;
    x[n++] = d[k] * v[k];
    x[n++] = -d[k] * p[k];
  }
  return SumSign(x, n);
}

TouchResult FindTouchCertificate(const TouchObject& a, const TouchObject& b, const Vec3d* ta, const Vec3d* tb,
                                 TouchStage stage, const TouchBudget& budget) {
  TouchResult r;
  const Mesh& ma = *a.mesh;
  const Mesh& mb = *b.mesh;
  const double slack = a.projection_slack + b.projection_slack;

  // A triangle's plane: the projection overlap on its normal bounds the depth; when it is within rounding
  // the exact sides decide.
  struct Plane {
    Vec3d n;
    double offset;
  };
  thread_local std::vector<Plane> planes;
  planes.clear();
  auto try_triangle = [&](const Vec3d* c) {
    if (planes.size() >= budget.planes) return false;
    const TriangleHierarchy::Triangle t{c[0], c[1], c[2]};
    Vec3d n;
    if (!UnitNormal(t, &n)) return false;
    // Triangles of one face (or faces lying on each other) give one plane up to rounding.
    const double offset = n.x * c[0].x + n.y * c[0].y + n.z * c[0].z;
    for (const Plane& q : planes)
      if (std::fabs(q.n.x - n.x) + std::fabs(q.n.y - n.y) + std::fabs(q.n.z - n.z) < 1e-12 &&
          std::fabs(q.offset - offset) <= slack)
        return false;
    planes.push_back({n, offset});
    ++r.planes_tried;
    // The smaller vertex set whole, the other until its interval overlaps the first by more than is of
    // use on both sides (then the plane neither separates nor gives a useful bound).
    const bool a_small = ma.vertex_count() <= mb.vertex_count();
    const Interval is = Project(a_small ? ma : mb, n);
    const Interval il = ProjectUntil(a_small ? mb : ma, n, is, std::max(slack, budget.useful_overlap));
    const double overlap = std::min(is.hi - il.lo, il.hi - is.lo);
    if (!il.complete) return false;
    r.depth_upper = std::min(r.depth_upper, std::max(0.0, overlap + slack));
    if (overlap > slack) return false;
    const double p0[3] = {c[0].x, c[0].y, c[0].z}, p1[3] = {c[1].x, c[1].y, c[1].z},
                 p2[3] = {c[2].x, c[2].y, c[2].z};
    return WeaklySeparates(ma, mb, [&](const double* v) { return Orient3dSign(p0, p1, p2, v); });
  };
  auto found = [&r] {
    r.separated = true;
    r.depth_upper = 0;
    return r;
  };

  if (stage == TouchStage::kCheap) {
    // The meeting pair the caller found costs no search.
    if (ta && try_triangle(ta)) return found();
    if (tb && try_triangle(tb)) return found();
    // The 26-DOP directions on which the bounds only touch (overlap within rounding): the plane through the
    // extreme vertex of the object on the far side.
    for (int k = 0; k < kKdopDirections; ++k) {
      const double up = a.kdop->hi[k] - b.kdop->lo[k], down = b.kdop->hi[k] - a.kdop->lo[k];
      const bool a_below = up <= down;
      const double overlap = (a_below ? up : down) * kKdopInverseLength[k];
      if (overlap > 2 * slack) continue;
      const int d[3] = {kKdopAxes[k][0], kKdopAxes[k][1], kKdopAxes[k][2]};
      // The vertex of the upper object with the lowest projection (in double: the exact test checks it).
      const Mesh& upper = a_below ? mb : ma;
      if (upper.vertex_count() == 0) continue;
      const int sign = a_below ? 1 : -1;
      size_t best = 0;
      double best_p = std::numeric_limits<double>::infinity();
      for (size_t i = 0; i < upper.vertex_count(); ++i) {
        const double* v = &upper.vertices[3 * i];
        const double p = sign * (d[0] * v[0] + d[1] * v[1] + d[2] * v[2]);
        if (p < best_p) {
          best_p = p;
          best = i;
        }
      }
      const double* p = &upper.vertices[3 * best];
      ++r.planes_tried;
      r.depth_upper = std::min(r.depth_upper, std::max(0.0, overlap + slack));
      if (WeaklySeparates(ma, mb, [&](const double* v) { return DirectionSideSign(d, v, p); }))
        return found();
    }
    return r;
  }

  // The planes of more meeting triangles.
  // Not skipped when the caller's pair straddles each other's planes: such triangles may still meet only
  // on their edges (steel members touching at a corner).
  thread_local std::vector<TriangleHierarchy::Triangle> meeting;
  meeting.clear();
  MeetingTriangles(*a.hierarchy, *b.hierarchy, budget, &meeting, &r.triangle_tests);
  for (const TriangleHierarchy::Triangle& t : meeting)
    if (try_triangle(t.data())) return found();

  // Non-convex contacts: either solid as a convex piece against the other, the smaller first.
  const bool a_smaller = ma.triangle_count() <= mb.triangle_count();
  if (ConvexPieceApart(a_smaller ? a : b, a_smaller ? b : a, budget)) return found();
  if (ConvexPieceApart(a_smaller ? b : a, a_smaller ? a : b, budget)) return found();
  return r;
}

}  // namespace mktree
