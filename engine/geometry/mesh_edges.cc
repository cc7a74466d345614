#include "engine/geometry/mesh_edges.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace mktree {
namespace {

// Per-thread scratch: ingest calls this once per object (millions of small meshes), where allocating
// fresh buffers each time cost as much as the check itself.
struct EdgeSlot {
  uint64_t edge;  // smaller vertex << 32 | larger vertex; 0 = empty (the larger vertex is never 0)
  uint32_t forward, backward;
};

struct Scratch {
  std::vector<uint32_t> canon;
  std::vector<uint32_t> slots;       // weld table: vertex index + 1, 0 = empty
  std::vector<EdgeSlot> edge_slots;  // all empty between calls (TallyHashed empties what it filled)
  std::vector<uint32_t> filled;      // the edge slots filled by this call
  std::vector<uint64_t> edges;
};

// Meshes up to this many edge uses count them in a hash table (small enough to stay in cache);
// larger ones sort, which needs half the memory.
constexpr size_t kHashedEdgeUses = size_t{1} << 16;

// Bits of a coordinate such that equal values give equal bits (-0 and +0 are one position).
uint64_t PositionBits(double f) {
  if (f == 0.0) return 0;
  uint64_t b;
  std::memcpy(&b, &f, 8);
  return b;
}

// Multiplicative (Fibonacci) hashing: the top `bits` bits of key * 2^64/phi. One multiply; the high bits
// depend on every key bit, which is what float bit patterns (equal low bits) and vertex pairs need.
size_t HashTop(uint64_t key, int bits) {
  return static_cast<size_t>((key * 0x9E3779B97F4A7C15ULL) >> (64 - bits));
}

int Log2(size_t pow2) { return std::countr_zero(pow2); }

// Canonical id per vertex: the smallest index among vertices with the same coordinates (compared as
// values; a vertex with a NaN coordinate equals nothing, itself only). One pass over a hash table
// indexed by position, instead of a sort: O(V), and the first index inserted is the smallest.
void WeldByPosition(const Mesh& mesh, Scratch* s) {
  const size_t n = mesh.vertex_count();
  const double* v = mesh.vertices.data();
  s->canon.resize(n);
  const size_t cap = std::bit_ceil(2 * n + 16);
  s->slots.assign(cap, 0);
  const size_t mask = cap - 1;
  const int bits = Log2(cap);
  for (size_t i = 0; i < n; ++i) {
    const double* p = v + 3 * i;
    if (std::isnan(p[0]) || std::isnan(p[1]) || std::isnan(p[2])) {
      s->canon[i] = static_cast<uint32_t>(i);
      continue;
    }
    const uint64_t x = PositionBits(p[0]), y = PositionBits(p[1]), z = PositionBits(p[2]);
    size_t h = HashTop(x ^ std::rotl(y, 21) ^ (z * 0xC2B2AE3D27D4EB4FULL), bits);
    for (;; h = (h + 1) & mask) {
      const uint32_t slot = s->slots[h];
      if (slot == 0) {
        s->slots[h] = static_cast<uint32_t>(i + 1);
        s->canon[i] = static_cast<uint32_t>(i);
        break;
      }
      const double* q = v + 3 * (slot - 1);
      if (PositionBits(q[0]) == x && PositionBits(q[1]) == y && PositionBits(q[2]) == z) {
        s->canon[i] = slot - 1;
        break;
      }
    }
  }
}

// Counts of one undirected edge: `forward` uses go from its smaller to its larger vertex.
struct EdgeUses {
  uint64_t forward = 0, backward = 0;
};

// Folds the uses of one undirected edge into the result.
void Tally(const EdgeUses& u, EdgeCheck* r) {
  // Closed and oriented <=> every undirected edge is used once in each direction.
  if (u.forward != 1 || u.backward != 1) r->closed = false;
  if ((u.forward + u.backward) % 2 != 0) r->even = false;
  if (u.forward + u.backward == 1) ++r->border_edges;
}

// Sorts the edge keys (undirected edge << 1 | direction) and tallies each run of one undirected edge.
// One sort of 8-byte keys, not three (directed, reversed, undirected): bench/README.md.
void TallySorted(std::vector<uint64_t>* keys, EdgeCheck* r) {
  std::sort(keys->begin(), keys->end());
  const std::vector<uint64_t>& k = *keys;
  for (size_t i = 0; i < k.size();) {
    EdgeUses u;
    const uint64_t edge = k[i] >> 1;
    for (; i < k.size() && k[i] >> 1 == edge; ++i) (k[i] & 1 ? u.backward : u.forward)++;
    Tally(u, r);
  }
}

// The same with a hash table: for small meshes (most objects of a scene) sorting ~100 keys costs more,
// in branch mispredictions, than hashing them. Only the filled slots are tallied and emptied again: a
// pass over the whole table (4 slots per edge use) cost more than the hashing.
void TallyHashed(const Mesh& mesh, Scratch* s, EdgeCheck* r) {
  const size_t uses = 3 * (mesh.triangles.size() / 3);
  const size_t cap = std::bit_ceil(2 * uses + 16), mask = cap - 1;
  const int bits = Log2(cap);
  if (s->edge_slots.size() < cap) s->edge_slots.assign(cap, EdgeSlot{0, 0, 0});
  if (s->filled.size() < uses) s->filled.resize(uses);
  EdgeSlot* const table = s->edge_slots.data();
  uint32_t* const filled = s->filled.data();
  const uint32_t* const canon = s->canon.data();
  size_t n_filled = 0;
  const uint32_t* tri = mesh.triangles.data();
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    const uint32_t c[3] = {canon[tri[t]], canon[tri[t + 1]], canon[tri[t + 2]]};
    if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) continue;  // no area after welding
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = c[k], b = c[(k + 1) % 3];
      const uint64_t edge = uint64_t{std::min(a, b)} << 32 | std::max(a, b);
      for (size_t h = HashTop(edge, bits);; h = (h + 1) & mask) {
        EdgeSlot& slot = table[h];
        if (slot.edge == 0) {
          slot.edge = edge;
          filled[n_filled++] = static_cast<uint32_t>(h);
        }
        if (slot.edge == edge) {
          ++(a < b ? slot.forward : slot.backward);
          break;
        }
      }
    }
  }
  // Branch-free over the filled slots: a branch per slot mispredicted often enough to show.
  bool not_closed = false, odd = false;
  size_t border = 0;
  for (size_t i = 0; i < n_filled; ++i) {
    EdgeSlot& slot = table[filled[i]];
    const uint32_t uses_of_edge = slot.forward + slot.backward;
    not_closed |= (slot.forward != 1) | (slot.backward != 1);
    odd |= (uses_of_edge & 1) != 0;
    border += uses_of_edge == 1;
    slot = EdgeSlot{0, 0, 0};
  }
  r->closed = r->closed && !not_closed;
  r->even = r->even && !odd;
  r->border_edges += border;
}

// The same for meshes with 2^31 vertices or more, whose edge key and direction do not fit 64 bits.
void TallyWide(const Mesh& mesh, const std::vector<uint32_t>& canon, EdgeCheck* r) {
  struct Use {
    uint64_t edge;
    bool backward;
    bool operator<(const Use& o) const { return edge != o.edge ? edge < o.edge : backward < o.backward; }
  };
  std::vector<Use> uses;
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    const uint32_t c[3] = {canon[mesh.triangles[t]], canon[mesh.triangles[t + 1]],
                           canon[mesh.triangles[t + 2]]};
    if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) continue;
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = c[k], b = c[(k + 1) % 3];
      uses.push_back({uint64_t{std::min(a, b)} << 32 | std::max(a, b), a > b});
    }
  }
  std::sort(uses.begin(), uses.end());
  for (size_t i = 0; i < uses.size();) {
    EdgeUses u;
    const uint64_t edge = uses[i].edge;
    for (; i < uses.size() && uses[i].edge == edge; ++i) (uses[i].backward ? u.backward : u.forward)++;
    Tally(u, r);
  }
}

}  // namespace

EdgeCheck CheckEdges(const Mesh& mesh) {
  thread_local Scratch s;
  const size_t n = mesh.vertex_count();
  // Out-of-range indices are a corrupt mesh, not a closed one.
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3)
    if (mesh.triangles[t] >= n || mesh.triangles[t + 1] >= n || mesh.triangles[t + 2] >= n)
      return EdgeCheck{};
  WeldByPosition(mesh, &s);

  EdgeCheck r;
  r.closed = r.even = true;
  if (mesh.triangles.size() <= kHashedEdgeUses) {
    TallyHashed(mesh, &s, &r);
  } else if (n >= (size_t{1} << 31)) {
    TallyWide(mesh, s.canon, &r);
  } else {
    s.edges.clear();
    for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
      const uint32_t c[3] = {s.canon[mesh.triangles[t]], s.canon[mesh.triangles[t + 1]],
                             s.canon[mesh.triangles[t + 2]]};
      if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) continue;
      for (int k = 0; k < 3; ++k) {
        const uint32_t a = c[k], b = c[(k + 1) % 3];
        s.edges.push_back((uint64_t{std::min(a, b)} << 32 | uint64_t{std::max(a, b)} << 1) | (a > b ? 1 : 0));
      }
    }
    TallySorted(&s.edges, &r);
  }
  // A huge mesh should not pin its buffers in this thread for good.
  if (s.edges.capacity() > (size_t{1} << 22) || s.slots.capacity() > (size_t{1} << 22)) s = Scratch{};
  return r;
}

}  // namespace mktree
