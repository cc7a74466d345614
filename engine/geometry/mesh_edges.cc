#include "engine/geometry/mesh_edges.h"

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

namespace mktree {
namespace {

// Canonical id per vertex: the smallest index among vertices with the same coordinates. Compares
// values, so -0 and +0 are one position.
std::vector<uint32_t> WeldByPosition(const Mesh& mesh) {
  const size_t n = mesh.vertex_count();
  const float* v = mesh.vertices.data();
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  auto less = [v](uint32_t i, uint32_t j) {
    for (int k = 0; k < 3; ++k)
      if (v[3 * i + k] != v[3 * j + k]) return v[3 * i + k] < v[3 * j + k];
    return i < j;
  };
  std::sort(order.begin(), order.end(), less);
  std::vector<uint32_t> canon(n);
  for (size_t r = 0; r < n; ++r) {
    const uint32_t i = order[r];
    const bool same_as_prev = r > 0 && v[3 * i] == v[3 * order[r - 1]] &&
                              v[3 * i + 1] == v[3 * order[r - 1] + 1] &&
                              v[3 * i + 2] == v[3 * order[r - 1] + 2];
    canon[i] = same_as_prev ? canon[order[r - 1]] : i;
  }
  return canon;
}

}  // namespace

EdgeCheck CheckEdges(const Mesh& mesh) {
  const std::vector<uint32_t> canon = WeldByPosition(mesh);
  std::vector<uint64_t> directed;
  directed.reserve(mesh.triangles.size());
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    uint32_t c[3];
    bool valid = true;
    for (int k = 0; k < 3; ++k) {
      const uint32_t idx = mesh.triangles[t + k];
      valid = valid && idx < canon.size();
      c[k] = valid ? canon[idx] : 0;
    }
    // Out-of-range indices are a corrupt mesh, not a closed one.
    if (!valid) return EdgeCheck{};
    if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) continue;
    for (int k = 0; k < 3; ++k) directed.push_back(uint64_t{c[k]} << 32 | c[(k + 1) % 3]);
  }
  auto reverse = [](uint64_t e) { return e << 32 | e >> 32; };
  auto undirected = [&](uint64_t e) { return std::min(e, reverse(e)); };

  EdgeCheck r;
  // Closed and oriented <=> the directed edges are distinct and the set is closed under reversal:
  // then each undirected edge appears exactly once per direction.
  std::vector<uint64_t> rev(directed.size());
  std::transform(directed.begin(), directed.end(), rev.begin(), reverse);
  std::sort(directed.begin(), directed.end());
  std::sort(rev.begin(), rev.end());
  r.closed = std::adjacent_find(directed.begin(), directed.end()) == directed.end() && directed == rev;

  std::vector<uint64_t>& und = rev;  // reuse the buffer
  std::transform(directed.begin(), directed.end(), und.begin(), undirected);
  std::sort(und.begin(), und.end());
  r.even = true;
  for (size_t i = 0; i < und.size();) {
    size_t j = i;
    while (j < und.size() && und[j] == und[i]) ++j;
    if ((j - i) % 2 != 0) r.even = false;
    if (j - i == 1) ++r.border_edges;
    i = j;
  }
  return r;
}

}  // namespace mktree
