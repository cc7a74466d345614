#include "engine/tree/leaf_filter.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace mktree {

namespace {

// q / 255.0 for every quantum, correctly rounded like the division it replaces: routing evaluates Level
// up to six times per object of every leaf it reaches, and the division cost more than the rest.
constexpr std::array<double, 256> kQuantumFraction = [] {
  std::array<double, 256> f{};
  for (int q = 0; q < 256; ++q) f[q] = q / 255.0;
  return f;
}();

// The value quantum q stands for on an axis [lo, hi]. Both the quantizer and the tests use this one
// function, so "rounded outward" is checked against exactly what queries compare with.
inline double Level(double lo, double hi, int q) { return q == 255 ? hi : lo + (hi - lo) * kQuantumFraction[q]; }

}  // namespace

void QuantizeBox(const Box3f& leaf, const Box3f& object, uint8_t* out) {
  for (int a = 0; a < 3; ++a) {
    const double lo = leaf.min[a], hi = leaf.max[a], ext = hi - lo;
    int qmin = 0, qmax = 255;
    if (ext > 0) {
      qmin = std::clamp(static_cast<int>(std::floor((object.min[a] - lo) / ext * 255.0)), 0, 255);
      while (qmin > 0 && Level(lo, hi, qmin) > object.min[a]) --qmin;
      qmax = std::clamp(static_cast<int>(std::ceil((object.max[a] - lo) / ext * 255.0)), 0, 255);
      while (qmax < 255 && Level(lo, hi, qmax) < object.max[a]) ++qmax;
    }
    out[a] = static_cast<uint8_t>(qmin);
    out[3 + a] = static_cast<uint8_t>(qmax);
  }
}

Box3d DequantizeBox(const Box3f& leaf, const uint8_t* q) {
  Box3d b;
  for (int a = 0; a < 3; ++a) {
    b.min[a] = Level(leaf.min[a], leaf.max[a], q[a]);
    b.max[a] = Level(leaf.min[a], leaf.max[a], q[3 + a]);
  }
  return b;
}

bool FilterMeetsPoint(const Box3f& leaf, const uint8_t* q, uint32_t count, const Vec3d& p) {
  // Quantize the point once (its cell on each axis), then compare bytes.
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    const double l = leaf.min[a], h = leaf.max[a];
    if (p[a] < l || p[a] > h) return false;
    if (h <= l) {
      lo[a] = 255;
      hi[a] = 0;
      continue;
    }
    // Boxes with qmin <= cell_lo and qmax >= cell_hi surely contain p; compare exactly only near edges.
    int c = std::clamp(static_cast<int>(std::floor((p[a] - l) / (h - l) * 255.0)), 0, 255);
    // A margin of one quantum on each side keeps the fast path clear of rounding in `c`.
    lo[a] = c;
    hi[a] = c + 1;
  }
  for (uint32_t i = 0; i < count; ++i, q += 6) {
    bool in = true;
    for (int a = 0; a < 3 && in; ++a) {
      if (q[a] <= lo[a] - 1 && q[3 + a] >= hi[a] + 1) continue;  // well around p's cell: contains p
      const double l = leaf.min[a], h = leaf.max[a];
      in = Level(l, h, q[a]) <= p[a] && p[a] <= Level(l, h, q[3 + a]);
    }
    if (in) return true;
  }
  return false;
}

bool FilterMeetsBox(const Box3f& leaf, const uint8_t* q, uint32_t count, const Box3d& box) {
  for (uint32_t i = 0; i < count; ++i, q += 6) {
    bool meets = true;
    for (int a = 0; a < 3 && meets; ++a) {
      const double l = leaf.min[a], h = leaf.max[a];
      meets = Level(l, h, q[a]) <= box.max[a] && box.min[a] <= Level(l, h, q[3 + a]);
    }
    if (meets) return true;
  }
  return false;
}

}  // namespace mktree
