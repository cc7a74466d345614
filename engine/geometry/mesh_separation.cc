#include "engine/geometry/mesh_separation.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cfloat>
#include <cmath>
#include <limits>
#include <mutex>
#include <numeric>
#include <string>
#include <vector>

#include "engine/geometry/kdop.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/geometry/touch_certificate.h"
#include "engine/geometry/triangle_hierarchy.h"
#include "engine/geometry/triangle_pair.h"

namespace mktree {

struct ClashShape::Impl {
  Impl(const Mesh& m, const std::optional<EdgeCheck>& e)
      : mesh(m), edges(e ? *e : CheckEdges(m)), bounds(m.Bounds()), kdop(Kdop::Of(m)) {
    is_solid = edges.closed && m.triangle_count() > 0;
    double largest = 0;
    for (double c : mesh.vertices) largest = std::max(largest, std::fabs(c));
    // Rounding of a projection onto a unit vector (|d| = 1 within a few ulp): a few ulp of the largest
    // coordinate sum.
    projection_slack = 16 * DBL_EPSILON * 3 * largest;
    // Depths below the classifier's surface tolerance are not depths (such points count as on the surface).
    negligible2 = SurfaceTolerance(bounds) * SurfaceTolerance(bounds);
  }

  // The parts below the 26-DOP are built on first use (most candidate pairs never need some of them);
  // Separate may run on several threads at once, hence call_once. `st` counts what was built.
  const TriangleHierarchy& Hierarchy(NarrowStats* st) const {
    std::call_once(hierarchy_once, [&] {
      hierarchy = std::make_unique<TriangleHierarchy>(mesh);
      ++st->hierarchies_built;
    });
    return *hierarchy;
  }
  // Solids only. Apart from the vertex lists: a pair whose depth the other's classifier decides (a
  // vertex of this object deep in the other) never needs this object's.
  const SolidClassifier& Classifier(NarrowStats* st) const {
    std::call_once(classifier_once, [&] {
      SolidClassifierOptions options;
      options.edges = edges;
      // Containment asks one point per component; the depth bound asks one per vertex inside.
      options.expected_queries = kGridBreakEven;
      classifier = std::make_unique<SolidClassifier>(mesh, options);
      ++st->classifiers_built;
    });
    return *classifier;
  }
  // Solids only: vertex_lists.
  void BuildVertexLists() const {
    std::call_once(vertices_once, [&] {
      auto lists = std::make_unique<VertexLists>();
      lists->component = ComponentVertices(mesh, &lists->distinct);
      vertex_lists = std::move(lists);
      vertices_built.store(true, std::memory_order_release);
    });
  }
  void BuildDirections() const {
    std::call_once(directions_once, [&] { FaceDirections(); });
  }

  // The distinct unit normals of a small mesh's triangles with the vertices' projection intervals on
  // them: more candidate directions for the depth upper bound (for convex solids meeting face to face
  // the exact depth is attained along one of them).
  void FaceDirections() const {
    if (mesh.triangle_count() > kMaxDepthDirectionTriangles ||
        mesh.vertex_count() > kMaxDepthDirectionVertices)
      return;
    // The directions' x components ascending, with their index: a direction within 1e-9 (L1) of n has
    // its x within 1e-9 of n.x, so only a short run of them is compared (the same set as comparing all).
    struct ByX {
      double x;
      uint32_t k;
    };
    std::array<ByX, kMaxDepthDirections> by_x;
    size_t n_dirs = 0;
    for (size_t t = 0; t < mesh.triangle_count() && directions.size() < kMaxDepthDirections; ++t) {
      const Vec3d a = At(mesh.triangles[3 * t]), b = At(mesh.triangles[3 * t + 1]),
                  c = At(mesh.triangles[3 * t + 2]);
      const Vec3d u{b.x - a.x, b.y - a.y, b.z - a.z}, v{c.x - a.x, c.y - a.y, c.z - a.z};
      Vec3d n{u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x};
      const double len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
      if (!(len > 0)) continue;
      n = {n.x / len, n.y / len, n.z / len};
      // Opposite normals give the same intervals.
      if (n.x < 0 || (n.x == 0 && (n.y < 0 || (n.y == 0 && n.z < 0)))) n = {-n.x, -n.y, -n.z};
      const double from = n.x - 2e-9, to = n.x + 2e-9;  // wider than 1e-9: rounding of the difference
      auto it = std::lower_bound(by_x.begin(), by_x.begin() + n_dirs, from,
                                 [](const ByX& e, double x) { return e.x < x; });
      bool seen = false;
      for (auto j = it; j != by_x.begin() + n_dirs && j->x <= to && !seen; ++j) {
        const Vec3d& d = directions[j->k].d;
        seen = std::fabs(d.x - n.x) + std::fabs(d.y - n.y) + std::fabs(d.z - n.z) < 1e-9;
      }
      if (seen) continue;
      auto at = std::lower_bound(by_x.begin(), by_x.begin() + n_dirs, n.x,
                                 [](const ByX& e, double x) { return e.x < x; });
      std::move_backward(at, by_x.begin() + n_dirs, by_x.begin() + n_dirs + 1);
      *at = {n.x, static_cast<uint32_t>(directions.size())};
      ++n_dirs;
      directions.push_back({n});
    }
    // Kept for the object's life: no growth slack.
    directions.shrink_to_fit();
    // All intervals in one pass over the vertices (each position once when known: the same intervals).
    const size_t nd = directions.size();
    std::array<double, kMaxDepthDirections> dx, dy, dz;
    for (size_t k = 0; k < nd; ++k) {
      dx[k] = directions[k].d.x;
      dy[k] = directions[k].d.y;
      dz[k] = directions[k].d.z;
    }
    std::array<double, kMaxDepthDirections> lo, hi;
    lo.fill(std::numeric_limits<double>::infinity());
    hi.fill(-std::numeric_limits<double>::infinity());
    auto add = [&](size_t i) {
      const double* p = &mesh.vertices[3 * i];
      const double x = p[0], y = p[1], z = p[2];
      for (size_t k = 0; k < nd; ++k) {
        const double q = x * dx[k] + y * dy[k] + z * dz[k];
        lo[k] = std::min(lo[k], q);
        hi[k] = std::max(hi[k], q);
      }
    };
    if (vertices_built.load(std::memory_order_acquire)) {
      for (uint32_t i : vertex_lists->distinct) add(i);
    } else {
      for (size_t i = 0; i < mesh.vertex_count(); ++i) add(i);
    }
    for (size_t k = 0; k < nd; ++k) {
      directions[k].lo = lo[k];
      directions[k].hi = hi[k];
    }
  }

  Vec3d At(uint32_t i) const {
    return {mesh.vertices[3 * size_t{i}], mesh.vertices[3 * size_t{i} + 1], mesh.vertices[3 * size_t{i} + 2]};
  }

  // Over each distinct position once when they are known (solids, once built): the same interval.
  std::pair<double, double> ProjectionInterval(const Vec3d& d) const {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    auto add = [&](size_t i) {
      const double* v = &mesh.vertices[3 * i];
      const double p = v[0] * d.x + v[1] * d.y + v[2] * d.z;
      lo = std::min(lo, p);
      hi = std::max(hi, p);
    };
    if (vertices_built.load(std::memory_order_acquire)) {
      for (uint32_t i : vertex_lists->distinct) add(i);
    } else {
      for (size_t i = 0; i < mesh.vertex_count(); ++i) add(i);
    }
    return {lo, hi};
  }

  // One vertex of each connected component (vertices with equal coordinates are one point), so that a
  // component of A inside B is found even when another component of A is not. `distinct`: the lowest
  // index of each distinct position, ascending (meshes with one vertex per face corner repeat positions).
  static std::vector<uint32_t> ComponentVertices(const Mesh& m, std::vector<uint32_t>* distinct) {
    const size_t n = m.vertex_count();
    auto at = [&](uint32_t i) { return &m.vertices[3 * size_t{i}]; };
    // Sorted by position with the coordinates beside the index (no indirection in the comparisons).
    struct Key {
      double x, y, z;
      uint32_t i;
    };
    std::vector<Key> keys(n);
    for (uint32_t i = 0; i < n; ++i) keys[i] = {at(i)[0], at(i)[1], at(i)[2], i};
    std::sort(keys.begin(), keys.end(), [](const Key& p, const Key& q) {
      return p.x < q.x || (p.x == q.x && (p.y < q.y || (p.y == q.y && p.z < q.z)));
    });
    std::vector<uint32_t> order(n);
    for (size_t k = 0; k < n; ++k) order[k] = keys[k].i;
    keys = {};
    std::vector<uint32_t> parent(n);
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](uint32_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    auto unite = [&](uint32_t x, uint32_t y) { parent[find(x)] = find(y); };
    distinct->clear();
    for (size_t i = 0; i < n;) {  // runs of equal positions: the sort leaves their indices unordered
      uint32_t lowest = order[i];
      size_t j = i + 1;
      for (; j < n && std::equal(at(order[j]), at(order[j]) + 3, at(order[i])); ++j) {
        unite(order[j], order[j - 1]);
        lowest = std::min(lowest, order[j]);
      }
      distinct->push_back(lowest);
      i = j;
    }
    std::sort(distinct->begin(), distinct->end());
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

  bool solid() const { return is_solid; }

  const Mesh& mesh;
  EdgeCheck edges;
  Box3d bounds;
  Kdop kdop;
  bool is_solid = false;  // closed meshes only: open ones are surfaces
  double projection_slack = 0;
  double negligible2 = 0;
  // Built on first use (the accessors above), each behind a pointer: most shapes of a sweep's window
  // never build some of them, and an empty part should cost a shape a pointer, not the part's size.
  struct VertexLists {
    std::vector<uint32_t> component, distinct;  // ComponentVertices
  };
  struct FaceDirection {
    Vec3d d;
    double lo = 0, hi = 0;  // the vertices' projection interval on d
  };
  mutable std::once_flag hierarchy_once, classifier_once, vertices_once, directions_once;
  mutable std::unique_ptr<TriangleHierarchy> hierarchy;
  mutable std::unique_ptr<SolidClassifier> classifier;
  mutable std::atomic<bool> vertices_built{false};
  mutable std::unique_ptr<VertexLists> vertex_lists;
  mutable std::vector<FaceDirection> directions;  // FaceDirections
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
  // What is built so far. Called by the thread that owns the shape while no Separate runs on it.
  const Impl& m = *impl_;
  size_t bytes = sizeof(Impl);
  if (m.hierarchy) bytes += sizeof(TriangleHierarchy) + m.hierarchy->MemoryBytes();
  if (m.classifier) bytes += sizeof(SolidClassifier) + m.classifier->MemoryBytes();
  if (m.vertex_lists)
    bytes += sizeof(Impl::VertexLists) +
             (m.vertex_lists->component.capacity() + m.vertex_lists->distinct.capacity()) * sizeof(uint32_t);
  bytes += m.directions.capacity() * sizeof(Impl::FaceDirection);
  return bytes;
}

ClashShape::Built ClashShape::built() const {
  return {impl_->hierarchy != nullptr, impl_->classifier != nullptr};
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

// Filtered all-pairs meeting test straight on the meshes, for a small mesh against one of moderate size:
// neither hierarchy is built (for most such pairs nothing else needs them). The small mesh's triangles
// whose boxes meet the large mesh's box, against each triangle of the large mesh, in mesh order, whose box
// meets the small mesh's box. Returns the meeting corners (ta of a, tb of b).
bool ScanMeeting(const Impl& a, const Impl& b, Vec3d* ta, Vec3d* tb, uint64_t* tests) {
  const bool a_small = a.mesh.triangle_count() <= b.mesh.triangle_count();
  const Impl& small = a_small ? a : b;
  const Impl& large = a_small ? b : a;
  using Corners = TriangleHierarchy::Triangle;
  auto corners = [](const Impl& x, size_t t) {
    return Corners{x.At(x.mesh.triangles[3 * t]), x.At(x.mesh.triangles[3 * t + 1]),
                   x.At(x.mesh.triangles[3 * t + 2])};
  };
  // Per-thread scratch: Separate runs once per candidate pair, an allocation each would show.
  thread_local std::vector<Corners> near;
  thread_local std::vector<Box3d> near_boxes;
  near.clear();
  near_boxes.clear();
  for (size_t t = 0; t < small.mesh.triangle_count(); ++t) {
    const Corners c = corners(small, t);
    const Box3d x = TriangleBox(c);
    if (!BoxesMeet(x, large.bounds)) continue;
    near.push_back(c);
    near_boxes.push_back(x);
  }
  const size_t n = near.size();
  for (size_t t = 0; t < large.mesh.triangle_count() && n > 0; ++t) {
    const Corners c = corners(large, t);
    const Box3d x = TriangleBox(c);
    if (!BoxesMeet(x, small.bounds)) continue;
    for (size_t k = 0; k < n; ++k) {
      if (!BoxesMeet(x, near_boxes[k])) continue;
      ++*tests;
      if (TrianglesMeet(c.data(), near[k].data())) {
        std::copy_n(a_small ? near[k].data() : c.data(), 3, ta);
        std::copy_n(a_small ? c.data() : near[k].data(), 3, tb);
        return true;
      }
    }
  }
  return false;
}

bool FindMeetingTriangles(const Impl& a, const Impl& b, size_t brute_force, Vec3d* ta, Vec3d* tb,
                          NarrowStats* st) {
  const size_t na = a.mesh.triangle_count(), nb = b.mesh.triangle_count();
  if (std::min(na, nb) <= brute_force && std::max(na, nb) <= kScanTriangles)
    return ScanMeeting(a, b, ta, tb, &st->triangle_tests);
  const TriangleHierarchy& ha = a.Hierarchy(st);
  const TriangleHierarchy& hb = b.Hierarchy(st);
  TriangleHierarchy::Pair pair;
  if (!TriangleHierarchy::FindMeeting(ha, hb, &pair, &st->triangle_tests)) return false;
  std::copy_n(ha.triangle(pair.a).data(), 3, ta);
  std::copy_n(hb.triangle(pair.b).data(), 3, tb);
  return true;
}

// The deepest vertex of solid `x` inside solid `y`: its distance to y's surface (0 when none is inside).
// Raises *deepest2 to v's squared distance to y's surface when v is in y's solid and deeper. The solid
// test first: it is cheap on small meshes, and the distance query then stops as soon as it finds a
// triangle no farther than *deepest2 (vertices on the other's surface, as in touching members).
bool InsideDeeper(const Vec3d& v, const Impl& y, double* deepest2, NarrowStats* st) {
  ++st->containment_tests;
  if (!y.Classifier(st).Contains(v)) return false;
  const double floor2 = std::max(*deepest2, y.negligible2);
  const double d2 = y.Hierarchy(st).PointDistanceSquared(v, floor2);
  if (d2 <= floor2) return false;
  *deepest2 = d2;
  return true;
}

// Stops once the depth reaches `stop` (the answer can then not change what it is used for). Each position
// once: a repeated one cannot raise the depth again, so the answer is that of every vertex in order.
// A mesh with no more vertices than triangles shares its positions (a closed indexed mesh has about half
// as many): its vertices are visited in index order without sorting out the repeats, which is the same
// answer (a repeat finds what its first occurrence found, which raised the depth or did not).
double DeepestVertex(const Impl& x, const Impl& y, double deepest, double stop, NarrowStats* st) {
  double deepest2 = deepest * deepest;
  auto visit = [&](size_t i) {
    const Vec3d v = VertexAt(x.mesh, i);
    if (y.kdop.Contains(v)) InsideDeeper(v, y, &deepest2, st);
  };
  if (x.mesh.vertex_count() <= x.mesh.triangle_count()) {
    for (size_t i = 0; i < x.mesh.vertex_count() && deepest2 < stop * stop; ++i) visit(i);
  } else {
    x.BuildVertexLists();
    const std::vector<uint32_t>& distinct = x.vertex_lists->distinct;
    for (size_t k = 0; k < distinct.size() && deepest2 < stop * stop; ++k) visit(distinct[k]);
  }
  return std::sqrt(deepest2);
}

// The deepest point of solid `x`'s edges inside solid `y`, sampled at the midpoints of the pieces into
// which y's surface cuts each edge (each piece is wholly inside or outside y): a point of x's surface in
// y at distance d from y's surface bounds the depth below by d, like a vertex.
double DeepestEdgePoint(const Impl& x, const Impl& y, double deepest, double stop, NarrowStats* st) {
  thread_local std::vector<double> cuts;
  double deepest2 = deepest * deepest;
  const Mesh& m = x.mesh;
  for (size_t t = 0; t < m.triangle_count() && deepest2 < stop * stop; ++t)
    for (int e = 0; e < 3; ++e) {
      const uint32_t i = m.triangles[3 * t + e], j = m.triangles[3 * t + (e + 1) % 3];
      if (i > j) continue;  // each edge of a closed indexed mesh once
      const Vec3d p = VertexAt(m, i), q = VertexAt(m, j);
      cuts.clear();
      y.Hierarchy(st).SegmentCrossings(p, q, &cuts);
      if (cuts.empty()) continue;
      cuts.push_back(0);
      cuts.push_back(1);
      std::sort(cuts.begin(), cuts.end());
      for (size_t k = 0; k + 1 < cuts.size(); ++k) {
        const double s = 0.5 * (cuts[k] + cuts[k + 1]);
        const Vec3d v{p.x + s * (q.x - p.x), p.y + s * (q.y - p.y), p.z + s * (q.z - p.z)};
        InsideDeeper(v, y, &deepest2, st);
      }
    }
  return std::sqrt(deepest2);
}

// The smallest overlap of the two objects' projections over x's face directions, or +infinity.
double FaceDirectionOverlap(const Impl& x, const Impl& y) {
  x.BuildDirections();
  double best = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < x.directions.size(); ++k) {
    const Impl::FaceDirection& f = x.directions[k];
    const auto [lo, hi] = y.ProjectionInterval(f.d);
    const double overlap = std::min(f.hi - lo, hi - f.lo);
    best = std::min(best, overlap + x.projection_slack + y.projection_slack);
    if (best <= 0) break;
  }
  return best;
}

TouchObject TouchOf(const Impl& x, NarrowStats* st) {
  return {&x.mesh, &x.Hierarchy(st), &x.kdop, x.projection_slack, x.solid() ? &x.Classifier(st) : nullptr};
}

double TranslationDepthBound(const Impl& a, const Impl& b, const Vec3d* ta, const Vec3d* tb, double enough,
                             double lower, NarrowStats* st);
// Two solids try the translation certificate only when no point of one lies deeper than this share of
// `enough` in the other: contacts that rounding makes cross. Deeper overlaps rarely part within `enough`,
// and each tries every direction (measured: bench/README.md, "The translation certificate").
constexpr double kTranslationLowerShare = 1.0 / 1024;

// `ta`, `tb`: a meeting triangle of each when the surfaces meet; null for containment (a component inside
// the other: no certificate can hold).
void SetDepth(const Impl& a, const Impl& b, double gap, double enough, const Vec3d* ta, const Vec3d* tb,
              Separation* r, NarrowStats* st) {
  r->depth_upper = std::max(0.0, -gap);
  if (r->depth_upper > 0 && b.mesh.vertex_count() <= kMaxDepthDirectionVertices &&
      a.mesh.vertex_count() <= kMaxDepthDirectionVertices) {
    // y's own slack covers rounding of its vertices' projections on x's directions (as large or larger
    // coordinates make it larger); both are added.
    const double faces = std::min(FaceDirectionOverlap(a, b), FaceDirectionOverlap(b, a));
    r->depth_upper = std::min(r->depth_upper, std::max(0.0, faces));
  }
  // A touch certificate proves depth 0 (engine/geometry/touch_certificate.h). A plane's depth bound is
  // kept only when it decides the class at a finite `enough` (a touch): other pairs keep the bound they
  // had (it depends on which meeting triangles were found, hence on the argument order).
  auto certify = [&](TouchStage stage) {
    if (!(r->depth_upper > 0) || !ta || !tb) return false;
    TouchBudget budget;
    if (std::isfinite(enough)) budget.useful_overlap = enough;
    const TouchResult touch = FindTouchCertificate(TouchOf(a, st), TouchOf(b, st), ta, tb, stage, budget);
    st->triangle_tests += touch.triangle_tests;
    if (touch.separated) {
      r->depth_upper = r->depth_lower = r->distance = 0;
      return true;
    }
    if (touch.depth_upper <= enough && std::isfinite(enough))
      r->depth_upper = std::min(r->depth_upper, touch.depth_upper);
    return false;
  };
  r->distance = -r->depth_upper;
  // Pairs already a touch: the cheap planes may make the depth exact; no search (below). Pairs
  // whose class the certificate can still change (depth_upper > enough, or any when enough is infinite):
  // the cheap planes, then the search, only when the search below found no point of one inside the other
  // (such a point rules a certificate out, and most hard pairs have one).
  const bool undecided = std::isinf(enough) ? r->depth_upper > 0 : r->depth_upper > enough;
  if (!undecided) {
    // Already a touch by its bounds: the depth search could only raise depth_lower towards depth_upper,
    // which changes no class; 0 stays a true lower bound (docs/clash.md section 2).
    if (!certify(TouchStage::kCheap)) r->distance = -r->depth_upper;
    return;
  }
  auto certify_undecided = [&] { return certify(TouchStage::kCheap) || certify(TouchStage::kSearch); };
  if (!a.solid() || !b.solid()) {  // a surface has no inside: depth_lower stays 0
    // Only the cheap planes of the touch certificate: on the real scenes the undecided surface pairs are
    // terrain crossing buildings, where its search finds nothing and costs as much as the rest of the
    // narrow phase. Then the translation certificate.
    if (undecided && !certify(TouchStage::kCheap) && std::isfinite(enough) && r->depth_upper > enough && ta &&
        tb)
      r->depth_upper = std::min(r->depth_upper, TranslationDepthBound(a, b, ta, tb, enough, 0, st));
    r->distance = -r->depth_upper;
    return;
  }
  // Vertices first (cheap), then points on edges; each stage only when the bound can still grow.
  const double stop = std::min(r->depth_upper, enough);
  double lower = DeepestVertex(a, b, 0, stop, st);
  lower = DeepestVertex(b, a, lower, stop, st);
  lower = DeepestEdgePoint(a, b, lower, stop, st);
  lower = DeepestEdgePoint(b, a, lower, stop, st);
  if (undecided && lower == 0 && certify_undecided()) return;
  // Still undecided (no point deeper than a share of `enough`, no certificate of 0): a short translation
  // may part them.
  if (std::isfinite(enough) && lower <= enough * kTranslationLowerShare && r->depth_upper > enough && ta &&
      tb)
    r->depth_upper = std::min(r->depth_upper, TranslationDepthBound(a, b, ta, tb, enough, lower, st));
  r->distance = -r->depth_upper;
  r->depth_lower = std::min(lower, r->depth_upper);
}

// A vertex of some component of solid `x` (moved by `shift`) inside solid `y`, when no triangles meet.
bool ComponentInside(const Impl& x, const Impl& y, Vec3d* point, NarrowStats* st,
                     const Vec3d& shift = {0, 0, 0}) {
  // The classifier counts points within its tolerance of y's surface as inside; such a point decides
  // nothing here (no triangles meet, so it may lie just outside), and a vertex clear of it is used.
  const SolidClassifier& cy = y.Classifier(st);
  const TriangleHierarchy& hy = y.Hierarchy(st);
  x.BuildVertexLists();
  const double tol2 = 4 * cy.tolerance() * cy.tolerance();
  bool unsure = false;
  auto moved = [&](size_t i) {
    const Vec3d v = VertexAt(x.mesh, i);
    return Vec3d{v.x + shift.x, v.y + shift.y, v.z + shift.z};
  };
  for (uint32_t v : x.vertex_lists->component) {
    const Vec3d p = moved(v);
    if (!y.kdop.Contains(p)) continue;
    ++st->containment_tests;
    if (!cy.Contains(p)) continue;
    if (hy.PointDistanceSquared(p, tol2) > tol2) {
      *point = p;
      return true;
    }
    unsure = true;
  }
  if (!unsure) return false;
  for (size_t i = 0; i < x.mesh.vertex_count(); ++i) {  // rare: any vertex of x clear of y's surface
    const Vec3d p = moved(i);
    if (!y.kdop.Contains(p) || hy.PointDistanceSquared(p, tol2) <= tol2) continue;
    ++st->containment_tests;
    if (cy.Contains(p)) {
      *point = p;
      return true;
    }
  }
  return false;
}

// Do a, moved by t, and b not meet at all? The moved copy's vertices are a's plus t rounded, so its
// surfaces must keep a gap that rounding cannot close and, for two solids, wider than twice either
// classifier's tolerance, so that the containment tests (a's vertices plus t against b, b's minus t against
// a, with the classifiers a and b already have) meet no vertex on the other's surface. The copy's hierarchy
// is a's, shifted.
bool ApartWhenMoved(const Impl& a, const Impl& b, const Vec3d& t, NarrowStats* st) {
  const TriangleHierarchy& ha = a.Hierarchy(st);
  const TriangleHierarchy& hb = b.Hierarchy(st);
  // Most directions that part the meeting triangles still leave others meeting: found without a copy.
  if (TriangleHierarchy::FindMeetingMoved(ha, t, hb, &st->triangle_tests)) return false;
  thread_local Mesh moved;
  moved.vertices.resize(a.mesh.vertices.size());
  for (size_t i = 0; i < moved.vertices.size(); i += 3) {
    moved.vertices[i] = a.mesh.vertices[i] + t.x;
    moved.vertices[i + 1] = a.mesh.vertices[i + 1] + t.y;
    moved.vertices[i + 2] = a.mesh.vertices[i + 2] + t.z;
  }
  moved.triangles = a.mesh.triangles;
  const TriangleHierarchy hm(ha, moved, t);
  // A surface has no inside (and one lying in a solid does not meet it): only two solids test containment.
  const bool solids = a.solid() && b.solid();
  const double tolerance = solids ? std::max(a.Classifier(st).tolerance(), b.Classifier(st).tolerance()) : 0;
  const double slack = a.projection_slack + b.projection_slack +
                       48 * DBL_EPSILON * (std::fabs(t.x) + std::fabs(t.y) + std::fabs(t.z));
  const double need = std::max(2 * tolerance, slack);
  ClosestPoints c;
  Vec3d p;
  return !TriangleHierarchy::ClosestBelow(hm, hb, need, &c, &st->triangle_tests) &&
         (!solids ||
          (!ComponentInside(a, b, &p, st, t) && !ComponentInside(b, a, &p, st, {-t.x, -t.y, -t.z})));
}

// The translation certificate (docs/clash.md section 2): when a moved by some t with |t| <= enough meets
// b nowhere, the depth is at most |t|. It decides members that touch but whose stored vertices cross by
// rounding where no plane separates the whole objects (a plate in the corner of an angle), and surfaces
// that overlap by less than `enough`. Tried along the meeting triangles' normals and the 26-DOP's directions,
// both ways, at just under `enough`; then shorter along the direction that worked, down to `lower`. Returns
// the shortest length that worked, rounded up, or +infinity.
double TranslationDepthBound(const Impl& a, const Impl& b, const Vec3d* ta, const Vec3d* tb, double enough,
                             double lower, NarrowStats* st) {
  std::array<Vec3d, 2 + kKdopDirections> dirs;
  size_t n = 0;
  for (const Vec3d* tri : {ta, tb}) {
    const Vec3d u{tri[1].x - tri[0].x, tri[1].y - tri[0].y, tri[1].z - tri[0].z};
    const Vec3d v{tri[2].x - tri[0].x, tri[2].y - tri[0].y, tri[2].z - tri[0].z};
    const Vec3d c{u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x};
    const double len = std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z);
    if (len > 0 && std::isfinite(len)) dirs[n++] = {c.x / len, c.y / len, c.z / len};
  }
  for (int k = 0; k < kKdopDirections; ++k) {
    const double s = kKdopInverseLength[k];
    dirs[n++] = {kKdopAxes[k][0] * s, kKdopAxes[k][1] * s, kKdopAxes[k][2] * s};
  }
  // A unit direction's length is 1 within a few ulp: lengths are tried a little short and reported up.
  constexpr double kShort = 1 - 1e-6, kUp = 1 + 1e-9;
  double length = enough * kShort;
  for (size_t k = 0; k < 2 * n; ++k) {
    const Vec3d d = k % 2 == 0 ? dirs[k / 2] : Vec3d{-dirs[k / 2].x, -dirs[k / 2].y, -dirs[k / 2].z};
    auto along = [&](double len) { return Vec3d{d.x * len, d.y * len, d.z * len}; };
    // Most directions leave the meeting triangles meeting: one test rules them out.
    const Vec3d t = along(length);
    const Vec3d moved[3] = {{ta[0].x + t.x, ta[0].y + t.y, ta[0].z + t.z},
                            {ta[1].x + t.x, ta[1].y + t.y, ta[1].z + t.z},
                            {ta[2].x + t.x, ta[2].y + t.y, ta[2].z + t.z}};
    ++st->triangle_tests;
    if (TrianglesMeet(moved, tb) || !ApartWhenMoved(a, b, t, st)) continue;
    for (int step = 0; step < 4; ++step) {
      const double shorter = length / 8;
      if (shorter <= lower || !ApartWhenMoved(a, b, along(shorter), st)) break;
      length = shorter;
    }
    return length * kUp;
  }
  return std::numeric_limits<double>::infinity();
}

}  // namespace

Separation Separate(const ClashShape& shape_a, const ClashShape& shape_b, double max_distance,
                    NarrowStats* stats) {
  return Separate(shape_a, shape_b, max_distance, stats, SeparateOptions{});
}

Separation Separate(const ClashShape& shape_a, const ClashShape& shape_b, double max_distance,
                    NarrowStats* stats, const SeparateOptions& options) {
  const Impl& a = shape_a.impl();
  const Impl& b = shape_b.impl();
  NarrowStats st;
  Separation r;
  r.meeting = Meeting::kApart;
  r.distance = std::numeric_limits<double>::infinity();
  const double limit = max_distance > 0 ? max_distance : 0;
  const double gap = a.kdop.Gap(b.kdop, std::clamp(options.bound_directions, 1, kKdopDirections));
  const double full_gap = options.bound_directions >= kKdopDirections ? gap : a.kdop.Gap(b.kdop);
  if (a.mesh.triangle_count() == 0 || b.mesh.triangle_count() == 0) {
    // Nothing to meet.
  } else if (limit > 0 ? gap >= limit : gap > 0) {
    ++st.bound_rejects;
  } else if (Vec3d ta[3], tb[3];
             gap <= 0 && FindMeetingTriangles(a, b, options.brute_force_triangles, ta, tb, &st)) {
    r.meeting = Meeting::kSurfacesMeet;
    const ClosestPoints c = TriangleTriangleClosest(ta, tb);
    r.point_a = r.point_b = c.on_a;
    SetDepth(a, b, full_gap, options.depth_lower_enough, ta, tb, &r, &st);
  } else {
    Vec3d p;
    if (gap <= 0 && a.solid() && b.solid()) {  // a positive bound gap already says apart
      if (ComponentInside(a, b, &p, &st))
        r.meeting = Meeting::kAInsideB;
      else if (ComponentInside(b, a, &p, &st))
        r.meeting = Meeting::kBInsideA;
    }
    if (r.meeting != Meeting::kApart) {
      r.point_a = r.point_b = p;
      SetDepth(a, b, full_gap, options.depth_lower_enough, nullptr, nullptr, &r, &st);
    } else if (limit > 0) {
      ClosestPoints c;
      if (TriangleHierarchy::ClosestBelow(a.Hierarchy(&st), b.Hierarchy(&st), limit, &c,
                                          &st.triangle_tests)) {
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
