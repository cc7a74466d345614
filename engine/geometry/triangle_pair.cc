#include "engine/geometry/triangle_pair.h"

#include <algorithm>
#include <cmath>

#include "engine/geometry/exact_predicates.h"

namespace mktree {
namespace {

Vec3d Sub(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3d Add(const Vec3d& a, const Vec3d& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3d Scale(const Vec3d& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double Dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3d Cross(const Vec3d& a, const Vec3d& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double Dist2(const Vec3d& a, const Vec3d& b) { return Dot(Sub(a, b), Sub(a, b)); }

int O3(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3d& d) {
  const double pa[3] = {a.x, a.y, a.z}, pb[3] = {b.x, b.y, b.z}, pc[3] = {c.x, c.y, c.z},
               pd[3] = {d.x, d.y, d.z};
  return Orient3dSign(pa, pb, pc, pd);
}

// The two coordinates kept when axis k is dropped.
struct P2 {
  double u, v;
};
P2 Drop(const Vec3d& p, int k) {
  switch (k) {
    case 0:
      return {p.y, p.z};
    case 1:
      return {p.z, p.x};
    default:
      return {p.x, p.y};
  }
}
int O2(const P2& a, const P2& b, const P2& c) { return Orient2dSign(a.u, a.v, b.u, b.v, c.u, c.v); }

// An axis whose dropping keeps a, b, c non-collinear (so the projection is one-to-one on their plane), or
// -1 when the three points are collinear. Exact.
int DropAxisOf(const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d n = Cross(Sub(b, a), Sub(c, a));
  int order[3] = {0, 1, 2};  // the largest normal component first: the best-conditioned projection
  std::sort(order, order + 3, [&](int i, int j) { return std::fabs(n[i]) > std::fabs(n[j]); });
  for (int k : order)
    if (O2(Drop(a, k), Drop(b, k), Drop(c, k)) != 0) return k;
  return -1;
}

bool Less(const Vec3d& a, const Vec3d& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

// Closed segments in 2D, points allowed (exact; orientation plus bounding-box checks for collinear cases).
bool OnSegment2(const P2& p, const P2& q, const P2& r) {  // r collinear with pq
  return std::min(p.u, q.u) <= r.u && r.u <= std::max(p.u, q.u) && std::min(p.v, q.v) <= r.v &&
         r.v <= std::max(p.v, q.v);
}
bool SegmentsMeet2(const P2& p, const P2& q, const P2& r, const P2& s) {
  const int d1 = O2(r, s, p), d2 = O2(r, s, q), d3 = O2(p, q, r), d4 = O2(p, q, s);
  if (d1 * d2 < 0 && d3 * d4 < 0) return true;
  if (d1 == 0 && OnSegment2(r, s, p)) return true;
  if (d2 == 0 && OnSegment2(r, s, q)) return true;
  if (d3 == 0 && OnSegment2(p, q, r)) return true;
  if (d4 == 0 && OnSegment2(p, q, s)) return true;
  return false;
}
// Closed non-degenerate triangle abc in 2D.
bool PointInTriangle2(const P2& p, const P2& a, const P2& b, const P2& c) {
  const int s1 = O2(a, b, p), s2 = O2(b, c, p), s3 = O2(c, a, p);
  const bool neg = s1 < 0 || s2 < 0 || s3<0, pos = s1> 0 || s2 > 0 || s3 > 0;
  return !(neg && pos);
}
bool SegmentMeetsTriangle2(const P2& p, const P2& q, const P2& a, const P2& b, const P2& c) {
  return PointInTriangle2(p, a, b, c) || PointInTriangle2(q, a, b, c) || SegmentsMeet2(p, q, a, b) ||
         SegmentsMeet2(p, q, b, c) || SegmentsMeet2(p, q, c, a);
}

// A triangle prepared for the exact tests: its drop axis (-1: collinear corners) and, when collinear,
// the extreme corners of the segment it is.
struct PreparedTriangle {
  const Vec3d* v;
  int axis;
  Vec3d lo, hi;
  explicit PreparedTriangle(const Vec3d* t) : v(t), axis(DropAxisOf(t[0], t[1], t[2])) {
    if (axis < 0) {
      // Collinear points are ordered along their line by lexicographic order.
      lo = hi = t[0];
      for (int i = 1; i < 3; ++i) {
        if (Less(t[i], lo)) lo = t[i];
        if (Less(hi, t[i])) hi = t[i];
      }
    }
  }
};

// Segment pq against a non-degenerate triangle, given the signs of p and q against its plane.
bool SegmentMeetsPrepared(const Vec3d& p, const Vec3d& q, int sp, int sq, const PreparedTriangle& t) {
  if (sp * sq > 0) return false;
  const Vec3d &a = t.v[0], &b = t.v[1], &c = t.v[2];
  if (sp == 0 && sq == 0) {
    const int k = t.axis;
    return SegmentMeetsTriangle2(Drop(p, k), Drop(q, k), Drop(a, k), Drop(b, k), Drop(c, k));
  }
  // The segment crosses (or ends on) the plane at one point: it is in the closed triangle iff the line pq
  // passes on the same side of the three edges (zeros allowed).
  const int s1 = O3(p, q, a, b), s2 = O3(p, q, b, c), s3 = O3(p, q, c, a);
  const bool neg = s1 < 0 || s2 < 0 || s3<0, pos = s1> 0 || s2 > 0 || s3 > 0;
  return !(neg && pos);
}

bool SegmentMeetsPrepared(const Vec3d& p, const Vec3d& q, const PreparedTriangle& t) {
  if (t.axis < 0) return SegmentsMeet(p, q, t.lo, t.hi);
  return SegmentMeetsPrepared(p, q, O3(t.v[0], t.v[1], t.v[2], p), O3(t.v[0], t.v[1], t.v[2], q), t);
}

bool BoxesApart(const Vec3d a[3], const Vec3d b[3]) {
  for (int k = 0; k < 3; ++k) {
    const double amin = std::min({a[0][k], a[1][k], a[2][k]}), amax = std::max({a[0][k], a[1][k], a[2][k]});
    const double bmin = std::min({b[0][k], b[1][k], b[2][k]}), bmax = std::max({b[0][k], b[1][k], b[2][k]});
    if (amax < bmin || bmax < amin) return true;
  }
  return false;
}

ClosestPoints Better(const ClosestPoints& x, const ClosestPoints& y) {
  return y.distance_squared < x.distance_squared ? y : x;
}

ClosestPoints PointSegmentClosest(const Vec3d& p, const Vec3d& a, const Vec3d& b) {
  const Vec3d ab = Sub(b, a);
  const double l2 = Dot(ab, ab);
  const double s = l2 > 0 ? std::clamp(Dot(Sub(p, a), ab) / l2, 0.0, 1.0) : 0.0;
  ClosestPoints out;
  out.on_a = p;
  out.on_b = Add(a, Scale(ab, s));
  out.distance_squared = Dist2(p, out.on_b);
  return out;
}

// Closest points of segment pq and triangle abc, assuming the segment does not cross the triangle's
// interior transversally (then a closest pair involves an endpoint or a triangle edge).
ClosestPoints SegmentTriangleFeatures(const Vec3d& p, const Vec3d& q, const Vec3d& a, const Vec3d& b,
                                      const Vec3d& c) {
  ClosestPoints best = PointTriangleClosest(p, a, b, c);
  best = Better(best, PointTriangleClosest(q, a, b, c));
  best = Better(best, SegmentSegmentClosest(p, q, a, b));
  best = Better(best, SegmentSegmentClosest(p, q, b, c));
  best = Better(best, SegmentSegmentClosest(p, q, c, a));
  return best;
}

// A point common to segment pq and triangle t, which are known to meet.
Vec3d MeetingPoint(const Vec3d& p, const Vec3d& q, const PreparedTriangle& t) {
  if (t.axis >= 0) {
    const Vec3d n = Cross(Sub(t.v[1], t.v[0]), Sub(t.v[2], t.v[0]));
    const double dp = Dot(Sub(p, t.v[0]), n), dq = Dot(Sub(q, t.v[0]), n);
    if ((dp > 0 && dq < 0) || (dp < 0 && dq > 0)) {  // a transversal crossing: the plane point
      const double s = std::clamp(dp / (dp - dq), 0.0, 1.0);
      return Add(p, Scale(Sub(q, p), s));
    }
  }
  const ClosestPoints c = SegmentTriangleFeatures(p, q, t.v[0], t.v[1], t.v[2]);
  return Scale(Add(c.on_a, c.on_b), 0.5);
}

}  // namespace

bool SegmentsMeet(const Vec3d& p, const Vec3d& q, const Vec3d& r, const Vec3d& s) {
  if (O3(p, q, r, s) != 0) return false;
  // Coplanar: project along an axis that keeps the four points' plane (or line) one-to-one.
  int k = -1;
  const Vec3d* triples[4][3] = {{&p, &q, &r}, {&p, &q, &s}, {&r, &s, &p}, {&r, &s, &q}};
  for (const auto& t : triples)
    if ((k = DropAxisOf(*t[0], *t[1], *t[2])) >= 0) break;
  if (k < 0) {  // all on one line (or one point): drop an axis the line is not parallel to
    Vec3d d = Sub(q, p);
    if (d.x == 0 && d.y == 0 && d.z == 0) d = Sub(s, r);
    if (d.x == 0 && d.y == 0 && d.z == 0) d = Sub(r, p);
    if (d.x == 0 && d.y == 0 && d.z == 0) return true;  // four equal points
    const int j = d.x != 0 ? 0 : (d.y != 0 ? 1 : 2);
    k = (j + 1) % 3;
  }
  return SegmentsMeet2(Drop(p, k), Drop(q, k), Drop(r, k), Drop(s, k));
}

bool SegmentMeetsTriangle(const Vec3d& p, const Vec3d& q, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d t[3] = {a, b, c};
  return SegmentMeetsPrepared(p, q, PreparedTriangle(t));
}

bool TrianglesMeet(const Vec3d a[3], const Vec3d b[3]) {
  if (BoxesApart(a, b)) return false;
  const PreparedTriangle ta(a), tb(b);
  int sb[3] = {0, 0, 0}, sa[3] = {0, 0, 0};  // corners of b against a's plane, and of a against b's
  if (ta.axis >= 0) {
    for (int i = 0; i < 3; ++i) sb[i] = O3(a[0], a[1], a[2], b[i]);
    if ((sb[0] > 0 && sb[1] > 0 && sb[2] > 0) || (sb[0] < 0 && sb[1] < 0 && sb[2] < 0)) return false;
  }
  if (tb.axis >= 0) {
    for (int i = 0; i < 3; ++i) sa[i] = O3(b[0], b[1], b[2], a[i]);
    if ((sa[0] > 0 && sa[1] > 0 && sa[2] > 0) || (sa[0] < 0 && sa[1] < 0 && sa[2] < 0)) return false;
  }
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    if (tb.axis >= 0 ? SegmentMeetsPrepared(a[i], a[j], sa[i], sa[j], tb)
                     : SegmentsMeet(a[i], a[j], tb.lo, tb.hi))
      return true;
    if (ta.axis >= 0 ? SegmentMeetsPrepared(b[i], b[j], sb[i], sb[j], ta)
                     : SegmentsMeet(b[i], b[j], ta.lo, ta.hi))
      return true;
  }
  return false;
}

ClosestPoints SegmentSegmentClosest(const Vec3d& p, const Vec3d& q, const Vec3d& r, const Vec3d& s) {
  // Ericson, Real-Time Collision Detection, 5.1.9, with exact zero tests for point "segments".
  const Vec3d d1 = Sub(q, p), d2 = Sub(s, r), r0 = Sub(p, r);
  const double a = Dot(d1, d1), e = Dot(d2, d2), f = Dot(d2, r0);
  double sp = 0, tp = 0;
  if (a == 0 && e == 0) {
    sp = tp = 0;
  } else if (a == 0) {
    tp = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = Dot(d1, r0);
    if (e == 0) {
      sp = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = Dot(d1, d2), denom = a * e - b * b;
      sp = denom > 0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      tp = (b * sp + f) / e;
      if (tp < 0) {
        tp = 0;
        sp = std::clamp(-c / a, 0.0, 1.0);
      } else if (tp > 1) {
        tp = 1;
        sp = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  ClosestPoints out;
  out.on_a = Add(p, Scale(d1, sp));
  out.on_b = Add(r, Scale(d2, tp));
  out.distance_squared = Dist2(out.on_a, out.on_b);
  return out;
}

ClosestPoints PointTriangleClosest(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d ab = Sub(b, a), ac = Sub(c, a), bc = Sub(c, b);
  const Vec3d n = Cross(ab, ac);
  const double n2 = Dot(n, n);
  const double longest2 = std::max({Dot(ab, ab), Dot(ac, ac), Dot(bc, bc)});
  // Slivers thinner than 1e-10 x their longest edge are measured as their edges (the face projection is
  // ill-conditioned there, and the edges are within that thickness of every interior point).
  if (n2 > 1e-20 * longest2 * longest2) {
    const Vec3d ap = Sub(p, a);
    const Vec3d proj = Sub(p, Scale(n, Dot(ap, n) / n2));
    if (Dot(Cross(ab, Sub(proj, a)), n) >= 0 && Dot(Cross(bc, Sub(proj, b)), n) >= 0 &&
        Dot(Cross(Sub(a, c), Sub(proj, c)), n) >= 0) {
      ClosestPoints out;
      out.on_a = p;
      out.on_b = proj;
      out.distance_squared = Dist2(p, proj);
      return out;
    }
  }
  ClosestPoints best = PointSegmentClosest(p, a, b);
  best = Better(best, PointSegmentClosest(p, b, c));
  best = Better(best, PointSegmentClosest(p, c, a));
  return best;
}

ClosestPoints TriangleTriangleClosest(const Vec3d a[3], const Vec3d b[3]) {
  if (TrianglesMeet(a, b)) {
    const PreparedTriangle ta(a), tb(b);
    ClosestPoints out;
    out.distance_squared = 0;
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      if (SegmentMeetsPrepared(a[i], a[j], tb)) {
        out.on_a = out.on_b = MeetingPoint(a[i], a[j], tb);
        return out;
      }
      if (SegmentMeetsPrepared(b[i], b[j], ta)) {
        out.on_a = out.on_b = MeetingPoint(b[i], b[j], ta);
        return out;
      }
    }
  }
  return TriangleFeatureClosest(a, b);
}

ClosestPoints TriangleFeatureClosest(const Vec3d a[3], const Vec3d b[3]) {
  ClosestPoints best;
  best.distance_squared = INFINITY;
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3;
    for (int j = 0; j < 3; ++j) best = Better(best, SegmentSegmentClosest(a[i], a[i1], b[j], b[(j + 1) % 3]));
    best = Better(best, PointTriangleClosest(a[i], b[0], b[1], b[2]));
    ClosestPoints r = PointTriangleClosest(b[i], a[0], a[1], a[2]);
    std::swap(r.on_a, r.on_b);
    best = Better(best, r);
  }
  return best;
}

}  // namespace mktree
