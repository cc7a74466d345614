#include "engine/geometry/mesh_separation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "engine/geometry/kdop.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/geometry/triangle_hierarchy.h"
#include "engine/geometry/triangle_pair.h"

namespace mktree {

struct ClashShape::Impl {
  Impl(const Mesh& m, const std::optional<EdgeCheck>& e)
      : mesh(m), edges(e ? *e : CheckEdges(m)), bounds(m.Bounds()), kdop(Kdop::Of(m)), hierarchy(m) {
    if (edges.closed && m.triangle_count() > 0) {
      SolidClassifierOptions options;
      options.edges = edges;
      // Containment asks one point per component; the depth bound asks one per vertex inside.
      options.expected_queries = kGridBreakEven;
      classifier.emplace(m, options);
      component_vertices = ComponentVertices(m);
    }
  }

  // One vertex of each connected component (vertices with equal coordinates are one point), so that a
  // component of A inside B is found even when another component of A is not.
  static std::vector<uint32_t> ComponentVertices(const Mesh& m) {
    const size_t n = m.vertex_count();
    std::vector<uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    auto at = [&](uint32_t i) { return &m.vertices[3 * size_t{i}]; };
    std::sort(order.begin(), order.end(), [&](uint32_t x, uint32_t y) {
      return std::lexicographical_compare(at(x), at(x) + 3, at(y), at(y) + 3);
    });
    std::vector<uint32_t> parent(n);
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](uint32_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    auto unite = [&](uint32_t x, uint32_t y) { parent[find(x)] = find(y); };
    for (size_t i = 1; i < n; ++i)
      if (std::equal(at(order[i]), at(order[i]) + 3, at(order[i - 1]))) unite(order[i], order[i - 1]);
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      unite(m.triangles[3 * t], m.triangles[3 * t + 1]);
      unite(m.triangles[3 * t], m.triangles[3 * t + 2]);
    }
    std::vector<char> seen(n, 0);
    std::vector<uint32_t> reps;
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      const uint32_t v = m.triangles[3 * t];
      const uint32_t r = find(v);
      if (!seen[r]) {
        seen[r] = 1;
        reps.push_back(v);
      }
    }
    return reps;
  }

  bool solid() const { return classifier.has_value(); }

  const Mesh& mesh;
  EdgeCheck edges;
  Box3d bounds;
  Kdop kdop;
  TriangleHierarchy hierarchy;
  std::optional<SolidClassifier> classifier;  // closed meshes only: open ones are surfaces
  std::vector<uint32_t> component_vertices;
};

ClashShape::ClashShape(const Mesh& mesh, const std::optional<EdgeCheck>& edges)
    : impl_(std::make_unique<Impl>(mesh, edges)) {}
ClashShape::~ClashShape() = default;
ClashShape::ClashShape(ClashShape&&) noexcept = default;
ClashShape& ClashShape::operator=(ClashShape&&) noexcept = default;

const Mesh& ClashShape::mesh() const { return impl_->mesh; }
bool ClashShape::solid() const { return impl_->solid(); }
Box3d ClashShape::bounds() const { return impl_->bounds; }
const Kdop& ClashShape::kdop() const { return impl_->kdop; }

size_t ClashShape::MemoryBytes() const {
  // The classifier's grid is not exposed; count its triangle lists as one index per triangle per cell
  // row, an estimate.
  size_t bytes =
      sizeof(Impl) + impl_->hierarchy.MemoryBytes() + impl_->component_vertices.capacity() * sizeof(uint32_t);
  if (impl_->classifier && impl_->classifier->has_grid()) bytes += 8 * impl_->mesh.triangle_count();
  return bytes;
}

Status ValidateClashMesh(const Mesh& mesh) {
  if (mesh.vertices.size() % 3 != 0 || mesh.triangles.size() % 3 != 0)
    return Status::InvalidArgument("mesh: vertex or index array length is not a multiple of 3");
  for (size_t i = 0; i < mesh.vertices.size(); ++i)
    if (!std::isfinite(mesh.vertices[i]))
      return Status::InvalidArgument("mesh: vertex " + std::to_string(i / 3) + " is not finite");
  const size_t n = mesh.vertex_count();
  for (size_t i = 0; i < mesh.triangles.size(); ++i)
    if (mesh.triangles[i] >= n)
      return Status::InvalidArgument("mesh: triangle " + std::to_string(i / 3) + " uses vertex " +
                                     std::to_string(mesh.triangles[i]) + " of " + std::to_string(n));
  return Status::Ok();
}

namespace {

using Impl = ClashShape::Impl;

Vec3d VertexAt(const Mesh& m, size_t i) {
  return {m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]};
}

// Filtered all-pairs meeting test for small meshes: only triangles whose boxes meet the other mesh's box
// take part. Returns the meeting corners.
bool BruteForceMeeting(const TriangleHierarchy& a, const TriangleHierarchy& b, Vec3d* ta, Vec3d* tb,
                       uint64_t* tests) {
  const Box3d ba = a.bounds(), bb = b.bounds();
  auto box_of = [](const TriangleHierarchy::Triangle& t) {
    Box3d x;
    for (const Vec3d& v : t) x.Extend(v.x, v.y, v.z);
    return x;
  };
  auto meet = [](const Box3d& x, const Box3d& y) {
    for (int k = 0; k < 3; ++k)
      if (x.max[k] < y.min[k] || y.max[k] < x.min[k]) return false;
    return true;
  };
  Box3d boxes_b[kBruteForceTriangles];
  uint32_t idx_b[kBruteForceTriangles];
  size_t nb = 0;
  for (uint32_t j = 0; j < b.triangle_count(); ++j) {
    const Box3d x = box_of(b.triangle(j));
    if (meet(x, ba)) {
      boxes_b[nb] = x;
      idx_b[nb++] = j;
    }
  }
  for (uint32_t i = 0; i < a.triangle_count() && nb > 0; ++i) {
    const Box3d x = box_of(a.triangle(i));
    if (!meet(x, bb)) continue;
    for (size_t k = 0; k < nb; ++k) {
      if (!meet(x, boxes_b[k])) continue;
      ++*tests;
      if (TrianglesMeet(a.triangle(i).data(), b.triangle(idx_b[k]).data())) {
        std::copy_n(a.triangle(i).data(), 3, ta);
        std::copy_n(b.triangle(idx_b[k]).data(), 3, tb);
        return true;
      }
    }
  }
  return false;
}

bool FindMeetingTriangles(const Impl& a, const Impl& b, Vec3d* ta, Vec3d* tb, uint64_t* tests) {
  if (a.hierarchy.triangle_count() <= kBruteForceTriangles &&
      b.hierarchy.triangle_count() <= kBruteForceTriangles)
    return BruteForceMeeting(a.hierarchy, b.hierarchy, ta, tb, tests);
  TriangleHierarchy::Pair pair;
  if (!TriangleHierarchy::FindMeeting(a.hierarchy, b.hierarchy, &pair, tests)) return false;
  std::copy_n(a.hierarchy.triangle(pair.a).data(), 3, ta);
  std::copy_n(b.hierarchy.triangle(pair.b).data(), 3, tb);
  return true;
}

// The deepest vertex of solid `x` inside solid `y`: its distance to y's surface (0 when none is inside).
double DeepestVertex(const Impl& x, const Impl& y, NarrowStats* st) {
  double deepest2 = 0;
  for (size_t i = 0; i < x.mesh.vertex_count(); ++i) {
    const Vec3d v = VertexAt(x.mesh, i);
    if (!y.kdop.Contains(v)) continue;
    ++st->containment_tests;
    if (!y.classifier->Contains(v)) continue;
    deepest2 = std::max(deepest2, y.hierarchy.PointDistanceSquared(v));
  }
  return std::sqrt(deepest2);
}

void SetDepth(const Impl& a, const Impl& b, double gap, Separation* r, NarrowStats* st) {
  r->depth_upper = std::max(0.0, -gap);
  r->distance = -r->depth_upper;
  if (!a.solid() || !b.solid()) return;  // a surface has no inside: depth_lower stays 0
  const double lower = std::max(DeepestVertex(a, b, st), DeepestVertex(b, a, st));
  r->depth_lower = std::min(lower, r->depth_upper);
}

// A vertex of some component of solid `x` inside solid `y`, when no triangles meet.
bool ComponentInside(const Impl& x, const Impl& y, Vec3d* point, NarrowStats* st) {
  for (uint32_t v : x.component_vertices) {
    const Vec3d p = VertexAt(x.mesh, v);
    if (!y.kdop.Contains(p)) continue;
    ++st->containment_tests;
    if (y.classifier->Contains(p)) {
      *point = p;
      return true;
    }
  }
  return false;
}

}  // namespace

Separation Separate(const ClashShape& shape_a, const ClashShape& shape_b, double max_distance,
                    NarrowStats* stats) {
  const Impl& a = shape_a.impl();
  const Impl& b = shape_b.impl();
  NarrowStats st;
  Separation r;
  r.meeting = Meeting::kApart;
  r.distance = std::numeric_limits<double>::infinity();
  const double limit = max_distance > 0 ? max_distance : 0;
  const double gap = a.kdop.Gap(b.kdop);
  if (a.hierarchy.triangle_count() == 0 || b.hierarchy.triangle_count() == 0) {
    // Nothing to meet.
  } else if (limit > 0 ? gap >= limit : gap > 0) {
    ++st.bound_rejects;
  } else if (Vec3d ta[3], tb[3]; FindMeetingTriangles(a, b, ta, tb, &st.triangle_tests)) {
    r.meeting = Meeting::kSurfacesMeet;
    const ClosestPoints c = TriangleTriangleClosest(ta, tb);
    r.point_a = r.point_b = c.on_a;
    SetDepth(a, b, gap, &r, &st);
  } else {
    Vec3d p;
    if (a.solid() && b.solid()) {
      if (ComponentInside(a, b, &p, &st))
        r.meeting = Meeting::kAInsideB;
      else if (ComponentInside(b, a, &p, &st))
        r.meeting = Meeting::kBInsideA;
    }
    if (r.meeting != Meeting::kApart) {
      r.point_a = r.point_b = p;
      SetDepth(a, b, gap, &r, &st);
    } else if (limit > 0) {
      ClosestPoints c;
      if (TriangleHierarchy::ClosestBelow(a.hierarchy, b.hierarchy, limit, &c, &st.triangle_tests)) {
        // The triangles do not meet (exact), so the gap is positive even when it rounds to 0.
        r.distance = std::max(std::sqrt(c.distance_squared), std::numeric_limits<double>::denorm_min());
        r.point_a = c.on_a;
        r.point_b = c.on_b;
      }
    }
  }
  if (stats) stats->Add(st);
  return r;
}

}  // namespace mktree
