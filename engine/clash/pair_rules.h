// The rules every clash path shares: when two boxes can hold a pair, which pairs are excluded, and how a
// narrow-phase Separation becomes a reported ClashPair (docs/clash.md §1).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "engine/geometry/mesh_separation.h"
#include "mktree/clash.h"
#include "mktree/geometry.h"
#include "mktree/status.h"

namespace mktree::clash {

inline Box3d ToBox3d(const Box3f& b) {
  Box3d d;
  for (int i = 0; i < 3; ++i) {
    d.min[i] = b.min[i];
    d.max[i] = b.max[i];
  }
  return d;
}

// Can objects inside `a` and inside `b` be closer than `c`? Growing by c on each axis is conservative:
// the boxes' per-axis gap is at most the objects' Euclidean gap. Closed intervals: touching boxes meet.
inline bool GrownMeet(const Box3d& a, const Box3d& b, double c) {
  for (int i = 0; i < 3; ++i) {
    if (a.min[i] - c > b.max[i] || b.min[i] - c > a.max[i]) return false;
  }
  return true;
}
inline Box3d Grow(const Box3d& b, double c) {
  Box3d g = b;
  for (int i = 0; i < 3; ++i) {
    g.min[i] -= c;
    g.max[i] += c;
  }
  return g;
}

// InvalidArgument unless C and T are finite and >= 0.
Status CheckOptions(const ClashOptions& o);

// A pair's coordinate resolution: the sum of both objects' CoordinateResolution (engine/store_format/
// object_codec.h; 0 for a mesh that was never stored, as Collide's). Gaps and depths up to it are
// rounding of the store's float32 vertices, not geometry: an exact touch in the input may be stored as a
// gap or an overlap that small. Such pairs are touches (docs/clash.md §1).
//
// The narrow phase as a clash needs it: the gap is computed up to max(C, resolution) (beyond C only to
// know whether it is within the resolution); the depth's lower bound is searched only until it passes
// max(T, resolution), since past it the class is decided (the costliest part of a meeting pair).
inline double NarrowMaxDistance(const ClashOptions& o, double resolution) {
  return std::max(o.clearance, std::nextafter(resolution, std::numeric_limits<double>::infinity()));
}
inline SeparateOptions NarrowOptions(const ClashOptions& o, double resolution) {
  SeparateOptions n;
  n.depth_lower_enough = std::max(o.touch_tolerance, resolution);
  return n;
}

// ClashOptions' exclusions over a store's names: the group of each object (its name up to the separator)
// computed once, then the caller's predicate.
class Exclusions {
 public:
  // `name(i)` for i < count: the object names.
  template <typename NameOf>
  Exclusions(const ClashOptions& o, uint64_t count, NameOf&& name) : exclude_(o.exclude) {
    if (!o.exclude_group_separator.empty()) BuildGroups(o.exclude_group_separator, count, name);
  }
  bool Excluded(ObjectId a, ObjectId b) const {
    if (!group_.empty() && group_[a] != kNoGroup && group_[a] == group_[b]) return true;
    return exclude_ && exclude_(a, b);
  }

 private:
  static constexpr uint32_t kNoGroup = 0xffffffffu;
  template <typename NameOf>
  void BuildGroups(const std::string& sep, uint64_t count, NameOf& name);
  std::vector<uint32_t> group_;
  ClashExclude exclude_;
};

// The reported pair for the separation `s` of objects a < b (shapes in the store's frame, `origin` its
// origin; `resolution` the pair's, as above), or false when the pair is no clash: apart by more than
// the resolution and by C or more.
bool Classify(const Separation& s, const ClashOptions& o, double resolution, ObjectId a, ObjectId b,
              const Vec3d& origin, ClashPair* out);

// Adds a classified pair's class to the counts of `stats`.
void CountClass(const ClashPair& p, ClashStats* stats);

}  // namespace mktree::clash

#include "engine/clash/pair_rules_inl.h"
