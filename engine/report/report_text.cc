#include "engine/report/report_text.h"

#include <cmath>
#include <cstdio>

namespace mktree::report {

std::string ShortNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string DepthOrGap(const ClashPair& p) {
  if (p.cls == ClashClass::kClearance || p.distance > 0)
    return "gap " + ShortNumber(std::max(0.0, p.distance));
  if (p.depth_upper <= 0) return "touching";
  if (!p.depth_exact && p.depth_lower < p.depth_upper)
    return "depth " + ShortNumber(p.depth_lower) + " to " + ShortNumber(p.depth_upper);
  return "depth " + ShortNumber(p.depth_upper);
}

std::string ObjectLine(const ObjectIdentity& o) {
  std::string s = "'" + (o.name.empty() ? "object " + std::to_string(o.id) : o.name) + "'";
  std::string extra = o.ifc_type;
  if (!o.global_id.empty()) extra += (extra.empty() ? "" : ", ") + o.global_id;
  if (!extra.empty()) s += " (" + extra + ")";
  return s;
}

const ClashRecord* WorstMember(const ClashGroup& g) {
  const ClashRecord* worst = nullptr;
  for (const ClashRecord& r : g.members)
    if (!worst || ClassRank(r.pair.cls) < ClassRank(worst->pair.cls) ||
        (r.pair.cls == worst->pair.cls && r.pair.distance < worst->pair.distance))
      worst = &r;
  return worst;
}

}  // namespace mktree::report
