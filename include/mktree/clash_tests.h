// Clash tests: the coordination workflow over a store's self-clash (docs/clash_workflow.md). A test pairs
// two selections of objects (A against B; A against itself when B is left out), chosen by their names,
// source files and stored attributes, under a mode (hard / touch / clearance, or duplicates) and rules
// that remove pairs that are not problems (each rule's removals counted, never silent). Its clashes get
// stable keys (the test and both objects' stable identities), are grouped into issues, and may be
// compared with a previous run's JSON lines (new / active / resolved).
//
//   auto tests = mktree::ParseClashTests(json_text, "tests.json");   // errors name the file and line
//   mktree::ClashRun run;
//   mktree::Status st = mktree::RunClashTests(*db, *tests, {}, &run);
//   for (const mktree::ClashGroup& g : run.groups) ...               // worst first
//
// A selection is evaluated by one scan of the objects' records (shared by all tests of a run) into one
// bit per object; the clash then descends only into subtrees that may hold an A object on one side and a
// B object on the other, and reads no leaf pair that cannot hold such a pair (a narrow test on a large
// store reads about the pages of its objects' neighbourhoods). Works on plain, revision and sharded stores.
//
// Thread safety: ParseClashTests and the types are plain; RunClashTests may run on several threads at
// once over one Database (a Database is safe to query from many threads).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mktree/clash.h"
#include "mktree/clash_issues.h"
#include "mktree/status.h"

namespace mktree {

class Database;

// Which objects a selection picks: an object is selected when, for every key of `include`, one of its
// values for that key matches one of the key's glob patterns, and it is not picked by `exclude` (the same
// rule over exclude's keys; an empty exclude picks nothing). No include key: every object. Keys: "name"
// and "source" are the object's name and source file (as given to the build); any other key is a stored
// attribute (ObjectAttribute::key; a repeated key matches when any of its values does). Patterns are
// globs: '*' any run of bytes, '?' one byte, the rest literal and case-sensitive, except for "ifc_type",
// compared without case (STEP files write IFCWALL), where a pattern without '*' or '?' naming a known
// IFC supertype (IfcWall, IfcSlab, IfcBeam, IfcFlowSegment, IfcBuildingElement, ...) also matches its
// subtypes (docs/clash_workflow.md lists them).
struct Selection {
  using Patterns = std::vector<std::pair<std::string, std::vector<std::string>>>;  // key -> globs
  Patterns include;
  Patterns exclude;
  bool everything() const { return include.empty() && exclude.empty(); }
};

// The rules a test applies to the pairs it found (docs/clash_workflow.md, "Rules"). Each removal is
// counted under the rule's name in ClashTestSummary::excluded_by_rule; a pair removed by several rules
// counts once, under the first in this order.
struct ClashRules {
  // "spatial_container": pairs with a spatial element that is not a solid (attribute ifc_spatial "true",
  // or ifc_type IfcSpace, IfcOpeningElement, IfcSite, IfcBuilding, IfcBuildingStorey, IfcSpatialZone,
  // IfcExternalSpatialElement, IfcGrid, IfcAnnotation, ...). Left out unless keep_spatial.
  bool keep_spatial = false;
  // "hosted_filling": a door or window and the element it fills (ifc_fills of one = ifc_global_id of the
  // other), an opening and the element it voids (ifc_voids), from one source model.
  bool hosted_fillings = true;
  // "same_aggregate": members of one aggregate (equal ifc_aggregate), or a part and its whole (the
  // ifc_aggregate of one is the other's ifc_global_id), from one source model.
  bool same_aggregate = true;
  // "same_group": names that both contain this separator and agree up to its first occurrence
  // ("pump3/flange", "pump3/body" with "/"; the command line's --exclude-group). Empty: off.
  std::string same_group_separator;
  // "same_attribute": pairs whose objects share a value of any of these attribute keys ("group", "layer",
  // "ifc_storey", ...).
  std::vector<std::string> same_attribute;
  // "approved": the caller's accepted pairs, as clash keys (ClashRecord::key of this test) or as pairs of
  // stable identities (ObjectIdentity::stable).
  std::vector<std::string> approved_keys;
  std::vector<std::pair<std::string, std::string>> approved_pairs;
};

enum class ClashTestMode : uint8_t {
  kHard,       // hard clashes only (touches found are counted, not reported)
  kTouch,      // hard and touch
  kClearance,  // hard, touch and clearance pairs (0 < s < clearance)
  kDuplicates  // objects placed twice: the same shape within `tolerance` at the same place
};

// How a test's clashes are grouped into issues (docs/clash_workflow.md, "Groups").
enum class ClashGrouping : uint8_t {
  kElement,    // an object in several clashes anchors one group (most clashes first, ties by identity)
  kProximity,  // clashes whose points are within group_distance of each other, chained (single linkage)
};

// "hard", "touch", "clearance", "duplicates" (ClashTestSummary::mode).
const char* ClashTestModeName(ClashTestMode mode);

struct ClashTest {
  std::string name;  // unique within a file
  Selection a;
  std::optional<Selection> b;  // none: A against itself
  ClashTestMode mode = ClashTestMode::kTouch;
  double clearance = 0;            // C (kClearance), store units
  double touch_tolerance = 0.002;  // T
  double tolerance = 0.001;        // kDuplicates: vertices and boxes agree within this
  ClashRules rules;
  ClashGrouping grouping = ClashGrouping::kElement;
  double group_distance = 1.0;  // kProximity: D, store units
  std::string file;             // where it was read ("" when built in code), for messages
  uint64_t line = 0;
};

struct ClashTestFile {
  std::vector<ClashTest> tests;
};

// Parses a clash-test file (docs/clash_workflow.md, "Test file"): {"tests": [{"name": ..., "a": SELECTION,
// "b": SELECTION, "mode": ..., "clearance": C, "touch_tolerance": T, "rules": [...], ...}, ...]}.
// InvalidArgument naming `file_name` and the line for bad JSON, an unknown key, a wrong type or value, a
// repeated test name, or no test at all.
Result<ClashTestFile> ParseClashTests(const std::string& json_text, const std::string& file_name);
// The same, read from the file at `path`.
Result<ClashTestFile> ReadClashTests(const std::string& path);

// A test's definition as canonical JSON (every field, defaults included; the file and line left out) and
// its fingerprint (16 hex digits of a hash of that text): two runs compare only when their tests' names
// and fingerprints are the same.
std::string ClashTestDefinition(const ClashTest& test);
std::string ClashTestFingerprint(const ClashTest& test);

// A previous run to compare against (`--compare`): what each test's summary line and pair lines said.
struct PreviousClashRun {
  struct Test {
    std::string name, fingerprint;
    uint64_t selected_a = 0, selected_b = 0;
    std::vector<std::string> sources;
    // The pair lines that were not resolved, status as recorded; of the identities (one per distinct
    // stable identity and name in the file, shared): name (with --names), stable, and from it the
    // source's file name and the GlobalId; no box, no IFC type.
    std::vector<ClashRecord> records;
    // The key of the group each record was in (records[i] in group_keys[group_of[i]]; "" when the line
    // had none), each distinct key once.
    std::vector<uint32_t> group_of;
    std::vector<std::string> group_keys;
  };
  std::string file;
  std::vector<Test> tests;
};

// Reads the JSON lines a `mktree clash --tests` run wrote. InvalidArgument naming the file and the line
// for a line that is not JSON, a pair line without test or key, a pair of a test with no summary line,
// or a file without any summary line (not the output of a test run).
Result<PreviousClashRun> ReadPreviousClashRun(const std::string& path);

struct ClashTestOptions {
  unsigned threads = 1;       // ClashOptions::threads
  uint64_t window_bytes = 0;  // ClashOptions::window_bytes
  // Set: label each clash new or active against it and add its resolved clashes. RunClashTests refuses
  // (InvalidArgument saying why, before any clash is visited) when the runs are not comparable: other
  // tests (names or definitions), a selection empty now and not before, or a source model of the
  // previous run missing now.
  const PreviousClashRun* previous = nullptr;
  // Optional, on the calling thread: the test running (index in the file) and the clash's progress.
  std::function<void(size_t test, uint64_t done, uint64_t total)> progress;
};

// Runs every test of `tests` over `db` and fills *run (replaced): per test its summary, and the groups
// with their records (keys, groups, statuses). Errors from the store are returned as they are; on an
// error *run is incomplete.
Status RunClashTests(const Database& db, const ClashTestFile& tests, const ClashTestOptions& options,
                     ClashRun* run);

}  // namespace mktree
