#include "engine/geometry/solid_classifier.h"

#include <algorithm>
#include <cassert>
#include <cfloat>
#include <cmath>
#include <numbers>

#include "engine/geometry/exact_predicates.h"
#include "engine/geometry/triangle_box.h"

namespace mktree {
namespace {

inline Vec3d Sub(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline double Dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3d Cross(const Vec3d& a, const Vec3d& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline Vec3d Vertex(const Mesh& m, uint32_t i) {
  const double* v = &m.vertices[3 * size_t{i}];
  return {v[0], v[1], v[2]};
}

double SegmentDistanceSquared(const Vec3d& p, const Vec3d& a, const Vec3d& b) {
  const Vec3d ab = Sub(b, a), ap = Sub(p, a);
  const double len2 = Dot(ab, ab);
  double t = len2 > 0 ? Dot(ap, ab) / len2 : 0;
  t = std::clamp(t, 0.0, 1.0);
  const Vec3d d = {ap.x - t * ab.x, ap.y - t * ab.y, ap.z - t * ab.z};
  return Dot(d, d);
}

// Solid angle of triangle abc seen from p (van Oosterom & Strackee 1983), signed by orientation.
double SolidAngle(const Vec3d& a0, const Vec3d& b0, const Vec3d& c0, const Vec3d& p) {
  const Vec3d a = Sub(a0, p), b = Sub(b0, p), c = Sub(c0, p);
  const double la = std::sqrt(Dot(a, a)), lb = std::sqrt(Dot(b, b)), lc = std::sqrt(Dot(c, c));
  const double det = Dot(a, Cross(b, c));
  const double den = la * lb * lc + Dot(a, b) * lc + Dot(b, c) * la + Dot(c, a) * lb;
  return 2 * std::atan2(det, den);
}

enum class RayHit { kMiss, kCross, kSurface };

// One triangle against the +x ray from p: on the surface (within tol), crossed ahead of p, or neither.
// See the header for the perturbation argument.
RayHit CastAlongX(const double* A, const double* B, const double* C, const Vec3d& p, double tol,
                  double tol2) {
  const double ymin = std::min({A[1], B[1], C[1]}), ymax = std::max({A[1], B[1], C[1]});
  const double zmin = std::min({A[2], B[2], C[2]}), zmax = std::max({A[2], B[2], C[2]});
  if (p.y < ymin - tol || p.y > ymax + tol || p.z < zmin - tol || p.z > zmax + tol) return RayHit::kMiss;
  const double xmin = std::min({A[0], B[0], C[0]}), xmax = std::max({A[0], B[0], C[0]});
  if (p.x >= xmin - tol && p.x <= xmax + tol) {
    const Vec3d a{A[0], A[1], A[2]}, b{B[0], B[1], B[2]}, c{C[0], C[1], C[2]};
    if (PointTriangleDistanceSquared(p, a, b, c) <= tol2) return RayHit::kSurface;
  }
  // Strictly outside the projected bounds: p + (0, e, e^2) is outside too. Beyond xmax: behind p.
  if (p.y < ymin || p.y > ymax || p.z < zmin || p.z > zmax || p.x > xmax) return RayHit::kMiss;
  const int s = Orient2dSign(A[1], A[2], B[1], B[2], C[1], C[2]);
  if (s == 0) return RayHit::kMiss;  // parallel to the ray: zero-area projection, never crossed
  const double* edge[3][2] = {{A, B}, {B, C}, {C, A}};
  for (const auto& [U, V] : edge) {
    int e = Orient2dSign(U[1], U[2], V[1], V[2], p.y, p.z);
    // (y, z) on the edge's line: side of (y + e, z + e^2), i.e. sign of (V - U) x (e, e^2). U != V in
    // projection here because the triangle's projection has nonzero area.
    if (e == 0) e = V[2] != U[2] ? (V[2] > U[2] ? -1 : 1) : (V[1] > U[1] ? 1 : -1);
    if (e != s) return RayHit::kMiss;
  }
  if (p.x < xmin) return RayHit::kCross;
  const double a[3] = {A[0], A[1], A[2]}, b[3] = {B[0], B[1], B[2]}, c[3] = {C[0], C[1], C[2]};
  const double d[3] = {p.x, p.y, p.z};
  // The ray meets the plane at t = orient3d(a, b, c, p) / n_x with n_x of sign s.
  const int o = Orient3dSign(a, b, c, d);
  if (o == 0) return RayHit::kSurface;  // p in the plane and within the triangle
  return o == s ? RayHit::kCross : RayHit::kMiss;
}

}  // namespace

double SurfaceTolerance(const Box3d& bounds) {
  if (bounds.empty()) return 0;
  double diag2 = 0, maxabs = 0;
  for (int k = 0; k < 3; ++k) {
    const double e = bounds.max[k] - bounds.min[k];
    diag2 += e * e;
    maxabs = std::max({maxabs, std::fabs(bounds.min[k]), std::fabs(bounds.max[k])});
  }
  return 1e-9 * std::sqrt(diag2) + 4 * DBL_EPSILON * maxabs;
}

double PointTriangleDistanceSquared(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d ab = Sub(b, a), bc = Sub(c, b), ca = Sub(a, c);
  const Vec3d n = Cross(ab, Sub(c, a));
  const double nn = Dot(n, n);
  const double l2 = std::max({Dot(ab, ab), Dot(bc, bc), Dot(ca, ca)});
  // Plane distance when p projects inside; slivers (|n| <= 1e-10 l2) are measured by their edges,
  // which are within 1e-10 x their length of every point of them.
  if (nn > 1e-20 * l2 * l2) {
    const Vec3d ap = Sub(p, a);
    if (Dot(Cross(ab, ap), n) >= 0 && Dot(Cross(bc, Sub(p, b)), n) >= 0 &&
        Dot(Cross(ca, Sub(p, c)), n) >= 0) {
      const double d = Dot(ap, n);
      return d * d / nn;
    }
  }
  return std::min(
      {SegmentDistanceSquared(p, a, b), SegmentDistanceSquared(p, b, c), SegmentDistanceSquared(p, c, a)});
}

double WindingNumber(const Mesh& mesh, const Vec3d& p) {
  double sum = 0;
  const uint32_t* t = mesh.triangles.data();
  for (size_t i = 0; i < mesh.triangle_count(); ++i, t += 3)
    sum += SolidAngle(Vertex(mesh, t[0]), Vertex(mesh, t[1]), Vertex(mesh, t[2]), p);
  return sum / (4 * std::numbers::pi);
}

SolidClassifier::SolidClassifier(const Mesh& mesh, const SolidClassifierOptions& options) : mesh_(mesh) {
  assert(std::all_of(mesh.triangles.begin(), mesh.triangles.end(),
                     [&](uint32_t i) { return i < mesh.vertex_count(); }));
  const EdgeCheck edges = options.edges ? *options.edges : CheckEdges(mesh);
  method_ = edges.even ? Method::kRayParity : Method::kWindingNumber;
  const Box3d bounds = mesh.Bounds();
  tol_ = SurfaceTolerance(bounds);
  reach_ = bounds;
  if (!bounds.empty()) {
    for (int k = 0; k < 3; ++k) {
      reach_.min[k] -= tol_;
      reach_.max[k] += tol_;
    }
  }
  if (method_ == Method::kRayParity && mesh.triangle_count() >= kGridMinTriangles &&
      options.expected_queries >= kGridBreakEven)
    BuildGrid();
}

int SolidClassifier::CellY(double y) const {
  // Same monotone arithmetic for binning and lookup, so a triangle whose closed bounds contain y is in
  // y's cell whatever the rounding.
  return std::clamp(static_cast<int>(std::floor((y - y0_) * inv_cy_)), 0, ny_ - 1);
}
int SolidClassifier::CellZ(double z) const {
  return std::clamp(static_cast<int>(std::floor((z - z0_) * inv_cz_)), 0, nz_ - 1);
}

void SolidClassifier::BuildGrid() {
  const size_t n = mesh_.triangle_count();
  const double ey = reach_.max[1] - reach_.min[1], ez = reach_.max[2] - reach_.min[2];
  // About one cell per triangle, square-ish cells; a flat extent gets a single row.
  const double target = static_cast<double>(n);
  if (ey > 0 && ez > 0) {
    ny_ = static_cast<int>(std::clamp(std::sqrt(target * ey / ez), 1.0, 2048.0));
    nz_ = static_cast<int>(std::clamp(target / ny_, 1.0, 2048.0));
  } else {
    ny_ = ey > 0 ? static_cast<int>(std::min(target, 4096.0)) : 1;
    nz_ = ez > 0 ? static_cast<int>(std::min(target, 4096.0)) : 1;
  }
  // Cells no narrower than the triangles' mean extent on each axis: a finer grid repeats long triangles
  // (members' faces spanning their length) in every cell they cross, for little faster queries.
  double sy = 0, sz = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t* c = &mesh_.triangles[3 * i];
    const double *a = &mesh_.vertices[3 * size_t{c[0]}], *b = &mesh_.vertices[3 * size_t{c[1]}],
                 *d = &mesh_.vertices[3 * size_t{c[2]}];
    sy += std::max({a[1], b[1], d[1]}) - std::min({a[1], b[1], d[1]});
    sz += std::max({a[2], b[2], d[2]}) - std::min({a[2], b[2], d[2]});
  }
  const double my = sy / target + 2 * tol_, mz = sz / target + 2 * tol_;
  if (my > 0) ny_ = std::clamp(static_cast<int>(ey / my), 1, ny_);
  if (mz > 0) nz_ = std::clamp(static_cast<int>(ez / mz), 1, nz_);
  y0_ = reach_.min[1];
  z0_ = reach_.min[2];
  inv_cy_ = ey > 0 ? ny_ / ey : 0;
  inv_cz_ = ez > 0 ? nz_ / ez : 0;

  std::vector<CellRange> ranges(n);
  cell_start_.assign(static_cast<size_t>(ny_) * nz_ + 1, 0);
  const uint32_t* t = mesh_.triangles.data();
  for (size_t i = 0; i < n; ++i, t += 3) {
    const double* v[3] = {&mesh_.vertices[3 * size_t{t[0]}], &mesh_.vertices[3 * size_t{t[1]}],
                          &mesh_.vertices[3 * size_t{t[2]}]};
    CellRange& r = ranges[i];
    r.y0 = CellY(std::min({v[0][1], v[1][1], v[2][1]}) - tol_);
    r.y1 = CellY(std::max({v[0][1], v[1][1], v[2][1]}) + tol_);
    r.z0 = CellZ(std::min({v[0][2], v[1][2], v[2][2]}) - tol_);
    r.z1 = CellZ(std::max({v[0][2], v[1][2], v[2][2]}) + tol_);
    for (int y = r.y0; y <= r.y1; ++y)
      for (int z = r.z0; z <= r.z1; ++z) ++cell_start_[static_cast<size_t>(y) * nz_ + z + 1];
  }
  for (size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_tris_.resize(cell_start_.back());
  std::vector<uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (size_t i = 0; i < n; ++i) {
    const CellRange& r = ranges[i];
    for (int y = r.y0; y <= r.y1; ++y)
      for (int z = r.z0; z <= r.z1; ++z)
        cell_tris_[fill[static_cast<size_t>(y) * nz_ + z]++] = static_cast<uint32_t>(i);
  }
}

bool SolidClassifier::Contains(const Vec3d& p) const {
  if (!reach_.Contains(p)) return false;
  return method_ == Method::kRayParity ? ParityContains(p) : WindingContains(p);
}

bool SolidClassifier::ParityContains(const Vec3d& p) const {
  const double tol2 = tol_ * tol_;
  const double* v = mesh_.vertices.data();
  const uint32_t* tris = mesh_.triangles.data();
  bool inside = false;
  auto visit = [&](size_t i) {  // false: stop, p is on the surface
    const uint32_t* t = tris + 3 * i;
    switch (CastAlongX(v + 3 * size_t{t[0]}, v + 3 * size_t{t[1]}, v + 3 * size_t{t[2]}, p, tol_, tol2)) {
      case RayHit::kSurface:
        return false;
      case RayHit::kCross:
        inside = !inside;
        break;
      case RayHit::kMiss:
        break;
    }
    return true;
  };
  if (has_grid()) {
    const size_t cell = static_cast<size_t>(CellY(p.y)) * nz_ + CellZ(p.z);
    for (uint32_t k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k)
      if (!visit(cell_tris_[k])) return true;
  } else {
    for (size_t i = 0; i < mesh_.triangle_count(); ++i)
      if (!visit(i)) return true;
  }
  return inside;
}

bool SolidClassifier::WindingContains(const Vec3d& p) const {
  const double tol2 = tol_ * tol_;
  double sum = 0;
  const uint32_t* t = mesh_.triangles.data();
  for (size_t i = 0; i < mesh_.triangle_count(); ++i, t += 3) {
    const Vec3d a = Vertex(mesh_, t[0]), b = Vertex(mesh_, t[1]), c = Vertex(mesh_, t[2]);
    const bool near = p.x >= std::min({a.x, b.x, c.x}) - tol_ && p.x <= std::max({a.x, b.x, c.x}) + tol_ &&
                      p.y >= std::min({a.y, b.y, c.y}) - tol_ && p.y <= std::max({a.y, b.y, c.y}) + tol_ &&
                      p.z >= std::min({a.z, b.z, c.z}) - tol_ && p.z <= std::max({a.z, b.z, c.z}) + tol_;
    if (near && PointTriangleDistanceSquared(p, a, b, c) <= tol2) return true;
    sum += SolidAngle(a, b, c, p);
  }
  return std::fabs(sum) >= 2 * std::numbers::pi;  // |w| >= 1/2
}

bool SolidClassifier::SomeTriangleMeets(const Box3d& box) const {
  const uint32_t* tris = mesh_.triangles.data();
  auto meets = [&](size_t i) {
    const uint32_t* t = tris + 3 * i;
    return TriangleMeetsBox(Vertex(mesh_, t[0]), Vertex(mesh_, t[1]), Vertex(mesh_, t[2]), box);
  };
  if (has_grid()) {
    // Triangles meeting the box have yz bounds meeting its yz range, so they are in these cells
    // (possibly several times; "any" does not care).
    const int y0 = CellY(box.min[1]), y1 = CellY(box.max[1]);
    const int z0 = CellZ(box.min[2]), z1 = CellZ(box.max[2]);
    const size_t cells = static_cast<size_t>(y1 - y0 + 1) * (z1 - z0 + 1);
    if (cells * 4 < static_cast<size_t>(ny_) * nz_) {
      for (int y = y0; y <= y1; ++y) {
        for (int z = z0; z <= z1; ++z) {
          const size_t cell = static_cast<size_t>(y) * nz_ + z;
          for (uint32_t k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k)
            if (meets(cell_tris_[k])) return true;
        }
      }
      return false;
    }
  }
  for (size_t i = 0; i < mesh_.triangle_count(); ++i)
    if (meets(i)) return true;
  return false;
}

bool SolidClassifier::MeetsBox(const Box3d& box) const {
  if (box.empty() || reach_.empty()) return false;
  for (int k = 0; k < 3; ++k)
    if (box.max[k] < reach_.min[k] || box.min[k] > reach_.max[k]) return false;
  if (SomeTriangleMeets(box)) return true;
  return Contains({box.min[0], box.min[1], box.min[2]});
}

bool PointInSolid(const Mesh& mesh, const Vec3d& p) {
  // Cheap exit before the edge check: beyond the tolerance-grown bounds nothing is inside.
  const Box3d b = mesh.Bounds();
  if (b.empty()) return false;
  const double tol = SurfaceTolerance(b);
  for (int k = 0; k < 3; ++k)
    if (p[k] < b.min[k] - tol || p[k] > b.max[k] + tol) return false;
  return SolidClassifier(mesh).Contains(p);
}

bool MeshMeetsBox(const Mesh& mesh, const Box3d& box) {
  if (box.empty()) return false;
  const uint32_t* t = mesh.triangles.data();
  for (size_t i = 0; i < mesh.triangle_count(); ++i, t += 3)
    if (TriangleMeetsBox(Vertex(mesh, t[0]), Vertex(mesh, t[1]), Vertex(mesh, t[2]), box)) return true;
  return PointInSolid(mesh, {box.min[0], box.min[1], box.min[2]});
}

}  // namespace mktree
