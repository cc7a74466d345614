// The words the BCF topics and the HTML report use for a clash: class, status, depth or gap, and the one
// line that names an object. In namespace mktree::report, so they never meet names of the clash tests.
//
// Thread safety: pure functions.
#pragma once

#include <string>

#include "engine/coordination/clash_issues.h"

namespace mktree::report {

// "depth 0.012" (hard and touch pairs; "depth 0.01 to 0.012" when only bounds are known), "gap 0.03"
// (clearance pairs, and touches by the store's resolution), "touching" (depth 0). Store units.
std::string DepthOrGap(const ClashPair& p);
// A number as the reports print it: at most 4 significant digits.
std::string ShortNumber(double v);
// "'Wall A' (IfcWall, 2O2Fr$t4X7Zf8NOew3FLOH)": the name, then the IFC type and GlobalId where known.
std::string ObjectLine(const ObjectIdentity& o);
// Severity order: hard 0, touch 1, clearance 2.
inline int ClassRank(ClashClass c) { return static_cast<int>(c); }
// The group's worst member: worst class, then the most negative distance (deepest overlap, smallest gap);
// the first of equals. nullptr for a group without members.
const ClashRecord* WorstMember(const ClashGroup& g);

}  // namespace mktree::report
