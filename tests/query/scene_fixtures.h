// Test scenes for query tests: random clustered boxes and prisms, with brute-force answers.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "mktree/scene.h"

namespace mktree::testing {

// A closed, outward-facing axis-aligned box mesh.
inline Mesh BoxMesh(const Box3d& b) {
  Mesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.push_back((i & 1) ? b.max[0] : b.min[0]);
    m.vertices.push_back((i & 2) ? b.max[1] : b.min[1]);
    m.vertices.push_back((i & 4) ? b.max[2] : b.min[2]);
  }
  // Faces as quads (outward by right-hand rule), split in two triangles each.
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.insert(m.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  }
  return m;
}

// A closed prism of `sides` sides along axis `axis`, centre c, radius r, from lo to hi on the axis.
inline Mesh PrismMesh(int axis, double cu, double cv, double r, double lo, double hi, int sides) {
  Mesh m;
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  for (int end = 0; end < 2; ++end) {
    for (int s = 0; s < sides; ++s) {
      const double ang = 2 * M_PI * s / sides;
      double p[3];
      p[axis] = end ? hi : lo;
      p[u] = cu + r * std::cos(ang);
      p[v] = cv + r * std::sin(ang);
      for (double x : p) m.vertices.push_back(x);
    }
  }
  const uint32_t n = static_cast<uint32_t>(sides);
  for (uint32_t s = 0; s < n; ++s) {
    const uint32_t a = s, b = (s + 1) % n;
    m.triangles.insert(m.triangles.end(), {a, b, b + n, a, b + n, a + n});
  }
  for (uint32_t s = 1; s + 1 < n; ++s) {
    m.triangles.insert(m.triangles.end(), {0, s + 1, s});          // bottom cap, facing -axis
    m.triangles.insert(m.triangles.end(), {n, n + s, n + s + 1});  // top cap, facing +axis
  }
  return m;
}

// Clustered random scene: boxes (plates, chunks) and prisms (pipes) around a few cluster centres.
inline std::vector<SceneObject> ClusteredScene(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<SceneObject> objs;
  const int clusters = 1 + static_cast<int>(n / 400);
  std::vector<std::array<double, 3>> centres;
  for (int c = 0; c < clusters; ++c) centres.push_back({unit(rng) * 100, unit(rng) * 40, unit(rng) * 20});
  for (size_t i = 0; i < n; ++i) {
    const auto& c = centres[rng() % centres.size()];
    const double x = c[0] + (unit(rng) - 0.5) * 20, y = c[1] + (unit(rng) - 0.5) * 10,
                 z = c[2] + (unit(rng) - 0.5) * 6;
    SceneObject o;
    o.name = "obj_" + std::to_string(i);
    const double kind = unit(rng);
    if (kind < 0.6) {
      const int axis = static_cast<int>(rng() % 3);
      const double len = 0.3 + unit(rng) * 10, r = 0.05 + unit(rng) * 0.25;
      double p[3] = {x, y, z};
      o.mesh = PrismMesh(axis, p[(axis + 1) % 3], p[(axis + 2) % 3], r, p[axis], p[axis] + len,
                         8 + static_cast<int>(rng() % 9));
    } else if (kind < 0.9) {
      Box3d b;
      const int thin = static_cast<int>(rng() % 3);
      double ext[3] = {0.5 + unit(rng) * 5, 0.5 + unit(rng) * 5, 0.5 + unit(rng) * 5};
      ext[thin] = (i % 50 == 0) ? 0.0 : 0.01 + unit(rng) * 0.02;  // some zero-thickness plates
      for (int a = 0; a < 3; ++a) {
        b.min[a] = (a == 0 ? x : a == 1 ? y : z);
        b.max[a] = b.min[a] + ext[a];
      }
      o.mesh = BoxMesh(b);
    } else {
      Box3d b;
      for (int a = 0; a < 3; ++a) {
        b.min[a] = (a == 0 ? x : a == 1 ? y : z);
        b.max[a] = b.min[a] + 0.5 + unit(rng) * 3;
      }
      o.mesh = BoxMesh(b);
    }
    objs.push_back(std::move(o));
  }
  for (size_t i = 0; i < objs.size(); ++i) objs[i].id = static_cast<ObjectId>(i);
  return objs;
}

}  // namespace mktree::testing
