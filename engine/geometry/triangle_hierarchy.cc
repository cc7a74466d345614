#include "engine/geometry/triangle_hierarchy.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

namespace mktree {
namespace {

double BoxExtent(const Box3d& b) {
  return (b.max[0] - b.min[0]) + (b.max[1] - b.min[1]) + (b.max[2] - b.min[2]);
}

// Nodes of the subtree over `count` triangles as Build splits them.
size_t NodeCount(uint32_t count) {
  if (count <= TriangleHierarchy::kLeafTriangles) return 1;
  return 1 + NodeCount(count / 2) + NodeCount(count - count / 2);
}

double PointBoxDistanceSquared(const Vec3d& p, const Box3d& b) {
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double d = std::max({b.min[k] - p[k], p[k] - b.max[k], 0.0});
    d2 += d * d;
  }
  return d2;
}

}  // namespace

double BoxDistanceSquared(const Box3d& a, const Box3d& b) {
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double d = std::max({b.min[k] - a.max[k], a.min[k] - b.max[k], 0.0});
    d2 += d * d;
  }
  return d2;
}

TriangleHierarchy::TriangleHierarchy(const TriangleHierarchy& base, const Mesh& moved, const Vec3d& shift)
    : nodes_(base.nodes_),
      vertices_(moved.vertices.data()),
      triangles_(moved.triangles.data()),
      mesh_index_(base.mesh_index_) {
  const double s[3] = {shift.x, shift.y, shift.z};
  for (Node& n : nodes_) {
    for (int k = 0; k < 3; ++k) {
      n.box.min[k] += s[k];
      n.box.max[k] += s[k];
    }
  }
}

TriangleHierarchy::TriangleHierarchy(const Mesh& mesh)
    : vertices_(mesh.vertices.data()), triangles_(mesh.triangles.data()) {
  const size_t n = mesh.triangle_count();
  if (n == 0) return;
  mesh_index_.resize(n);
  // Centroid coordinates by axis (centroids[axis * n + t]): the median splits compare them directly.
  // Small meshes (most clash candidates) reuse this thread's scratch: one allocation less per object.
  constexpr size_t kScratchTriangles = 4096;
  thread_local std::vector<double> scratch;
  std::vector<double> own;
  std::vector<double>& centroids = n <= kScratchTriangles ? scratch : own;
  centroids.resize(3 * n);
  for (size_t t = 0; t < n; ++t) {
    Vec3d c{0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      const double* v = &mesh.vertices[3 * size_t{mesh.triangles[3 * t + k]}];
      c = {c.x + v[0], c.y + v[1], c.z + v[2]};
    }
    centroids[t] = c.x / 3;
    centroids[n + t] = c.y / 3;
    centroids[2 * n + t] = c.z / 3;
    mesh_index_[t] = static_cast<uint32_t>(t);
  }
  // The exact node count: a reserve that falls short would double the array (MemoryBytes must be true).
  nodes_.reserve(NodeCount(static_cast<uint32_t>(n)));
  nodes_.emplace_back();
  Build(0, 0, static_cast<uint32_t>(n), centroids);
  // Boxes, bottom-up (children always follow their parent in the array).
  for (size_t i = nodes_.size(); i-- > 0;) {
    Node& node = nodes_[i];
    node.box = Box3d{};
    if (node.leaf()) {
      for (uint32_t t = node.first; t < node.first + node.count; ++t)
        for (const Vec3d& v : triangle(t)) node.box.Extend(v.x, v.y, v.z);
    } else {
      for (uint32_t c = node.first; c < node.first + 2; ++c) {
        node.box.Extend(nodes_[c].box.min[0], nodes_[c].box.min[1], nodes_[c].box.min[2]);
        node.box.Extend(nodes_[c].box.max[0], nodes_[c].box.max[1], nodes_[c].box.max[2]);
      }
    }
  }
}

// Builds the subtree of node `self` over mesh_index_[first, first + count).
void TriangleHierarchy::Build(uint32_t self, uint32_t first, uint32_t count,
                              const std::vector<double>& centroids) {
  if (count <= kLeafTriangles) {
    nodes_[self].first = first;
    nodes_[self].count = count;
    return;
  }
  const size_t n = mesh_index_.size();
  double extent[3];
  for (int k = 0; k < 3; ++k) {
    const double* c = centroids.data() + k * n;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (uint32_t i = first; i < first + count; ++i) {
      lo = std::min(lo, c[mesh_index_[i]]);
      hi = std::max(hi, c[mesh_index_[i]]);
    }
    extent[k] = hi - lo;
  }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (extent[k] > extent[axis]) axis = k;
  const uint32_t half = count / 2;
  uint32_t* begin = mesh_index_.data() + first;
  const double* key = centroids.data() + axis * n;
  std::nth_element(begin, begin + half, begin + count,
                   [key](uint32_t x, uint32_t y) { return key[x] < key[y]; });
  const uint32_t left = static_cast<uint32_t>(nodes_.size());
  nodes_[self].first = left;
  nodes_[self].count = 0;
  nodes_.resize(nodes_.size() + 2);
  Build(left, first, half, centroids);
  Build(left + 1, first + half, count - half, centroids);
}

size_t TriangleHierarchy::MemoryBytes() const {
  return nodes_.capacity() * sizeof(Node) + mesh_index_.capacity() * sizeof(uint32_t);
}

namespace {

struct NodePair {
  uint32_t a, b;
};

// True when every corner of `u` is strictly beyond t's plane on one side by clearly more than
// sqrt(best2) (a margin above the rounding of both this test and the distance computation): the
// triangles are then at least that far apart (the distance from u to the plane is attained at a
// corner), and the exact distance test could not accept the pair.
bool PlaneFarApart(const TriangleHierarchy::Triangle& t, const TriangleHierarchy::Triangle& u, double best2) {
  const Vec3d e1{t[1].x - t[0].x, t[1].y - t[0].y, t[1].z - t[0].z};
  const Vec3d e2{t[2].x - t[0].x, t[2].y - t[0].y, t[2].z - t[0].z};
  const Vec3d n{e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x};
  const double nn = n.x * n.x + n.y * n.y + n.z * n.z;
  if (!(nn > 0)) return false;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, reach = 0;
  for (const Vec3d& v : u) {
    const Vec3d d{v.x - t[0].x, v.y - t[0].y, v.z - t[0].z};
    const double sd = n.x * d.x + n.y * d.y + n.z * d.z;
    lo = std::min(lo, sd);
    hi = std::max(hi, sd);
    reach = std::max(reach, std::fabs(d.x) + std::fabs(d.y) + std::fabs(d.z));
  }
  // Rounding of n and of the dot products: a few ulp of |e1|_1 |e2|_1 reach.
  const double l1 = (std::fabs(e1.x) + std::fabs(e1.y) + std::fabs(e1.z)) *
                    (std::fabs(e2.x) + std::fabs(e2.y) + std::fabs(e2.z));
  const double err = 64 * std::numeric_limits<double>::epsilon() * l1 * reach;
  const double m = lo > 0 ? lo - err : hi < 0 ? -hi - err : 0;
  if (!(m > 0)) return false;
  const double len = std::sqrt(nn);
  const double need = std::sqrt(best2) * (1 + 1e-6) + 1e-12 * (len + reach);
  return m > need * len;
}

// Which node of the pair to open: the inner one, or the larger of two inner ones.
bool OpenA(const TriangleHierarchy::Node& na, const TriangleHierarchy::Node& nb) {
  if (na.leaf()) return false;
  if (nb.leaf()) return true;
  return BoxExtent(na.box) >= BoxExtent(nb.box);
}

}  // namespace

namespace {

// FindMeeting's walk; kMoved: a's corners and boxes plus `shift` (each sum rounded as a moved copy's).
template <bool kMoved>
bool FindMeetingWalk(const TriangleHierarchy& a, const TriangleHierarchy& b, const Vec3d& shift,
                     TriangleHierarchy::Pair* found, uint64_t* tests) {
  using Node = TriangleHierarchy::Node;
  using Triangle = TriangleHierarchy::Triangle;
  constexpr uint32_t kLeaf = TriangleHierarchy::kLeafTriangles;
  const std::vector<Node>& an = a.nodes();
  const std::vector<Node>& bn = b.nodes();
  if (an.empty() || bn.empty()) return false;
  const double sh[3] = {shift.x, shift.y, shift.z};
  auto box_of_a = [&](const Node& n) {
    if constexpr (!kMoved) return n.box;
    Box3d m = n.box;
    for (int k = 0; k < 3; ++k) {
      m.min[k] += sh[k];
      m.max[k] += sh[k];
    }
    return m;
  };
  auto triangle_of_a = [&](uint32_t i) {
    Triangle t = a.triangle(i);
    if constexpr (kMoved)
      for (Vec3d& v : t) v = {v.x + shift.x, v.y + shift.y, v.z + shift.z};
    return t;
  };
  uint64_t n_tests = 0;
  bool met = false;
  thread_local std::vector<NodePair> stack;  // per thread: no allocation per query
  stack.clear();
  stack.push_back({0, 0});
  while (!stack.empty() && !met) {
    const NodePair p = stack.back();
    stack.pop_back();
    const Node& na = an[p.a];
    const Node& nb = bn[p.b];
    if (!BoxesMeet(box_of_a(na), nb.box)) continue;
    if (na.leaf() && nb.leaf()) {
      // b's triangles and boxes once per leaf pair, not once per triangle of a (the same tests in the
      // same order).
      std::array<Triangle, kLeaf> tb;
      std::array<Box3d, kLeaf> boxes_b;
      uint32_t nb_ready = 0;
      for (uint32_t i = na.first; i < na.first + na.count && !met; ++i) {
        const Triangle ti = triangle_of_a(i);
        const Box3d bi = TriangleBox(ti);
        if (!BoxesMeet(bi, nb.box)) continue;
        for (; nb_ready < nb.count; ++nb_ready) {
          tb[nb_ready] = b.triangle(nb.first + nb_ready);
          boxes_b[nb_ready] = TriangleBox(tb[nb_ready]);
        }
        for (uint32_t j = 0; j < nb.count; ++j) {
          if (!BoxesMeet(bi, boxes_b[j])) continue;
          ++n_tests;
          if (TrianglesMeet(ti.data(), tb[j].data())) {
            *found = {i, nb.first + j};
            met = true;
            break;
          }
        }
      }
    } else if (OpenA(na, nb)) {
      stack.push_back({na.first + 1, p.b});
      stack.push_back({na.first, p.b});
    } else {
      stack.push_back({p.a, nb.first + 1});
      stack.push_back({p.a, nb.first});
    }
  }
  if (tests) *tests += n_tests;
  return met;
}

}  // namespace

bool TriangleHierarchy::FindMeeting(const TriangleHierarchy& a, const TriangleHierarchy& b, Pair* found,
                                    uint64_t* tests) {
  return FindMeetingWalk<false>(a, b, Vec3d{0, 0, 0}, found, tests);
}

bool TriangleHierarchy::FindMeetingMoved(const TriangleHierarchy& a, const Vec3d& shift,
                                         const TriangleHierarchy& b, uint64_t* tests) {
  Pair found;
  return FindMeetingWalk<true>(a, b, shift, &found, tests);
}

bool TriangleHierarchy::ClosestBelow(const TriangleHierarchy& a, const TriangleHierarchy& b, double bound,
                                     ClosestPoints* closest, uint64_t* tests) {
  if (a.nodes_.empty() || b.nodes_.empty() || !(bound > 0)) return false;
  uint64_t n_tests = 0;
  double best2 = bound * bound;
  bool found = false;
  struct Item {
    uint32_t a, b;
    double d2;
  };
  thread_local std::vector<Item> stack;
  stack.clear();
  stack.push_back({0, 0, BoxDistanceSquared(a.nodes_[0].box, b.nodes_[0].box)});
  while (!stack.empty()) {
    const Item p = stack.back();
    stack.pop_back();
    if (p.d2 >= best2) continue;
    const Node& na = a.nodes_[p.a];
    const Node& nb = b.nodes_[p.b];
    if (na.leaf() && nb.leaf()) {
      for (uint32_t i = na.first; i < na.first + na.count; ++i) {
        const Triangle ti = a.triangle(i);
        const Box3d bi = TriangleBox(ti);
        if (BoxDistanceSquared(bi, nb.box) >= best2) continue;
        for (uint32_t j = nb.first; j < nb.first + nb.count; ++j) {
          const Triangle tj = b.triangle(j);
          if (BoxDistanceSquared(bi, TriangleBox(tj)) >= best2) continue;
          if (PlaneFarApart(ti, tj, best2) || PlaneFarApart(tj, ti, best2)) continue;
          ++n_tests;
          const ClosestPoints c = TriangleFeatureClosest(ti.data(), tj.data());
          if (c.distance_squared < best2) {
            best2 = c.distance_squared;
            *closest = c;
            found = true;
          }
        }
      }
      continue;
    }
    Item c0, c1;
    if (OpenA(na, nb)) {
      c0 = {na.first, p.b, BoxDistanceSquared(a.nodes_[na.first].box, nb.box)};
      c1 = {na.first + 1, p.b, BoxDistanceSquared(a.nodes_[na.first + 1].box, nb.box)};
    } else {
      c0 = {p.a, nb.first, BoxDistanceSquared(na.box, b.nodes_[nb.first].box)};
      c1 = {p.a, nb.first + 1, BoxDistanceSquared(na.box, b.nodes_[nb.first + 1].box)};
    }
    if (c0.d2 < c1.d2) std::swap(c0, c1);  // the nearer pair is popped first
    if (c0.d2 < best2) stack.push_back(c0);
    if (c1.d2 < best2) stack.push_back(c1);
  }
  if (tests) *tests += n_tests;
  return found;
}

double TriangleHierarchy::PointDistanceSquared(const Vec3d& p, double enough) const {
  double best2 = std::numeric_limits<double>::infinity();
  if (nodes_.empty()) return best2;
  struct Item {
    uint32_t node;
    double d2;
  };
  thread_local std::vector<Item> stack;
  stack.clear();
  stack.push_back({0, PointBoxDistanceSquared(p, nodes_[0].box)});
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    if (it.d2 >= best2) continue;
    const Node& n = nodes_[it.node];
    if (n.leaf()) {
      for (uint32_t t = n.first; t < n.first + n.count; ++t) {
        const Triangle tr = triangle(t);
        best2 = std::min(best2, PointTriangleClosest(p, tr[0], tr[1], tr[2]).distance_squared);
      }
      if (best2 <= enough) return best2;
      continue;
    }
    Item c0{n.first, PointBoxDistanceSquared(p, nodes_[n.first].box)};
    Item c1{n.first + 1, PointBoxDistanceSquared(p, nodes_[n.first + 1].box)};
    if (c0.d2 < c1.d2) std::swap(c0, c1);
    if (c0.d2 < best2) stack.push_back(c0);
    if (c1.d2 < best2) stack.push_back(c1);
  }
  return best2;
}

void TriangleHierarchy::SegmentCrossings(const Vec3d& p, const Vec3d& q, std::vector<double>* out) const {
  if (nodes_.empty()) return;
  Box3d seg;
  seg.Extend(p.x, p.y, p.z);
  seg.Extend(q.x, q.y, q.z);
  const Vec3d d{q.x - p.x, q.y - p.y, q.z - p.z};
  thread_local std::vector<uint32_t> stack;
  stack.assign(1, 0);
  while (!stack.empty()) {
    const Node& n = nodes_[stack.back()];
    stack.pop_back();
    if (!BoxesMeet(n.box, seg)) continue;
    if (!n.leaf()) {
      stack.push_back(n.first);
      stack.push_back(n.first + 1);
      continue;
    }
    for (uint32_t t = n.first; t < n.first + n.count; ++t) {
      // Moller-Trumbore on the segment.
      const Triangle tr = triangle(t);
      const Vec3d e1{tr[1].x - tr[0].x, tr[1].y - tr[0].y, tr[1].z - tr[0].z};
      const Vec3d e2{tr[2].x - tr[0].x, tr[2].y - tr[0].y, tr[2].z - tr[0].z};
      const Vec3d h{d.y * e2.z - d.z * e2.y, d.z * e2.x - d.x * e2.z, d.x * e2.y - d.y * e2.x};
      const double det = e1.x * h.x + e1.y * h.y + e1.z * h.z;
      if (det == 0) continue;
      const double f = 1 / det;
      const Vec3d s{p.x - tr[0].x, p.y - tr[0].y, p.z - tr[0].z};
      const double u = f * (s.x * h.x + s.y * h.y + s.z * h.z);
      if (u < 0 || u > 1) continue;
      const Vec3d c{s.y * e1.z - s.z * e1.y, s.z * e1.x - s.x * e1.z, s.x * e1.y - s.y * e1.x};
      const double v = f * (d.x * c.x + d.y * c.y + d.z * c.z);
      if (v < 0 || u + v > 1) continue;
      const double at = f * (e2.x * c.x + e2.y * c.y + e2.z * c.z);
      if (at > 0 && at < 1) out->push_back(at);
    }
  }
}

}  // namespace mktree
