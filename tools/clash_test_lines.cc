#include "tools/clash_test_lines.h"

#include <cstdio>
#include <nlohmann/json.hpp>

#include "engine/report/bcf_writer.h"
#include "engine/report/group_snapshot.h"
#include "engine/report/html_report.h"
#include "engine/store_format/store_file.h"
#include "mktree/database.h"
#include "tools/clash_lines.h"
#include "tools/command.h"
#include "tools/json_text.h"
#include "tools/progress.h"

namespace mktree::tools {

namespace {

void AppendString(std::string* s, const char* key, const std::string& value) {
  *s += ", \"";
  *s += key;
  *s += "\": \"";
  *s += JsonText(value);
  *s += '"';
}

}  // namespace

std::string ClashRecordLine(const ClashGroup& group, const ClashRecord& r, bool names) {
  // By hand like PairLine: nlohmann-json's dump is several times slower per line (bench/README.md).
  const ClashPair& p = r.pair;
  std::string s = "{\"test\": \"" + JsonText(group.test) + "\"";
  AppendString(&s, "key", r.key);
  AppendString(&s, "group", group.key);
  s += ", \"a\": " + std::to_string(p.a) + ", \"b\": " + std::to_string(p.b);
  AppendString(&s, "id_a", r.a->stable);
  AppendString(&s, "id_b", r.b->stable);
  if (names) {
    AppendString(&s, "name_a", r.a->name);
    AppendString(&s, "name_b", r.b->name);
  }
  AppendPairMeasures(&s, p);
  if (r.status != ClashStatus::kResolved) {
    s += ", \"meeting\": \"";
    s += MeetingName(p.meeting);
    s += "\", \"resolution\": ";
    AppendReal(&s, p.resolution);
  }
  if (r.status != ClashStatus::kNone) {
    s += ", \"status\": \"";
    s += ClashStatusName(r.status);
    s += '"';
  }
  s += "}\n";
  return s;
}

std::string ClashTestSummaryLine(const ClashTestSummary& t, bool compared, uint64_t peak_rss_bytes,
                                 double scan_seconds) {
  using Json = nlohmann::ordered_json;
  Json rules = Json::object();
  uint64_t excluded = 0;
  for (const auto& [rule, n] : t.excluded_by_rule) {
    rules[rule] = n;
    excluded += n;
  }
  Json j{{"test", t.name},
         {"summary", true},
         {"mode", t.mode},
         {"fingerprint", t.fingerprint},
         {"clearance", t.clearance},
         {"touch_tolerance", t.touch_tolerance},
         {"selected_a", t.selected_a},
         {"selected_b", t.selected_b},
         {"sources", t.sources},
         {"pairs", t.hard + t.touch + t.clearance_pairs + t.duplicates},
         {"hard", t.hard},
         {"touch", t.touch},
         {"clearance_pairs", t.clearance_pairs},
         {"duplicates", t.duplicates},
         {"groups", t.groups},
         {"excluded", excluded},
         {"excluded_by_rule", rules},
         {"warning_count", t.warnings.size()},
         {"warnings", t.warnings}};
  if (compared) {
    j["new"] = t.new_clashes;
    j["active"] = t.active;
    j["resolved"] = t.resolved;
  }
  const ClashStats& s = t.stats;
  j["pages_read"] = s.pages_read;
  j["store_pages"] = s.store_pages;
  j["leaf_pairs_visited"] = s.leaf_pairs_visited;
  j["candidate_pairs"] = s.candidate_pairs;
  j["unreported_touches"] = s.unreported_touches;
  j["seconds"] = s.total_seconds;
  j["workflow_seconds"] = t.workflow_seconds;
  j["scan_seconds"] = scan_seconds;
  j["peak_rss_bytes"] = peak_rss_bytes;
  return j.dump(-1, ' ', false, Json::error_handler_t::replace) + "\n";
}

namespace {

// --bcf and --report, after the lines: each file is written whole or not at all (temporary file and
// rename). The pictures come from the store file itself (the newest base: objects added since by changes
// are framed but not drawn); a manifest of shards gets none, with a warning.
int WriteClashOutputs(const ClashTestsArgs& a, const ClashRun& run) {
  if (a.bcf.empty() && a.report.empty()) return 0;
  std::unique_ptr<StoreReader> store;
  GroupSnapshotSource snapshots;
  if (a.snapshots > 0) {
    auto reader = StoreReader::Open(a.store);
    if (reader.ok()) {
      store = std::move(*reader);
      snapshots = MemoizedSnapshotSource(StoreSnapshotSource(*store), a.snapshots);
    } else {
      std::fprintf(stderr, "mktree: warning: no snapshots: %s\n", reader.status().message().c_str());
    }
  }
  if (!a.bcf.empty()) {
    BcfOptions b;
    b.version = a.bcf_version == "3.0" ? BcfVersion::k3_0 : BcfVersion::k2_1;
    b.snapshot = snapshots;
    b.max_snapshots = a.snapshots;
    auto written = WriteBcf(run, a.bcf, b);
    if (!written.ok()) return Fail(written.status().message());
  }
  if (!a.report.empty()) {
    HtmlReportOptions h;
    h.snapshot = snapshots;
    h.max_snapshots = a.snapshots;
    auto written = WriteHtmlReport(run, a.report, h);
    if (!written.ok()) return Fail(written.status().message());
  }
  return 0;
}

}  // namespace

int RunClashTestsCommand(const ClashTestsArgs& a) {
  auto tests = ReadClashTests(a.tests);
  if (!tests.ok()) return Fail(tests.status().message());
  PreviousClashRun previous;
  if (!a.compare.empty()) {
    auto p = ReadPreviousClashRun(a.compare);
    if (!p.ok()) return Fail(p.status().message());
    previous = std::move(*p);
  }
  OpenOptions oo;
  oo.cache_pages = a.cache_pages;
  if (a.has_revision) oo.revision = a.revision;
  auto db = Database::Open(a.store, oo);
  if (!db.ok()) return Fail(db.status().message());
  ClashTestOptions o;
  o.threads = a.threads;
  o.window_bytes = a.window_bytes;
  if (!a.compare.empty()) o.previous = &previous;
  Progress progress(!a.progress);
  if (a.progress)
    o.progress = [&](size_t test, uint64_t done, uint64_t total) {
      progress.Update(("clash test " + std::to_string(test + 1)).c_str(), done, total);
    };
  ClashRun run;
  const Status st = RunClashTests(**db, *tests, o, &run);
  progress.Done();
  if (!st.ok()) return Fail(st.message());
  const uint64_t rss = PeakRssBytes();
  bool failed = false;
  auto put = [&](const std::string& line) {
    failed |= std::fwrite(line.data(), 1, line.size(), stdout) != line.size();
  };
  for (const ClashTestSummary& t : run.tests) {
    for (const ClashGroup& g : run.groups) {
      if (g.test != t.name) continue;
      for (const ClashRecord& r : g.members)
        if (r.status != ClashStatus::kResolved) put(ClashRecordLine(g, r, a.names));
    }
    for (const ClashGroup& g : run.groups) {
      if (g.test != t.name) continue;
      for (const ClashRecord& r : g.members)
        if (r.status == ClashStatus::kResolved) put(ClashRecordLine(g, r, a.names));
    }
    put(ClashTestSummaryLine(t, !a.compare.empty(), rss, run.scan_seconds));
  }
  if (failed || std::fflush(stdout) != 0) return Fail("cannot write to standard output");
  return WriteClashOutputs(a, run);
}

}  // namespace mktree::tools
