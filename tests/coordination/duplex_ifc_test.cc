// The clash tests on a real IFC model through today's assimp reader, which gives ifc_type, ifc_name and
// ifc_global_id (no relations): selections by IFC type with subtypes, keys made of the GlobalIds, each test
// against the self-clash's pairs filtered by the records' types.
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "coordination/coordination_fixtures.h"
#include "engine/coordination/clash_keys.h"
#include "mktree/build.h"
#include "test_dirs.h"

namespace mktree {
namespace {

TEST(DuplexIfc, TypeSelectionsAndGlobalIdKeys) {
  static const testing::TempDir dir("mktree_duplex_tests");
  const std::string store = dir.file("duplex.mkt");
  auto built = BuildFromFiles({std::string(MKTREE_SHARED_DATA) + "/buildings/duplex.ifc"}, store);
  ASSERT_TRUE(built.ok()) << built.status().ToString();
  auto db = testing::OpenStore(store);
  std::vector<ObjectRecord> records;
  for (ObjectId id = 0; id < db->object_count(); ++id) {
    auto r = db->Object(id);
    ASSERT_TRUE(r.ok());
    records.push_back(*r);
  }
  auto type = [&](ObjectId id) { return std::string(coordination::AttributeValue(records[id], "ifc_type")); };
  std::vector<ClashPair> all;
  ASSERT_TRUE(db->SelfClash(
                    {}, [&](const ClashPair& p) { all.push_back(p); }, nullptr)
                  .ok());
  const ClashRun run = testing::RunTests(*db, testing::Tests(R"({"tests": [
    {"name": "openings", "a": {"ifc_type": ["IfcDoor", "IfcWindow"]}, "b": {"ifc_type": ["IfcWall"]},
     "rules": [], "keep_spatial": true},
    {"name": "all", "a": {}, "rules": [], "keep_spatial": true}]})"));
  const std::set<std::string> fillings{"IfcDoor", "IfcWindow", "IfcDoorStandardCase",
                                       "IfcWindowStandardCase"};
  const std::set<std::string> walls{"IfcWall", "IfcWallStandardCase", "IfcWallElementedCase"};
  std::set<std::pair<ObjectId, ObjectId>> want, got, want_all, got_all;
  for (const ClashPair& p : all) {
    want_all.insert({p.a, p.b});
    if ((fillings.count(type(p.a)) && walls.count(type(p.b))) ||
        (fillings.count(type(p.b)) && walls.count(type(p.a))))
      want.insert({p.a, p.b});
  }
  size_t standard_case_walls = 0;
  for (const testing::RunRecord& r : testing::Records(run)) {
    (r.test == "openings" ? got : got_all).insert({r.pair.a, r.pair.b});
    for (const ObjectIdentity* o : {r.a.get(), r.b.get()}) {
      ASSERT_FALSE(o->global_id.empty());
      EXPECT_EQ(o->stable, "duplex.ifc|" + o->global_id);
      standard_case_walls += o->ifc_type == "IfcWallStandardCase";
    }
    EXPECT_EQ(r.key, coordination::ClashKey(r.test, r.a->stable, r.b->stable));
  }
  EXPECT_EQ(got, want);
  EXPECT_EQ(got_all, want_all);  // no rule, spatial containers kept: nothing removed
  EXPECT_GT(want.size(), 20u);
  EXPECT_GT(standard_case_walls, 0u);  // "IfcWall" selected its subtype
  for (const ClashTestSummary& s : run.tests) {
    EXPECT_EQ(s.sources.size(), 1u);
    for (const auto& [rule, n] : s.excluded_by_rule) EXPECT_EQ(n, 0u) << rule;
  }
}

}  // namespace
}  // namespace mktree
