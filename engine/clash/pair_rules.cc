#include "engine/clash/pair_rules.h"

#include <algorithm>
#include <cmath>

namespace mktree::clash {

Status CheckOptions(const ClashOptions& o) {
  if (!std::isfinite(o.clearance) || o.clearance < 0)
    return Status::InvalidArgument("clash: the clearance must be a finite number >= 0");
  if (!std::isfinite(o.touch_tolerance) || o.touch_tolerance < 0)
    return Status::InvalidArgument("clash: the touch tolerance must be a finite number >= 0");
  return Status::Ok();
}

bool Classify(const Separation& s, const ClashOptions& o, double resolution, ObjectId a, ObjectId b,
              const Vec3d& origin, ClashPair* out) {
  ClashPair p;
  p.a = a;
  p.b = b;
  switch (s.meeting) {
    case Meeting::kApart:
      if (s.distance <= resolution) {
        p.cls = ClashClass::kTouch;
        p.meeting = ClashMeeting::kResolutionGap;
        break;
      }
      if (!(s.distance < o.clearance)) return false;
      p.cls = ClashClass::kClearance;
      p.meeting = ClashMeeting::kApart;
      break;
    case Meeting::kSurfacesMeet:
    case Meeting::kAInsideB:
    case Meeting::kBInsideA:
      p.meeting = s.meeting == Meeting::kSurfacesMeet ? ClashMeeting::kCross
                  : s.meeting == Meeting::kAInsideB   ? ClashMeeting::kAInsideB
                                                      : ClashMeeting::kBInsideA;
      p.depth_lower = s.depth_lower;
      p.depth_upper = s.depth_upper;
      p.depth_exact = s.depth_lower == s.depth_upper;
      // Never hide a clash as a touch: only a depth known to be <= T (or within the resolution) is one.
      p.cls =
          s.depth_upper <= std::max(o.touch_tolerance, resolution) ? ClashClass::kTouch : ClashClass::kHard;
      break;
  }
  p.distance = s.distance;
  p.resolution = resolution;
  p.point_a = {s.point_a.x + origin.x, s.point_a.y + origin.y, s.point_a.z + origin.z};
  p.point_b = {s.point_b.x + origin.x, s.point_b.y + origin.y, s.point_b.z + origin.z};
  *out = p;
  return true;
}

void CountClass(const ClashPair& p, ClashStats* stats) {
  switch (p.cls) {
    case ClashClass::kHard:
      ++stats->hard;
      break;
    case ClashClass::kTouch:
      ++stats->touch;
      break;
    case ClashClass::kClearance:
      ++stats->clearance;
      break;
  }
}

}  // namespace mktree::clash
