// `mktree clash STORE --tests FILE`: the run of the clash tests and its JSON lines (docs/cli.md,
// docs/clash_workflow.md "Output"): per test its pair lines (with test, key, group, the objects' stable
// identities and, with --compare, status), its resolved lines, then its summary line.
#pragma once

#include <cstdint>
#include <string>

#include "mktree/clash_issues.h"
#include "mktree/clash_tests.h"

namespace mktree::tools {

struct ClashTestsArgs {
  std::string store;
  std::string tests;    // --tests FILE
  std::string compare;  // --compare PREVIOUS.jsonl ("" none)
  std::string bcf;      // --bcf OUT.bcf ("" none), BCF-XML 2.1 or, with bcf_version "3.0", 3.0
  std::string bcf_version = "2.1";
  std::string report;       // --report OUT.html ("" none)
  uint64_t snapshots = 50;  // --snapshots N: pictures of the N worst groups in the BCF and the report
  bool names = false;
  bool progress = false;
  uint64_t cache_pages = 4096;
  uint64_t window_bytes = 0;
  unsigned threads = 0;
  bool has_revision = false;
  uint64_t revision = 0;
};

// The pair line of one record of `group` (a resolved record: its previous values).
std::string ClashRecordLine(const ClashGroup& group, const ClashRecord& r, bool names);
// The summary line of one test (scan_seconds: the run's selection scan, shared by its tests).
std::string ClashTestSummaryLine(const ClashTestSummary& s, bool compared, uint64_t peak_rss_bytes,
                                 double scan_seconds);

// Runs the tests and prints their lines; nothing is printed unless the whole run succeeded. Returns the
// exit code.
int RunClashTestsCommand(const ClashTestsArgs& args);

}  // namespace mktree::tools
