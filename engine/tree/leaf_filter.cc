#include "engine/tree/leaf_filter.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace mktree {

namespace {

constexpr int kTop = kLeafFilterLevels;

// q / 1023.0 for every level, correctly rounded like the division it replaces: routing evaluates Level
// up to six times per object of every leaf it reaches, and the division cost more than the rest.
constexpr std::array<double, kTop + 1> kLevelFraction = [] {
  std::array<double, kTop + 1> f{};
  for (int q = 0; q <= kTop; ++q) f[q] = q / static_cast<double>(kTop);
  return f;
}();

// The value level q stands for on an axis [lo, hi]. Both the quantizer and the tests use this one
// function, so "rounded outward" is checked against exactly what queries compare with.
inline double Level(double lo, double hi, int q) {
  return q == kTop ? hi : lo + (hi - lo) * kLevelFraction[q];
}

inline uint64_t LoadEntry(const uint8_t* q) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= uint64_t{q[i]} << (8 * i);
  return v;
}
// Level k of an entry: 0-2 the min on axes x, y, z, 3-5 the max.
inline int Field(uint64_t v, int k) { return static_cast<int>((v >> (10 * k)) & kTop); }

}  // namespace

void QuantizeBox(const Box3f& leaf, const Box3f& object, uint8_t* out) {
  uint64_t v = 0;
  for (int a = 0; a < 3; ++a) {
    const double lo = leaf.min[a], hi = leaf.max[a], ext = hi - lo;
    int qmin = 0, qmax = kTop;
    if (ext > 0) {
      qmin = std::clamp(static_cast<int>(std::floor((object.min[a] - lo) / ext * kTop)), 0, kTop);
      while (qmin > 0 && Level(lo, hi, qmin) > object.min[a]) --qmin;
      qmax = std::clamp(static_cast<int>(std::ceil((object.max[a] - lo) / ext * kTop)), 0, kTop);
      while (qmax < kTop && Level(lo, hi, qmax) < object.max[a]) ++qmax;
    }
    v |= uint64_t(qmin) << (10 * a) | uint64_t(qmax) << (10 * (3 + a));
  }
  for (int i = 0; i < 8; ++i) out[i] = static_cast<uint8_t>(v >> (8 * i));
}

Box3d DequantizeBox(const Box3f& leaf, const uint8_t* q) {
  const uint64_t v = LoadEntry(q);
  Box3d b;
  for (int a = 0; a < 3; ++a) {
    b.min[a] = Level(leaf.min[a], leaf.max[a], Field(v, a));
    b.max[a] = Level(leaf.min[a], leaf.max[a], Field(v, 3 + a));
  }
  return b;
}

bool FilterMeetsPoint(const Box3f& leaf, const uint8_t* q, uint32_t count, const Vec3d& p) {
  // Quantize the point once (its cell on each axis), then compare levels.
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    const double l = leaf.min[a], h = leaf.max[a];
    if (p[a] < l || p[a] > h) return false;
    // A flat axis, or one no level can be computed on (an infinite or NaN bound: a damaged store), lets
    // every entry through on this axis rather than cast a NaN level to int.
    if (!(h > l) || !std::isfinite(h - l)) {
      lo[a] = kTop;
      hi[a] = 0;
      continue;
    }
    // Boxes with qmin <= cell_lo and qmax >= cell_hi surely contain p; compare exactly only near edges.
    int c = std::clamp(static_cast<int>(std::floor((p[a] - l) / (h - l) * kTop)), 0, kTop);
    // A margin of one level on each side keeps the fast path clear of rounding in `c`.
    lo[a] = c;
    hi[a] = c + 1;
  }
  for (uint32_t i = 0; i < count; ++i, q += kLeafFilterBytesPerObject) {
    const uint64_t v = LoadEntry(q);
    bool in = true;
    for (int a = 0; a < 3 && in; ++a) {
      const int qmin = Field(v, a), qmax = Field(v, 3 + a);
      if (qmin <= lo[a] - 1 && qmax >= hi[a] + 1) continue;  // well around p's cell: contains p
      const double l = leaf.min[a], h = leaf.max[a];
      in = Level(l, h, qmin) <= p[a] && p[a] <= Level(l, h, qmax);
    }
    if (in) return true;
  }
  return false;
}

bool FilterMeetsBox(const Box3f& leaf, const uint8_t* q, uint32_t count, const Box3d& box) {
  // A box holding the leaf's box meets every entry: each level lies in [lo, hi] when the bounds are
  // finite and lo <= hi (not so in a damaged store).
  bool holds = true;
  for (int a = 0; a < 3; ++a) holds &= box.min[a] <= leaf.min[a] && leaf.max[a] <= box.max[a];
  if (holds) {
    for (int a = 0; a < 3; ++a)
      holds &= std::isfinite(leaf.min[a]) && std::isfinite(leaf.max[a]) && leaf.min[a] <= leaf.max[a];
    if (holds) return count > 0;
  }
  for (uint32_t i = 0; i < count; ++i, q += kLeafFilterBytesPerObject) {
    const uint64_t v = LoadEntry(q);
    bool meets = true;
    for (int a = 0; a < 3 && meets; ++a) {
      const double l = leaf.min[a], h = leaf.max[a];
      meets = Level(l, h, Field(v, a)) <= box.max[a] && box.min[a] <= Level(l, h, Field(v, 3 + a));
    }
    if (meets) return true;
  }
  return false;
}

}  // namespace mktree
