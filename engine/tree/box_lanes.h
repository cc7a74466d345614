// A Box3f as two 4-lane float vectors (GCC/Clang vector extension), so that unions of many boxes take one
// vector min and one vector max per box (the split sweeps' margins, the SplitTree's cell extremes).
#pragma once

#include <cstddef>
#include <cstring>
#include <limits>
#include <type_traits>

#include "mktree/geometry.h"

namespace mktree {

typedef float Lanes __attribute__((vector_size(16)));

// A box's bytes 0-15, whose lanes 0-2 are min[0..2], and its bytes 8-23, whose lanes 1-3 are max[0..2].
// (The other lane of each is never read.)
static_assert(std::is_standard_layout_v<Box3f> && sizeof(Box3f) == 24 && offsetof(Box3f, max) == 12);
constexpr int kMaxLane = 1;  // max[u] is lane u + kMaxLane
inline Lanes MinLanes(const Box3f& b) {
  Lanes v;
  std::memcpy(&v, &b, sizeof v);
  return v;
}
inline Lanes MaxLanes(const Box3f& b) {
  Lanes v;
  std::memcpy(&v, reinterpret_cast<const char*>(&b) + 8, sizeof v);
  return v;
}
// The max lanes (1-3) of MaxLanes or of a union's `hi` moved to lanes 0-2, as the min lanes are.
inline Lanes MaxToMinLanes(Lanes hi) {
  static_assert(kMaxLane == 1);
  return __builtin_shufflevector(hi, hi, 1, 2, 3, 3);
}
// As std::min(acc, x) and std::max(acc, x), lane by lane (so a NaN in x never enters).
inline Lanes Min(Lanes acc, Lanes x) { return x < acc ? x : acc; }
inline Lanes Max(Lanes acc, Lanes x) { return x > acc ? x : acc; }

// A union of boxes as (MinLanes, MaxLanes) accumulators: one vector min and one vector max per box.
struct LanesUnion {
  static constexpr float kInf = std::numeric_limits<float>::infinity();
  Lanes lo = {kInf, kInf, kInf, kInf};
  Lanes hi = {-kInf, -kInf, -kInf, -kInf};
  void Add(const Box3f& b) {
    lo = Min(lo, MinLanes(b));
    hi = Max(hi, MaxLanes(b));
  }
  // (max[0] - min[0]) + (max[1] - min[1]) + (max[2] - min[2]), in that order (as for a Box3f): the three
  // differences as one vector subtraction (the same IEEE operations lane by lane), then the two adds.
  float Margin() const {
    const Lanes extent = MaxToMinLanes(hi) - lo;
    return (extent[0] + extent[1]) + extent[2];
  }
};

}  // namespace mktree
