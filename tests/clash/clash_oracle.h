// The clash tests' own rules and pair checks (tests/clash, tests/shard): the shape of a stored object and
// the class of a separation as docs/clash.md §1 states them, restated here rather than taken from
// engine/clash, and field-by-field comparison of pair lists.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "engine/geometry/mesh_separation.h"
#include "mktree/clash.h"

namespace mktree::testing {

// The narrow phase's shape of a stored object: its stored mesh (tests/store_format/stored_geometry.h) with
// the edge check of its input mesh, which ingest computes and the leaf entry keeps (solid or surface is
// decided on the input). Not the check of the stored mesh: float32 rounding may weld vertices that were
// distinct in the input, e.g. a table's legs meeting its top, each a closed part, so that edges are used
// four times; each part stays closed by its indices, so the object stays a solid.
inline std::unique_ptr<ClashShape> StoredShape(const Mesh& input, const Mesh& stored) {
  return std::make_unique<ClashShape>(stored, CheckEdges(input));
}

// The pair `p` for separation `s` with clearance c, touch tolerance t and r the pair's resolution (the sum
// of both objects' CoordinateResolution); false when the pair is not reported (apart, gap >= c). Sets
// every field but the ids and the points.
inline bool OracleClass(const Separation& s, double c, double t, double r, ClashPair* p) {
  p->resolution = r;
  if (s.meeting == Meeting::kApart) {
    if (s.distance <= r) {
      p->cls = ClashClass::kTouch;
      p->meeting = ClashMeeting::kResolutionGap;
    } else {
      if (!(s.distance < c)) return false;
      p->cls = ClashClass::kClearance;
      p->meeting = ClashMeeting::kApart;
    }
  } else {
    const double touch = std::max(t, r);
    p->cls = s.depth_lower > touch    ? ClashClass::kHard
             : s.depth_upper <= touch ? ClashClass::kTouch
                                      : ClashClass::kHard;
    p->meeting = s.meeting == Meeting::kSurfacesMeet ? ClashMeeting::kCross
                 : s.meeting == Meeting::kAInsideB   ? ClashMeeting::kAInsideB
                                                     : ClashMeeting::kBInsideA;
    p->depth_lower = s.depth_lower;
    p->depth_upper = s.depth_upper;
  }
  p->depth_exact = p->depth_lower == p->depth_upper;
  p->distance = s.distance;
  p->point_a = s.point_a;
  p->point_b = s.point_b;
  return true;
}

inline auto PairKey(const ClashPair& p) { return std::tie(p.a, p.b); }

inline std::vector<ClashPair> Sorted(std::vector<ClashPair> v) {
  std::sort(v.begin(), v.end(),
            [](const ClashPair& x, const ClashPair& y) { return PairKey(x) < PairKey(y); });
  return v;
}

// Every field of every pair, in order.
inline void ExpectSame(const std::vector<ClashPair>& got, const std::vector<ClashPair>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i) {
    SCOPED_TRACE("pair " + std::to_string(want[i].a) + " " + std::to_string(want[i].b));
    EXPECT_EQ(got[i].a, want[i].a);
    EXPECT_EQ(got[i].b, want[i].b);
    EXPECT_EQ(got[i].cls, want[i].cls);
    EXPECT_EQ(got[i].meeting, want[i].meeting);
    EXPECT_EQ(got[i].distance, want[i].distance);
    EXPECT_EQ(got[i].depth_lower, want[i].depth_lower);
    EXPECT_EQ(got[i].depth_upper, want[i].depth_upper);
    EXPECT_EQ(got[i].depth_exact, want[i].depth_exact);
    EXPECT_EQ(got[i].resolution, want[i].resolution);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(got[i].point_a[k], want[i].point_a[k]);
      EXPECT_EQ(got[i].point_b[k], want[i].point_b[k]);
    }
  }
}

}  // namespace mktree::testing
