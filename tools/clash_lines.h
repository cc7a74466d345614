// The JSON lines of `mktree clash` / `mktree collide` (docs/cli.md), shared with `mktree-mpi clash`.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>

#include "mktree/clash.h"
#include "tools/json_text.h"

namespace mktree::tools {

inline void AppendReal(std::string* out, double v) {
  if (!std::isfinite(v)) {
    *out += "null";
    return;
  }
  // Shortest round-trip: the same double back, without printf's cost (which bounded a 2-thread clash).
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out->append(buf, r.ptr);
}

inline void AppendPoint(std::string* out, const Vec3d& p) {
  *out += '[';
  for (int i = 0; i < 3; ++i) {
    if (i) *out += ", ";
    AppendReal(out, p[i]);
  }
  *out += ']';
}

inline const char* ClassName(ClashClass c) {
  switch (c) {
    case ClashClass::kHard:
      return "hard";
    case ClashClass::kTouch:
      return "touch";
    case ClashClass::kClearance:
      return "clearance";
  }
  return "hard";
}

inline const char* MeetingName(ClashMeeting m) {
  switch (m) {
    case ClashMeeting::kCross:
      return "cross";
    case ClashMeeting::kAInsideB:
      return "a_inside_b";
    case ClashMeeting::kBInsideA:
      return "b_inside_a";
    case ClashMeeting::kApart:
      return "apart";
    case ClashMeeting::kResolutionGap:
      return "resolution_gap";
  }
  return "cross";
}

// The fields every pair line has: class, distance, depth bounds and the two points.
inline void AppendPairMeasures(std::string* out, const ClashPair& p) {
  std::string& s = *out;
  s += ", \"class\": \"";
  s += ClassName(p.cls);
  s += "\", \"distance\": ";
  AppendReal(&s, p.distance);
  s += ", \"depth_lower\": ";
  AppendReal(&s, p.depth_lower);
  s += ", \"depth_upper\": ";
  AppendReal(&s, p.depth_upper);
  s += ", \"depth_exact\": ";
  s += p.depth_exact ? "true" : "false";
  s += ", \"point_a\": ";
  AppendPoint(&s, p.point_a);
  s += ", \"point_b\": ";
  AppendPoint(&s, p.point_b);
}

// The JSON line of one pair; in collide, b (the query object) is -1. With names (--names), name_a and
// name_b follow b (name_b is null in collide). With a status (clash --since: "new" or "resolved"), a last
// key "status".
inline std::string PairLine(const ClashPair& p, const std::string* name_a = nullptr,
                            const std::string* name_b = nullptr, const char* status = nullptr) {
  std::string s = "{\"a\": " + std::to_string(p.a) + ", \"b\": ";
  s += p.b == kCollideObject ? std::string("-1") : std::to_string(p.b);
  if (name_a) {
    s += ", \"name_a\": \"" + JsonText(*name_a) + "\", \"name_b\": ";
    s += name_b ? "\"" + JsonText(*name_b) + "\"" : std::string("null");
  }
  AppendPairMeasures(&s, p);
  s += ", \"meeting\": \"";
  s += MeetingName(p.meeting);
  s += "\", \"resolution\": ";
  AppendReal(&s, p.resolution);
  if (status) {
    s += ", \"status\": \"";
    s += status;
    s += '"';
  }
  s += "}\n";
  return s;
}

inline std::string SummaryLine(const ClashStats& s, uint64_t peak_rss_bytes) {
  auto u = [](const char* k, uint64_t v) { return std::string("\"") + k + "\": " + std::to_string(v); };
  auto d = [](const char* k, double v) {
    std::string r = std::string("\"") + k + "\": ";
    AppendReal(&r, v);
    return r;
  };
  std::string line =
      "{" + u("pairs", s.hard + s.touch + s.clearance) + ", " + u("hard", s.hard) + ", " +
      u("touch", s.touch) + ", " + u("clearance", s.clearance) + ", " + u("pages_read", s.pages_read) + ", " +
      u("store_pages", s.store_pages) + ", " + d("seconds", s.total_seconds) + ", " +
      u("reported_pairs", s.reported_pairs) + ", " + u("capped_pairs", s.capped_pairs) + ", " +
      u("unreported_touches", s.unreported_touches) + ", " + u("pages_touched", s.pages_touched) + ", " +
      u("distinct_pages", s.distinct_pages) + ", " + u("leaf_reads", s.leaf_reads) + ", " +
      u("leaf_rereads", s.leaf_rereads) + ", " + u("window_peak_bytes", s.window_peak_bytes) + ", " +
      u("window_budget_bytes", s.window_budget_bytes) + ", " + u("leaf_pairs_tree", s.leaf_pairs_tree) +
      ", " + u("leaf_pairs_visited", s.leaf_pairs_visited) + ", " + u("candidate_pairs", s.candidate_pairs) +
      ", " + u("excluded_pairs", s.excluded_pairs) + ", " + u("bound_rejects", s.bound_rejects) + ", " +
      u("triangle_tests", s.triangle_tests) + ", " + u("containment_tests", s.containment_tests) + ", " +
      u("shapes_prepared", s.shapes_prepared) + ", " + u("hierarchies_built", s.hierarchies_built) + ", " +
      u("classifiers_built", s.classifiers_built) + ", " + d("broad_seconds", s.broad_seconds) + ", " +
      d("read_seconds", s.read_seconds) + ", " + d("narrow_seconds", s.narrow_seconds) + ", " +
      u("peak_rss_bytes", peak_rss_bytes) + "}\n";
  return line;
}

}  // namespace mktree::tools
