// Small fixed-dimension geometry types. One concrete box type (Box3f) is what the tree and the pages
// store; Box3d is used where precision matters (computing a mesh's bounds, queries).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

namespace mktree {

struct Vec3d {
  double x = 0, y = 0, z = 0;
  double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

struct Box3d {
  std::array<double, 3> min{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                            std::numeric_limits<double>::infinity()};
  std::array<double, 3> max{-std::numeric_limits<double>::infinity(),
                            -std::numeric_limits<double>::infinity(),
                            -std::numeric_limits<double>::infinity()};
  bool empty() const { return min[0] > max[0] || min[1] > max[1] || min[2] > max[2]; }
  void Extend(double x, double y, double z) {
    min[0] = std::min(min[0], x);
    max[0] = std::max(max[0], x);
    min[1] = std::min(min[1], y);
    max[1] = std::max(max[1], y);
    min[2] = std::min(min[2], z);
    max[2] = std::max(max[2], z);
  }
  bool Contains(const Vec3d& p) const {  // closed
    return p.x >= min[0] && p.x <= max[0] && p.y >= min[1] && p.y <= max[1] && p.z >= min[2] && p.z <= max[2];
  }
};

// Axis-aligned box in float32, as stored in records, tree nodes and pages. Intervals are closed.
struct Box3f {
  std::array<float, 3> min{std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                           std::numeric_limits<float>::infinity()};
  std::array<float, 3> max{-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                           -std::numeric_limits<float>::infinity()};

  bool empty() const { return min[0] > max[0] || min[1] > max[1] || min[2] > max[2]; }
  void Extend(const Box3f& b) {
    for (int i = 0; i < 3; ++i) {
      min[i] = std::min(min[i], b.min[i]);
      max[i] = std::max(max[i], b.max[i]);
    }
  }
  bool Intersects(const Box3f& b) const {
    for (int i = 0; i < 3; ++i)
      if (b.max[i] < min[i] || b.min[i] > max[i]) return false;
    return true;
  }
  bool Intersects(const Box3d& b) const {
    for (int i = 0; i < 3; ++i)
      if (b.max[i] < min[i] || b.min[i] > max[i]) return false;
    return true;
  }
  bool Contains(const Vec3d& p) const {
    for (int i = 0; i < 3; ++i)
      if (p[i] < min[i] || p[i] > max[i]) return false;
    return true;
  }
  bool operator==(const Box3f&) const = default;
};

// The largest float32 <= x and the smallest float32 >= x (x finite and within float32's range).
inline float RoundDownToFloat(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}
inline float RoundUpToFloat(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// The float32 box that contains `b`: each bound is rounded outward (down for min, up for max), so that
// every point of the double-precision box lies inside the stored box.
inline Box3f RoundOutward(const Box3d& b) {
  Box3f r;
  for (int i = 0; i < 3; ++i) {
    r.min[i] = RoundDownToFloat(b.min[i]);
    r.max[i] = RoundUpToFloat(b.max[i]);
  }
  return r;
}

}  // namespace mktree
