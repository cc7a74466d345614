// A run against a previous one (`mktree clash --tests FILE --compare PREVIOUS.jsonl`, docs/clash_workflow.md
// "Compare"): whether the two runs compare, and each clash's status. Thread safety: pure functions.
#pragma once

#include <string>
#include <vector>

#include "mktree/clash_issues.h"
#include "mktree/clash_tests.h"

namespace mktree::coordination {

// Ok when `now` (the run's summaries after the selection scan: names, fingerprints, selected counts and
// sources) compares with `before`; else InvalidArgument naming the previous file and saying why: a test
// added, removed or defined otherwise, a selection that picks nothing now and did before, a source model
// of the previous run that no selected object comes from now.
Status CheckComparable(const PreviousClashRun& before, const std::vector<ClashTestSummary>& now);

// A clash of the previous run not found now, with the key of the group it was in ("" when none).
struct ResolvedClash {
  ClashRecord record;
  std::string group;
};

// Labels the test's records new or active against the previous run's records of that test, and returns
// the previous records whose keys are not among them, as resolved (the previous values and names).
std::vector<ResolvedClash> LabelAgainst(const PreviousClashRun::Test& before, std::vector<ClashRecord>* now);

}  // namespace mktree::coordination
