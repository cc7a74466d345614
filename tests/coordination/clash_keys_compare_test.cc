// Stable keys and revisions: the keys and groups of a run do not depend on ids, load order, A/B order, the
// store being rebuilt or sharded; a revision that removes one clash and adds one compares as exactly one
// resolved, one new, the rest active; runs that are not comparable are refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "coordination/coordination_fixtures.h"
#include "mktree/changes.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::TempPath;

const char* kMepAndAll = R"({"tests": [
  {"name": "mep", "a": {"ifc_type": ["IfcDuctSegment", "IfcPipeSegment"]}, "b": {"ifc_type": ["IfcWall*", "IfcBeam"]}},
  {"name": "all", "a": {}, "group": {"proximity": 2.0}}]})";
const char* kSwapped = R"({"tests": [
  {"name": "mep", "b": {"ifc_type": ["IfcDuctSegment", "IfcPipeSegment"]}, "a": {"ifc_type": ["IfcWall*", "IfcBeam"]}},
  {"name": "all", "a": {}, "group": {"proximity": 2.0}}]})";

// test/key -> (identity a, identity b, group), with identities sorted.
std::map<std::string, std::tuple<std::string, std::string, std::string>> Keyed(const ClashRun& run) {
  std::map<std::string, std::tuple<std::string, std::string, std::string>> out;
  for (const testing::RunRecord& r : testing::Records(run)) {
    auto ids = std::minmax(r.a->stable, r.b->stable);
    EXPECT_TRUE(out.emplace(r.test + "/" + r.key, std::tuple{ids.first, ids.second, r.group}).second);
  }
  return out;
}

TEST(ClashKeys, StableUnderOrderSidesAndRebuilds) {
  const auto scene = testing::AttributedScene(600, 11);
  testing::BuildScene(scene, TempPath("k1.mkt"));
  auto db = testing::OpenStore(TempPath("k1.mkt"));
  const ClashRun first = testing::RunTests(*db, testing::Tests(kMepAndAll));
  const auto keyed = Keyed(first);
  ASSERT_GT(keyed.size(), 200u);
  // Reordered input: other ids for every object.
  auto shuffled = scene;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937_64(12));
  for (size_t i = 0; i < shuffled.size(); ++i) shuffled[i].id = static_cast<ObjectId>(i);
  testing::BuildScene(shuffled, TempPath("k2.mkt"));
  auto db2 = testing::OpenStore(TempPath("k2.mkt"));
  const ClashRun reordered = testing::RunTests(*db2, testing::Tests(kMepAndAll));
  EXPECT_EQ(Keyed(reordered), keyed);
  // The ids did change.
  size_t moved = 0;
  const auto r1 = testing::Records(first), r2 = testing::Records(reordered);
  for (size_t i = 0; i < r1.size() && i < r2.size(); ++i) moved += r1[i].pair.a != r2[i].pair.a;
  EXPECT_GT(moved, 0u);
  // A and B swapped: the same keys, groups and counts (the fingerprint changes: the definition did).
  const ClashRun swapped = testing::RunTests(*db, testing::Tests(kSwapped));
  EXPECT_EQ(Keyed(swapped), keyed);
  // Rebuilt as a sharded store.
  testing::BuildScene(scene, TempPath("k3.mkt"), 3);
  auto sharded = testing::OpenStore(TempPath("k3.mkt"));
  ASSERT_EQ(sharded->shard_count(), 3u);
  const ClashRun over_shards = testing::RunTests(*sharded, testing::Tests(kMepAndAll));
  EXPECT_EQ(Keyed(over_shards), keyed);
  // The groups' keys, boxes and order too.
  ASSERT_EQ(over_shards.groups.size(), first.groups.size());
  for (size_t i = 0; i < first.groups.size(); ++i) {
    EXPECT_EQ(over_shards.groups[i].key, first.groups[i].key);
    EXPECT_EQ(reordered.groups[i].key, first.groups[i].key);
    EXPECT_EQ(reordered.groups[i].members.size(), first.groups[i].members.size());
  }
}

// A previous run as ReadPreviousClashRun would give it from this run's lines.
PreviousClashRun AsPrevious(const ClashRun& run) {
  PreviousClashRun p;
  p.file = "previous.jsonl";
  for (const ClashTestSummary& s : run.tests) {
    PreviousClashRun::Test t;
    t.name = s.name;
    t.fingerprint = s.fingerprint;
    t.selected_a = s.selected_a;
    t.selected_b = s.selected_b;
    t.sources = s.sources;
    for (const testing::RunRecord& r : testing::Records(run))
      if (r.test == s.name && r.status != ClashStatus::kResolved) {
        t.records.push_back(r);
        t.group_of.push_back(static_cast<uint32_t>(t.group_keys.size()));
        t.group_keys.push_back(r.group);
      }
    p.tests.push_back(std::move(t));
  }
  return p;
}

// An object with exactly one clash in `run`'s test, and the other one.
std::pair<ObjectId, ObjectId> LoneClash(const ClashRun& run, const std::string& test) {
  std::map<ObjectId, int> degree;
  const auto records = testing::Records(run);
  for (const testing::RunRecord& r : records)
    if (r.test == test) ++degree[r.pair.a], ++degree[r.pair.b];
  for (const testing::RunRecord& r : records)
    if (r.test == test && degree[r.pair.a] == 1) return {r.pair.a, r.pair.b};
  ADD_FAILURE() << "no object with one clash";
  return {0, 0};
}

TEST(ClashCompare, RevisionResolvesOneAndAddsOne) {
  const auto scene = testing::AttributedScene(600, 13);
  const std::string path = TempPath("rev.mkt");
  testing::BuildScene(scene, path);
  const ClashTestFile tests =
      testing::Tests(R"({"tests": [{"name": "all", "a": {}, "keep_spatial": true}]})");
  auto db0 = testing::OpenStore(path);
  const ClashRun before = testing::RunTests(*db0, tests);
  const uint64_t n_before = testing::Records(before).size();
  ASSERT_GT(n_before, 100u);
  const auto [lone, partner] = LoneClash(before, "all");
  ObjectId host = 0;
  const SceneObject added = testing::CubeClashingWithOne(scene, lone, partner, "added_cube", "GNEW", &host);
  {
    auto w = ChangeWriter::Open(path);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    ChangeBatch batch;
    batch.remove.push_back(lone);
    batch.add.push_back(added);
    auto done = (*w)->Commit(batch);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
  }
  auto db1 = testing::OpenStore(path);
  ASSERT_GT(db1->revision(), 0u);
  const PreviousClashRun previous = AsPrevious(before);
  ClashTestOptions o;
  o.previous = &previous;
  const ClashRun after = testing::RunTests(*db1, tests, o);
  const ClashTestSummary& s = after.tests[0];
  EXPECT_EQ(s.resolved, 1u);
  EXPECT_EQ(s.new_clashes, 1u);
  EXPECT_EQ(s.active, n_before - 1);
  uint64_t resolved = 0, fresh = 0;
  for (const testing::RunRecord& r : testing::Records(after)) {
    if (r.status == ClashStatus::kResolved) {
      ++resolved;
      EXPECT_TRUE(r.pair.a == lone || r.pair.b == lone);
    }
    if (r.status == ClashStatus::kNew) {
      ++fresh;
      EXPECT_TRUE(r.a->global_id == "GNEW" || r.b->global_id == "GNEW");
      EXPECT_TRUE(r.pair.a == host || r.pair.b == host);
    }
  }
  EXPECT_EQ(resolved, 1u);
  EXPECT_EQ(fresh, 1u);
  for (const ClashGroup& g : after.groups) EXPECT_NE(g.status, ClashStatus::kNone);

  // The old revision against itself: everything active.
  const ClashRun same = testing::RunTests(*db0, tests, o);
  EXPECT_EQ(same.tests[0].active, n_before);
  EXPECT_EQ(same.tests[0].new_clashes + same.tests[0].resolved, 0u);
}

TEST(ClashCompare, NotComparableIsRefused) {
  const auto scene = testing::AttributedScene(300, 17);
  testing::BuildScene(scene, TempPath("nc.mkt"));
  auto db = testing::OpenStore(TempPath("nc.mkt"));
  const ClashTestFile tests =
      testing::Tests(R"({"tests": [{"name": "t", "a": {"ifc_type": ["IfcBeam"]}, "b": {}}]})");
  const ClashRun run = testing::RunTests(*db, tests);
  auto refused = [&](PreviousClashRun p, const ClashTestFile& f, const std::string& why) {
    ClashTestOptions o;
    o.previous = &p;
    ClashRun r;
    const Status st = RunClashTests(*db, f, o, &r);
    EXPECT_EQ(st.code(), Status::Code::kInvalidArgument) << why;
    EXPECT_NE(st.message().find("previous.jsonl: not comparable"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find(why), std::string::npos) << st.message();
  };
  // A selection empty now that was not before (same definition: the objects went).
  PreviousClashRun p = AsPrevious(run);
  const ClashTestFile none =
      testing::Tests(R"({"tests": [{"name": "t", "a": {"ifc_type": ["IfcNoSuch"]}, "b": {}}]})");
  PreviousClashRun q = AsPrevious(testing::RunTests(*db, none));
  q.tests[0].selected_a = 5;
  refused(q, none, "selection a of test \"t\" picks no object now (5 before)");
  // A source model missing.
  p.tests[0].sources.push_back("models/gone.ifc");
  refused(p, tests, "source model \"models/gone.ifc\" is missing now");
  // Another definition, another test set.
  refused(AsPrevious(run),
          testing::Tests(
              R"({"tests": [{"name": "t", "a": {"ifc_type": ["IfcBeam"]}, "b": {}, "mode": "hard"}]})"),
          "is defined otherwise");
  refused(AsPrevious(run), testing::Tests(R"({"tests": [{"name": "u", "a": {}}]})"), "test \"u\" is new");
}

}  // namespace
}  // namespace mktree
