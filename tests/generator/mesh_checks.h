// Helpers shared by the generator tests: draining a SceneSource and checking that a mesh is a closed,
// outward-oriented solid.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "engine/scene/scene_source.h"

namespace mktree::testing {

inline std::vector<SceneObject> Drain(SceneSource* source) {
  std::vector<SceneObject> objects;
  SceneObject o;
  while (true) {
    Result<bool> more = source->Next(&o);
    EXPECT_TRUE(more.ok()) << more.status().ToString();
    if (!more.ok() || !*more) break;
    objects.push_back(o);
  }
  return objects;
}

// Six times the signed volume enclosed by the triangles (divergence theorem), in double.
inline double SignedVolume6(const Mesh& m) {
  double v = 0;
  auto at = [&](uint32_t i, int d) { return static_cast<double>(m.vertices[3 * i + d]); };
  for (size_t t = 0; t < m.triangles.size(); t += 3) {
    const uint32_t a = m.triangles[t], b = m.triangles[t + 1], c = m.triangles[t + 2];
    v += at(a, 0) * (at(b, 1) * at(c, 2) - at(b, 2) * at(c, 1)) -
         at(a, 1) * (at(b, 0) * at(c, 2) - at(b, 2) * at(c, 0)) +
         at(a, 2) * (at(b, 0) * at(c, 1) - at(b, 1) * at(c, 0));
  }
  return v;
}

// Empty string when closed and consistently oriented: every directed edge occurs once and its reverse once.
inline std::string ClosedManifoldError(const Mesh& m) {
  std::unordered_map<uint64_t, int> directed;
  for (size_t t = 0; t < m.triangles.size(); t += 3) {
    for (int e = 0; e < 3; ++e) {
      const uint64_t a = m.triangles[t + e], b = m.triangles[t + (e + 1) % 3];
      if (a == b) return "degenerate triangle " + std::to_string(t / 3);
      if (++directed[(a << 32) | b] > 1)
        return "directed edge " + std::to_string(a) + "->" + std::to_string(b) + " used twice";
    }
  }
  for (const auto& [key, count] : directed) {
    const uint64_t reverse = (key << 32) | (key >> 32);
    if (!directed.count(reverse))
      return "edge " + std::to_string(key >> 32) + "->" + std::to_string(key & 0xffffffffu) + " has no twin";
  }
  return "";
}

}  // namespace mktree::testing
