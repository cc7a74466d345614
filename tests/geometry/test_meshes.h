// Test-only meshes with known answers, and slow reference classifiers that share no code with
// engine/geometry's ray parity (plain double Moller-Trumbore rays in random directions).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include "engine/geometry/solid_classifier.h"
#include "mktree/scene.h"

namespace mktree::testing {

inline uint32_t AddVertex(Mesh* m, double x, double y, double z) {
  m->vertices.insert(m->vertices.end(),
                     {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)});
  return static_cast<uint32_t>(m->vertex_count() - 1);
}

inline Vec3d VertexOf(const Mesh& m, uint32_t i) {
  return {m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]};
}

// Axis-aligned box [lo, hi] as 12 outward triangles.
inline Mesh BoxMesh(const Vec3d& lo, const Vec3d& hi) {
  Mesh m;
  for (int i = 0; i < 8; ++i) AddVertex(&m, i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) m.triangles.insert(m.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  return m;
}

inline Mesh TetrahedronMesh() {  // (0,0,0), (1,0,0), (0,1,0), (0,0,1), outward
  Mesh m;
  AddVertex(&m, 0, 0, 0);
  AddVertex(&m, 1, 0, 0);
  AddVertex(&m, 0, 1, 0);
  AddVertex(&m, 0, 0, 1);
  m.triangles = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  return m;
}

// Convex UV sphere of radius r: 2 * segments * (bands - 1) triangles, outward.
inline Mesh UvSphereMesh(int bands, int segments, double r) {
  Mesh m;
  const uint32_t north = AddVertex(&m, 0, 0, r);
  for (int b = 1; b < bands; ++b) {
    const double th = std::numbers::pi * b / bands;
    for (int s = 0; s < segments; ++s) {
      const double ph = 2 * std::numbers::pi * s / segments;
      AddVertex(&m, r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th));
    }
  }
  const uint32_t south = AddVertex(&m, 0, 0, -r);
  auto ring = [&](int b, int s) { return static_cast<uint32_t>(1 + (b - 1) * segments + (s % segments)); };
  for (int s = 0; s < segments; ++s) {
    m.triangles.insert(m.triangles.end(), {north, ring(1, s), ring(1, s + 1)});
    m.triangles.insert(m.triangles.end(), {south, ring(bands - 1, s + 1), ring(bands - 1, s)});
    for (int b = 1; b + 1 < bands; ++b)
      m.triangles.insert(m.triangles.end(), {ring(b, s), ring(b + 1, s), ring(b + 1, s + 1), ring(b, s),
                                             ring(b + 1, s + 1), ring(b, s + 1)});
  }
  return m;
}

// Union of unit voxels [x, x+1] x [y, y+1] x [z, z+1] for occupied cells of an n^3 grid: the faces
// between occupied and empty cells, two triangles each (diagonal included). Voxels touching along an
// edge make non-manifold edges used 4 times: "even", not "closed".
struct VoxelSet {
  int n = 0;
  std::vector<char> occupied;  // n^3
  bool At(int x, int y, int z) const {
    if (x < 0 || y < 0 || z < 0 || x >= n || y >= n || z >= n) return false;
    return occupied[(static_cast<size_t>(z) * n + y) * n + x] != 0;
  }
  // Closed union: p is in some occupied closed voxel.
  bool Contains(const Vec3d& p) const {
    int lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = static_cast<int>(std::ceil(p[k])) - 1;
      hi[k] = static_cast<int>(std::floor(p[k]));
    }
    for (int x = lo[0]; x <= hi[0]; ++x)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int z = lo[2]; z <= hi[2]; ++z)
          if (At(x, y, z)) return true;
    return false;
  }
};

inline Mesh VoxelMesh(const VoxelSet& v) {
  Mesh m;
  auto quad = [&](std::array<std::array<int, 3>, 4> c) {  // counterclockwise seen from outside
    uint32_t i[4];
    for (int k = 0; k < 4; ++k) i[k] = AddVertex(&m, c[k][0], c[k][1], c[k][2]);
    m.triangles.insert(m.triangles.end(), {i[0], i[1], i[2], i[0], i[2], i[3]});
  };
  for (int z = 0; z < v.n; ++z)
    for (int y = 0; y < v.n; ++y)
      for (int x = 0; x < v.n; ++x) {
        if (!v.At(x, y, z)) continue;
        const int X = x + 1, Y = y + 1, Z = z + 1;
        if (!v.At(x - 1, y, z)) quad({{{x, y, z}, {x, y, Z}, {x, Y, Z}, {x, Y, z}}});
        if (!v.At(x + 1, y, z)) quad({{{X, y, z}, {X, Y, z}, {X, Y, Z}, {X, y, Z}}});
        if (!v.At(x, y - 1, z)) quad({{{x, y, z}, {X, y, z}, {X, y, Z}, {x, y, Z}}});
        if (!v.At(x, y + 1, z)) quad({{{x, Y, z}, {x, Y, Z}, {X, Y, Z}, {X, Y, z}}});
        if (!v.At(x, y, z - 1)) quad({{{x, y, z}, {x, Y, z}, {X, Y, z}, {X, y, z}}});
        if (!v.At(x, y, z + 1)) quad({{{x, y, Z}, {X, y, Z}, {X, Y, Z}, {x, Y, Z}}});
      }
  return m;
}

// Minimum distance from p to the mesh surface, brute force.
inline double SurfaceDistance(const Mesh& m, const Vec3d& p) {
  double best = INFINITY;
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    const uint32_t* i = &m.triangles[3 * t];
    best = std::min(best,
                    PointTriangleDistanceSquared(p, VertexOf(m, i[0]), VertexOf(m, i[1]), VertexOf(m, i[2])));
  }
  return std::sqrt(best);
}

// Number of triangles the ray p + t d (t > 0) crosses, Moller-Trumbore in plain double.
inline int RayCrossings(const Mesh& m, const Vec3d& p, const Vec3d& d) {
  int hits = 0;
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    const uint32_t* i = &m.triangles[3 * t];
    const Vec3d a = VertexOf(m, i[0]), b = VertexOf(m, i[1]), c = VertexOf(m, i[2]);
    const Vec3d e1{b.x - a.x, b.y - a.y, b.z - a.z}, e2{c.x - a.x, c.y - a.y, c.z - a.z};
    const Vec3d h{d.y * e2.z - d.z * e2.y, d.z * e2.x - d.x * e2.z, d.x * e2.y - d.y * e2.x};
    const double det = e1.x * h.x + e1.y * h.y + e1.z * h.z;
    if (det == 0) continue;
    const double f = 1 / det;
    const Vec3d s{p.x - a.x, p.y - a.y, p.z - a.z};
    const double u = f * (s.x * h.x + s.y * h.y + s.z * h.z);
    if (u < 0 || u > 1) continue;
    const Vec3d q{s.y * e1.z - s.z * e1.y, s.z * e1.x - s.x * e1.z, s.x * e1.y - s.y * e1.x};
    const double v = f * (d.x * q.x + d.y * q.y + d.z * q.z);
    if (v < 0 || u + v > 1) continue;
    if (f * (e2.x * q.x + e2.y * q.y + e2.z * q.z) > 0) ++hits;
  }
  return hits;
}

// Votes of ray parity over `rays` random directions: how many say "inside".
inline int InsideVotes(const Mesh& m, const Vec3d& p, int rays, std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  int votes = 0;
  for (int r = 0; r < rays; ++r) votes += RayCrossings(m, p, {g(rng), g(rng), g(rng)}) % 2;
  return votes;
}

inline Vec3d RandomIn(const Box3d& b, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  return {b.min[0] + u(rng) * (b.max[0] - b.min[0]), b.min[1] + u(rng) * (b.max[1] - b.min[1]),
          b.min[2] + u(rng) * (b.max[2] - b.min[2])};
}

inline Box3d Grown(Box3d b, double frac) {
  for (int k = 0; k < 3; ++k) {
    const double e = (b.max[k] - b.min[k]) * frac;
    b.min[k] -= e;
    b.max[k] += e;
  }
  return b;
}

inline double Diagonal(const Box3d& b) {
  return std::hypot(b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]);
}

inline Box3d MakeBox(double x0, double y0, double z0, double x1, double y1, double z1) {
  Box3d b;
  b.min = {x0, y0, z0};
  b.max = {x1, y1, z1};
  return b;
}

// A classifier's options for `n` expected queries.
inline SolidClassifierOptions Queries(size_t n) {
  SolidClassifierOptions o;
  o.expected_queries = n;
  return o;
}

// A triangle as the triangle-pair functions take it: its three corners.
struct Tri {
  Vec3d v[3];
};

}  // namespace mktree::testing
