// A test's clashes grouped into issues (docs/clash_workflow.md, "Groups"), deterministically: the same
// records in any order give the same groups with the same keys. Thread safety: pure functions.
#pragma once

#include <string>
#include <vector>

#include "mktree/clash_issues.h"
#include "mktree/clash_tests.h"

namespace mktree::coordination {

// By element: each object's degree (its clashes in the test, objects told apart by stable identity);
// objects taken by decreasing degree, ties by identity; each takes the clashes not yet taken that it is
// in, as one group anchored by it (key: the test and the anchor's identity). By proximity: the clashes
// whose places (the middle of the overlap of the two objects' boxes) lie within `distance` of each other,
// chained (single linkage over a grid of cells of that size; key: the test and its smallest member key).
// Groups come back worst first (class, then distance), then by key, each
// with its members in key order. Records with status kResolved and an empty box count by their points.
std::vector<ClashGroup> GroupClashes(const std::string& test, std::vector<ClashRecord> records,
                                     ClashGrouping grouping, double distance);

// A group's box, centre, worst class and distance, and status, from its members (sorted by key here).
void FinishGroup(ClashGroup* group);

// The order of ClashRun::groups: worst class first, then the most negative distance, then the key.
bool WorseGroup(const ClashGroup& x, const ClashGroup& y);

}  // namespace mktree::coordination
