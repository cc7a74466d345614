// `mktree clash --report OUT.html`: a clash run as one self-contained web page a person opens in a browser
// (no network: inline CSS and JavaScript, snapshots as data: URIs, a Content-Security-Policy that forbids
// anything else). docs/clash_reports.md shows it.
//
//   - the run: store, revision, groups and clashes by class and by status;
//   - the tests: mode, clearance and touch tolerance, objects each selection picked, clashes by class and
//     status, pairs each rule excluded, warnings;
//   - the groups, worst first (hard before touch before clearance, then the deepest overlap or the smallest
//     gap): title, class, worst depth or gap, status, member count, the snapshot, and the members (both
//     objects' names, IFC types and GlobalIds, class, depth or gap, status);
//   - filters by test, class, status and text (a few lines of inline JavaScript; the page reads without it).
//
// Bounded for large runs: at most `max_groups` groups and `members_per_group` members of each are listed
// (the page says how many are left out), and snapshots for the first `max_snapshots` groups only. All text
// is escaped. Written under a temporary name and renamed: nothing half-written on error.
// Memory: the run, one group's HTML and one snapshot at a time.
// Thread safety: WriteHtmlReport reads `run` only; the snapshot source is called on the calling thread.
#pragma once

#include <cstdint>
#include <string>

#include "engine/coordination/clash_issues.h"
#include "engine/report/bcf_writer.h"
#include "mktree/status.h"

namespace mktree {

struct HtmlReportOptions {
  std::string title;             // "": "Clash report: <store file name>"
  GroupSnapshotSource snapshot;  // empty: no pictures
  uint64_t max_snapshots = 50;   // pictures for the first (worst) groups
  uint32_t members_per_group = 20;
  uint64_t max_groups = 5000;
};

struct HtmlReportSummary {
  uint64_t groups_listed = 0, groups_left_out = 0;
  uint64_t members_listed = 0, members_left_out = 0;
  uint64_t snapshots = 0;
  uint64_t bytes = 0;
};

// Writes the page at `path`. Errors name the path (IOError), or are the snapshot source's.
Result<HtmlReportSummary> WriteHtmlReport(const ClashRun& run, const std::string& path,
                                          const HtmlReportOptions& options);

}  // namespace mktree
