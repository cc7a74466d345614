// What a run of clash tests found, keyed, compared and grouped (mktree/clash_tests.h): the model the
// workflow's outputs read (the JSON lines of `mktree clash --tests`, the BCF archive and the HTML report of
// engine/report/, the Python module). RunClashTests fills it; docs/clash_workflow.md is the account of keys,
// groups and statuses.
//
// Memory: a run holds its groups and, per group, its members' records: per clash a small fixed record (the
// pair as the engine found it, its key, its status and two shared pointers), and one ObjectIdentity per
// distinct object of the run, shared by every record that names it (a record's test and group are those of
// the group holding it). Nothing here holds the store's objects.
// Thread safety: plain values; the identities are immutable once shared (copies of a run share them).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "mktree/clash.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

// Who an object is, beyond its id in one store: what a person and another tool recognise it by.
struct ObjectIdentity {
  ObjectId id = 0;
  std::string name;
  std::string source;     // the model (input file) it came from, as given to the build
  std::string ifc_type;   // "" when the input says no IFC type
  std::string global_id;  // the IFC GlobalId, "" when none
  // The object's stable identity within a run's keys: (source model, GlobalId) where there is a
  // GlobalId, else (source model, name). docs/clash_workflow.md states it: the source's file name without
  // its folders, then "|" and the GlobalId, or "|name=" and the name.
  std::string stable;
  Box3d box;  // world coordinates (the stored box); empty for a resolved clash's objects (not in the store)
};

// A clash against a previous run (`--compare`): found now and not before, found in both, found before only.
enum class ClashStatus : uint8_t { kNone, kNew, kActive, kResolved };

// One clash of a test. Its test is its group's (ClashGroup::test) and its group key its group's
// (ClashGroup::key).
struct ClashRecord {
  // The two objects, shared with every other record of the run naming them (never null in a run).
  std::shared_ptr<const ObjectIdentity> a, b;
  std::string key;  // stable: the test and both objects' stable identities, independent of ids and A/B order
  ClashPair pair;   // as the clash engine found it (a resolved clash: the previous run's values)
  ClashStatus status = ClashStatus::kNone;
};

struct ClashGroup {
  std::string key;  // stable: derived from the test and the group's anchor (docs/clash_workflow.md)
  std::string test;
  std::string title;  // one line a person reads, e.g. "IfcBeam B-12 hit by 12 IfcPipeSegment"
  Vec3d centre;       // of the box
  Box3d box;          // the union of the members' two objects' boxes (world coordinates)
  ClashClass worst = ClashClass::kClearance;  // hard > touch > clearance
  double worst_distance = 0;                  // the most negative ClashPair::distance of the worst class
  ClashStatus status = ClashStatus::kNone;  // new when any member is new, else active; resolved when all are
  std::vector<ClashRecord> members;         // in key order
};

struct ClashTestSummary {
  std::string name;
  // "hard", "touch", "clearance" or "duplicates" (with clearance and touch tolerance below).
  std::string mode;
  double clearance = 0, touch_tolerance = 0;
  uint64_t selected_a = 0, selected_b = 0;  // objects each selection picked (b = a for a self test)
  uint64_t hard = 0, touch = 0, clearance_pairs = 0;
  uint64_t duplicates = 0;  // mode "duplicates": objects found placed twice (pairs)
  uint64_t new_clashes = 0, active = 0, resolved = 0;
  // Pairs each rule removed, by rule name ("hosted_filling", "same_aggregate", ...), never silent: pairs the
  // clash engine found clashing under the test's mode (docs/clash_workflow.md, "Rules").
  std::vector<std::pair<std::string, uint64_t>> excluded_by_rule;
  std::vector<std::string> warnings;  // e.g. a selection that matched nothing
  std::string fingerprint;  // of the test's definition (ClashTestFingerprint): runs compare when equal
  std::vector<std::string> sources;  // the source models of the selected objects, sorted
  uint64_t groups = 0;
  ClashStats stats;  // the clash engine's statistics for this test
  // Wall seconds of the test outside the clash engine: its objects' records, rules, keys, comparison and
  // groups.
  double workflow_seconds = 0;
};

struct ClashRun {
  std::string store;  // the store's path
  uint64_t revision = 0;
  std::vector<ClashTestSummary> tests;
  std::vector<ClashGroup> groups;  // worst first (class, then distance), then by key
  double scan_seconds = 0;         // the selection scan shared by the tests (wall)
};

// The names the JSON lines, BCF and report use: "hard", "touch", "clearance"; "new", "active",
// "resolved" ("" for kNone).
const char* ClashClassName(ClashClass c);
const char* ClashStatusName(ClashStatus s);

}  // namespace mktree
