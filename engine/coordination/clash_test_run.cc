// RunClashTests (mktree/clash_tests.h): the selection scan shared by all tests, then per test a clash
// scoped to its two sets, the rules, keys, comparison and groups.
#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "engine/coordination/clash_compare.h"
#include "engine/coordination/clash_groups.h"
#include "engine/coordination/clash_keys.h"
#include "engine/coordination/clash_rules.h"
#include "engine/coordination/duplicate_shapes.h"
#include "engine/coordination/selection_scan.h"
#include "engine/core/guarded.h"
#include "engine/query/revision_database.h"
#include "mktree/clash_tests.h"
#include "mktree/database.h"

namespace mktree {

namespace {

using coordination::SelectionScan;

double SecondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}
using coordination::TestSelections;

ClashOptions OptionsFor(const ClashTest& t, const ClashTestOptions& run) {
  ClashOptions o;
  o.threads = run.threads;
  o.window_bytes = run.window_bytes;
  o.touch_tolerance = t.touch_tolerance;
  o.clearance = t.mode == ClashTestMode::kClearance ? t.clearance : 0;
  o.report_touch = t.mode != ClashTestMode::kHard;
  return o;
}

// The clash of one test within its two sets: the whole self-clash when both are every object, else the
// clash focused on one set with the other as its partner (MultiClashScope).
Status ScopedClash(const Database& db, const ClashTest& t, const TestSelections& sel, uint64_t live,
                   const ClashOptions& o, const ClashVisitor& visit, ClashStats* stats) {
  const bool all_a = sel.count_a == live;
  const bool all_b = t.b ? sel.count_b == live : all_a;
  if (all_a && all_b) return db.SelfClash(o, visit, stats);
  const std::vector<ObjectId> a = sel.a.Ids();
  if (!t.b) return FocusedSelfClash(db, a, o, visit, stats, &a);
  const std::vector<ObjectId> b = sel.b.Ids();
  if (all_a) return FocusedSelfClash(db, b, o, visit, stats);
  if (all_b) return FocusedSelfClash(db, a, o, visit, stats);
  return a.size() <= b.size() ? FocusedSelfClash(db, a, o, visit, stats, &b)
                              : FocusedSelfClash(db, b, o, visit, stats, &a);
}

// The duplicates test's candidates: pairs of the sets whose boxes coincide within the tolerance, found
// through the clash's exclusion (called on worker threads), which leaves every pair out of the narrow
// phase. Sorted.
Status DuplicateCandidates(const Database& db, const ClashTest& t, const SelectionScan& scan,
                           const TestSelections& sel, ClashOptions o, ClashStats* stats,
                           std::vector<std::pair<ObjectId, ObjectId>>* out) {
  std::mutex mu;
  o.exclude = [&](ObjectId a, ObjectId b) {
    if (coordination::BoxesCoincide(scan.boxes[a], scan.boxes[b], t.tolerance)) {
      std::lock_guard<std::mutex> lock(mu);
      out->emplace_back(a, b);
    }
    return true;
  };
  MKTREE_RETURN_IF_ERROR(ScopedClash(
      db, t, sel, scan.live_objects, o, [](const ClashPair&) {}, stats));
  std::sort(out->begin(), out->end());
  return Status::Ok();
}

// The records of the objects of `pairs`, read in id order.
Status ReadRecords(const Database& db, const std::vector<std::pair<ObjectId, ObjectId>>& pairs,
                   std::unordered_map<ObjectId, ObjectRecord>* out) {
  std::vector<ObjectId> ids;
  for (const auto& [a, b] : pairs) {
    ids.push_back(a);
    ids.push_back(b);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  out->reserve(ids.size());
  MKTREE_RETURN_IF_ERROR(
      coordination::VisitRecords(db, &ids, [&](ObjectRecord& r) { out->emplace(r.id, std::move(r)); }));
  if (out->size() != ids.size()) return Status::Internal(db.path() + ": a clashing object has no record");
  return Status::Ok();
}

std::shared_ptr<const ObjectIdentity> IdentityOf(const ObjectRecord& r, std::string stable) {
  auto o = std::make_shared<ObjectIdentity>();
  o->id = r.id;
  o->name = r.name;
  o->source = r.source;
  o->ifc_type = std::string(coordination::AttributeValue(r, "ifc_type"));
  o->global_id = std::string(coordination::AttributeValue(r, "ifc_global_id"));
  o->stable = std::move(stable);
  o->box = r.box;
  return o;
}

// Whether the pair (a, b) is one of the test's: one object in A and the other in B.
bool InScope(const ClashTest& t, const TestSelections& s, ObjectId a, ObjectId b) {
  if (!t.b) return s.a.Get(a) && s.a.Get(b);
  return (s.a.Get(a) && s.b.Get(b)) || (s.b.Get(a) && s.a.Get(b));
}

// The test's pairs through its rules into records (keys set), counting each rule's removals.
std::vector<ClashRecord> ApplyRules(const ClashTest& t, const std::vector<ClashPair>& pairs,
                                    const std::unordered_map<ObjectId, ObjectRecord>& records,
                                    ClashTestSummary* summary) {
  const coordination::ClashRuleSet rules(t);
  std::vector<uint64_t> removed(rules.names().size(), 0);
  // Each object's identity once, shared by its records.
  std::unordered_map<ObjectId, std::shared_ptr<const ObjectIdentity>> identity;
  identity.reserve(records.size());
  for (const auto& [id, r] : records) identity.emplace(id, IdentityOf(r, coordination::StableIdentity(r)));
  std::vector<ClashRecord> out;
  out.reserve(pairs.size());
  for (const ClashPair& p : pairs) {
    const std::shared_ptr<const ObjectIdentity>& ia = identity.at(p.a);
    const std::shared_ptr<const ObjectIdentity>& ib = identity.at(p.b);
    std::string key = coordination::ClashKey(t.name, ia->stable, ib->stable);
    const int rule = rules.Excluding(records.at(p.a), records.at(p.b), ia->stable, ib->stable, key);
    if (rule >= 0) {
      ++removed[rule];
      continue;
    }
    ClashRecord& r = out.emplace_back();
    r.key = std::move(key);
    r.a = ia;
    r.b = ib;
    r.pair = p;
  }
  out.shrink_to_fit();
  for (size_t i = 0; i < removed.size(); ++i)
    summary->excluded_by_rule.emplace_back(rules.names()[i], removed[i]);
  return out;
}

// Mode duplicates: the candidates whose meshes agree, as pairs (a hard meeting at the box's centre).
Status ConfirmDuplicates(const Database& db, const ClashTest& t, const std::vector<ClashRecord>& candidates,
                         std::vector<ClashRecord>* out) {
  for (const ClashRecord& c : candidates) {
    MKTREE_ASSIGN_OR_RETURN(const Mesh ma, db.ObjectGeometry(c.pair.a));
    MKTREE_ASSIGN_OR_RETURN(const Mesh mb, db.ObjectGeometry(c.pair.b));
    double deviation = 0;
    if (!coordination::SameShape(ma, mb, t.tolerance, &deviation)) continue;
    out->push_back(c);
    out->back().pair.depth_exact = deviation == 0;
  }
  return Status::Ok();
}

Status RunTest(const Database& db, const ClashTest& t, const SelectionScan& scan, size_t index,
               const ClashTestOptions& options, ClashTestSummary* summary,
               std::vector<ClashRecord>* records) {
  const TestSelections& sel = scan.tests[index];
  ClashOptions o = OptionsFor(t, options);
  if (options.progress)
    o.progress = [&](uint64_t done, uint64_t total) { options.progress(index, done, total); };
  const bool empty = sel.count_a == 0 || sel.count_b == 0;
  std::vector<ClashPair> pairs;
  if (t.mode == ClashTestMode::kDuplicates) {
    std::vector<std::pair<ObjectId, ObjectId>> candidates;
    if (!empty)
      MKTREE_RETURN_IF_ERROR(DuplicateCandidates(db, t, scan, sel, o, &summary->stats, &candidates));
    for (const auto& [a, b] : candidates) {
      ClashPair p;
      p.a = a;
      p.b = b;
      const Box3d& box = scan.boxes[a];
      for (int i = 0; i < 3; ++i) p.point_a[i] = p.point_b[i] = (box.min[i] + box.max[i]) / 2;
      pairs.push_back(p);
    }
  } else if (!empty) {
    MKTREE_RETURN_IF_ERROR(ScopedClash(
        db, t, sel, scan.live_objects, o,
        [&](const ClashPair& p) {
          if (InScope(t, sel, p.a, p.b)) pairs.push_back(p);
        },
        &summary->stats));
  }
  std::vector<std::pair<ObjectId, ObjectId>> ids;
  for (const ClashPair& p : pairs) ids.emplace_back(p.a, p.b);
  std::unordered_map<ObjectId, ObjectRecord> objects;
  MKTREE_RETURN_IF_ERROR(ReadRecords(db, ids, &objects));
  std::vector<ClashRecord> kept = ApplyRules(t, pairs, objects, summary);
  if (t.mode == ClashTestMode::kDuplicates) {
    std::vector<ClashRecord> confirmed;
    MKTREE_RETURN_IF_ERROR(ConfirmDuplicates(db, t, kept, &confirmed));
    kept = std::move(confirmed);
    summary->duplicates = kept.size();
  }
  for (const ClashRecord& r : kept) {
    if (t.mode == ClashTestMode::kDuplicates) continue;
    ++(r.pair.cls == ClashClass::kHard    ? summary->hard
       : r.pair.cls == ClashClass::kTouch ? summary->touch
                                          : summary->clearance_pairs);
  }
  *records = std::move(kept);
  return Status::Ok();
}

void Summarise(const ClashTest& t, const TestSelections& sel, ClashTestSummary* s) {
  s->name = t.name;
  s->mode = ClashTestModeName(t.mode);
  s->clearance = t.mode == ClashTestMode::kClearance ? t.clearance : 0;
  s->touch_tolerance = t.touch_tolerance;
  s->selected_a = sel.count_a;
  s->selected_b = sel.count_b;
  s->fingerprint = ClashTestFingerprint(t);
  s->sources.assign(sel.sources.begin(), sel.sources.end());
  if (sel.count_a == 0) s->warnings.push_back("selection a picks no object");
  if (t.b && sel.count_b == 0) s->warnings.push_back("selection b picks no object");
}

// The test's groups, with the resolved records of a comparison put in the group they were in when it is
// still there, else in groups of their own (by their previous group keys).
std::vector<ClashGroup> GroupWithResolved(const ClashTest& t, std::vector<ClashRecord> records,
                                          std::vector<coordination::ResolvedClash> resolved) {
  std::vector<ClashGroup> groups =
      coordination::GroupClashes(t.name, std::move(records), t.grouping, t.group_distance);
  std::unordered_map<std::string, size_t> at;
  for (size_t i = 0; i < groups.size(); ++i) at[groups[i].key] = i;
  std::vector<size_t> touched;
  for (coordination::ResolvedClash& r : resolved) {
    if (r.group.empty()) r.group = coordination::Hex64(coordination::StableHash("resolved\n" + r.record.key));
    auto it = at.find(r.group);
    if (it == at.end()) {
      it = at.emplace(r.group, groups.size()).first;
      ClashGroup g;
      g.key = r.group;
      g.test = t.name;
      groups.push_back(std::move(g));
    }
    groups[it->second].members.push_back(std::move(r.record));
    touched.push_back(it->second);
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  for (size_t i : touched) coordination::FinishGroup(&groups[i]);
  return groups;
}

Status Run(const Database& db, const ClashTestFile& file, const ClashTestOptions& options, ClashRun* run) {
  *run = ClashRun();
  run->store = db.path();
  run->revision = db.revision();
  SelectionScan scan;
  const auto start = std::chrono::steady_clock::now();
  MKTREE_RETURN_IF_ERROR(coordination::ScanSelections(db, file, &scan));
  run->scan_seconds = SecondsSince(start);
  run->tests.resize(file.tests.size());
  for (size_t i = 0; i < file.tests.size(); ++i) Summarise(file.tests[i], scan.tests[i], &run->tests[i]);
  if (options.previous) MKTREE_RETURN_IF_ERROR(coordination::CheckComparable(*options.previous, run->tests));
  for (size_t i = 0; i < file.tests.size(); ++i) {
    const ClashTest& t = file.tests[i];
    ClashTestSummary& s = run->tests[i];
    std::vector<ClashRecord> records;
    const auto test_start = std::chrono::steady_clock::now();
    MKTREE_RETURN_IF_ERROR(RunTest(db, t, scan, i, options, &s, &records));
    std::vector<std::string_view> keys;
    keys.reserve(records.size());
    for (const ClashRecord& r : records) keys.push_back(r.key);
    std::sort(keys.begin(), keys.end());
    uint64_t shared = 0;
    for (size_t k = 0; k < keys.size(); ++k)
      shared += (k > 0 && keys[k] == keys[k - 1]) || (k + 1 < keys.size() && keys[k] == keys[k + 1]);
    if (shared)
      s.warnings.push_back(std::to_string(shared) +
                           " clashes share their key with another (objects without "
                           "a unique GlobalId or name in their source model)");
    std::vector<coordination::ResolvedClash> resolved;
    if (options.previous) {
      for (const PreviousClashRun::Test& before : options.previous->tests)
        if (before.name == t.name) resolved = coordination::LabelAgainst(before, &records);
      for (const ClashRecord& r : records) ++(r.status == ClashStatus::kNew ? s.new_clashes : s.active);
      s.resolved = resolved.size();
    }
    std::vector<ClashGroup> groups = GroupWithResolved(t, std::move(records), std::move(resolved));
    s.groups = groups.size();
    s.workflow_seconds = SecondsSince(test_start) - s.stats.total_seconds;
    for (ClashGroup& g : groups) run->groups.push_back(std::move(g));
  }
  std::stable_sort(run->groups.begin(), run->groups.end(), coordination::WorseGroup);
  return Status::Ok();
}

}  // namespace

Status RunClashTests(const Database& db, const ClashTestFile& tests, const ClashTestOptions& options,
                     ClashRun* run) {
  return Guarded(db.path(), [&] { return Run(db, tests, options, run); });
}

}  // namespace mktree
