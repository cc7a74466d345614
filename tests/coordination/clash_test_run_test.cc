// RunClashTests against brute force: on random scenes with attributes, each test's pairs are exactly the
// self-clash's pairs with one object in A and the other in B (selections evaluated here independently)
// that no rule removes, and each rule's count is exactly the pairs it removes, first rule first: found +
// excluded = all pairs of A x B. A narrow test reads fewer pages than the self-clash.
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "coordination/coordination_fixtures.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::Attr;

using testing::TempPath;

std::vector<ClashPair> SelfClash(const Database& db, const ClashOptions& o) {
  std::vector<ClashPair> out;
  const Status st = db.SelfClash(
      o, [&](const ClashPair& p) { out.push_back(p); }, nullptr);
  EXPECT_TRUE(st.ok()) << st.ToString();
  return out;
}

bool StartsWith(const std::string& s, const std::string& p) { return s.compare(0, p.size(), p) == 0; }

// The rules as docs/clash_workflow.md states them, written out again.
struct BruteRules {
  bool spatial = true, hosted = false, aggregate = false;
  std::string group_sep;
  std::string same_attr;
  std::set<std::pair<ObjectId, ObjectId>> approved;

  // The first rule removing (a, b), or "".
  std::string Removing(const SceneObject& a, const SceneObject& b) const {
    auto spatial_of = [](const SceneObject& o) {
      const std::string t = Attr(o, "ifc_type");
      return Attr(o, "ifc_spatial") == "true" || t == "IfcSpace" || t == "IfcOpeningElement";
    };
    auto names = [](const SceneObject& of, const char* key, const SceneObject& other) {
      const std::string gid = Attr(other, "ifc_global_id");
      return !gid.empty() && Attr(of, key) == gid;
    };
    const bool same_source = a.source == b.source;
    if (spatial && (spatial_of(a) || spatial_of(b))) return "spatial_container";
    if (hosted && same_source &&
        (names(a, "ifc_fills", b) || names(b, "ifc_fills", a) || names(a, "ifc_voids", b) ||
         names(b, "ifc_voids", a)))
      return "hosted_filling";
    if (aggregate && same_source) {
      const std::string ga = Attr(a, "ifc_aggregate"), gb = Attr(b, "ifc_aggregate");
      if ((!ga.empty() && ga == gb) || names(a, "ifc_aggregate", b) || names(b, "ifc_aggregate", a))
        return "same_aggregate";
    }
    if (!group_sep.empty()) {
      const size_t x = a.name.find(group_sep), y = b.name.find(group_sep);
      if (x != std::string::npos && y != std::string::npos && a.name.substr(0, x) == b.name.substr(0, y))
        return "same_group";
    }
    if (!same_attr.empty() && Attr(a, same_attr) == Attr(b, same_attr) && !Attr(a, same_attr).empty())
      return "same_attribute";
    if (approved.count({std::min(a.id, b.id), std::max(a.id, b.id)})) return "approved";
    return "";
  }
};

struct BruteTest {
  std::string name;
  std::function<bool(const SceneObject&)> in_a, in_b;  // in_b null: A against itself
  BruteRules rules;
};

// Checks the run's test against brute force over the self-clash's pairs.
void ExpectBrute(const ClashRun& run, const BruteTest& t, const std::vector<SceneObject>& scene,
                 const std::vector<ClashPair>& all) {
  SCOPED_TRACE("test " + t.name);
  const ClashTestSummary* s = testing::Summary(run, t.name);
  ASSERT_NE(s, nullptr);
  std::set<std::pair<ObjectId, ObjectId>> want;
  std::map<std::string, uint64_t> removed;
  uint64_t in_scope = 0;
  for (const ClashPair& p : all) {
    const SceneObject &a = scene[p.a], &b = scene[p.b];
    const bool scoped =
        t.in_b ? (t.in_a(a) && t.in_b(b)) || (t.in_b(a) && t.in_a(b)) : t.in_a(a) && t.in_a(b);
    if (!scoped) continue;
    ++in_scope;
    const std::string rule = t.rules.Removing(a, b);
    if (rule.empty()) {
      want.insert({p.a, p.b});
    } else {
      ++removed[rule];
    }
  }
  std::set<std::pair<ObjectId, ObjectId>> got;
  for (const testing::RunRecord& r : testing::Records(run))
    if (r.test == t.name) EXPECT_TRUE(got.insert({r.pair.a, r.pair.b}).second) << "a pair twice";
  EXPECT_EQ(got, want);
  uint64_t excluded = 0;
  for (const auto& [rule, n] : s->excluded_by_rule) {
    EXPECT_EQ(n, removed[rule]) << rule;
    excluded += n;
  }
  for (const auto& [rule, n] : removed) EXPECT_EQ(testing::RuleCount(*s, rule), n) << rule << " not counted";
  EXPECT_EQ(got.size() + excluded, in_scope);
  EXPECT_EQ(s->hard + s->touch + s->clearance_pairs, got.size());
  uint64_t na = 0, nb = 0;
  for (const SceneObject& o : scene) {
    na += t.in_a(o);
    nb += t.in_b ? t.in_b(o) : t.in_a(o);
  }
  EXPECT_EQ(s->selected_a, na);
  EXPECT_EQ(s->selected_b, nb);
}

TEST(ClashTests, SelectionsAndRulesAgainstBruteForce) {
  const auto scene = testing::AttributedScene(700, 3);
  const std::string path = TempPath("rules.mkt");
  testing::BuildScene(scene, path);
  auto db = testing::OpenStore(path);
  ASSERT_TRUE(db);
  const auto all = SelfClash(*db, ClashOptions{});
  ASSERT_GT(all.size(), 300u);

  const std::string file = R"({"tests": [
    {"name": "mep-vs-walls", "a": {"ifc_type": ["IfcDuctSegment", "IfcPipe*"]}, "b": {"ifc_type": ["IfcWall"]}},
    {"name": "groups", "a": {"name": ["grp*"]}, "keep_spatial": true,
     "rules": [{"same_group": "/"}, {"same_attribute": "layer"}]},
    {"name": "structure", "a": {}, "b": {"source": ["*structure.ifc"], "exclude": {"ifc_type": ["IfcSpace"]}},
     "rules": ["hosted_fillings", "same_aggregate"]},
    {"name": "nothing", "a": {"ifc_type": ["IfcNoSuchThing"]}, "b": {}}
  ]})";
  const ClashRun run = testing::RunTests(*db, testing::Tests(file));
  auto type_in = [](std::set<std::string> types) {
    return [types](const SceneObject& o) { return types.count(Attr(o, "ifc_type")) > 0; };
  };
  BruteTest mep{"mep-vs-walls",
                type_in({"IfcDuctSegment", "IfcPipeSegment"}),
                type_in({"IfcWall", "IfcWallStandardCase"}),
                {}};
  mep.rules.hosted = mep.rules.aggregate = true;  // the defaults
  BruteTest groups{"groups", [](const SceneObject& o) { return StartsWith(o.name, "grp"); }, nullptr, {}};
  groups.rules.spatial = false;
  groups.rules.group_sep = "/";
  groups.rules.same_attr = "layer";
  BruteTest structure{"structure",
                      [](const SceneObject&) { return true; },
                      [](const SceneObject& o) {
                        return o.source == "models/structure.ifc" && Attr(o, "ifc_type") != "IfcSpace";
                      },
                      {}};
  structure.rules.hosted = structure.rules.aggregate = true;
  for (const BruteTest* t : {&mep, &groups, &structure}) ExpectBrute(run, *t, scene, all);
  // Each rule had pairs to remove.
  for (const auto& [test, rule] :
       std::vector<std::pair<std::string, std::string>>{{"structure", "spatial_container"},
                                                        {"structure", "hosted_filling"},
                                                        {"structure", "same_aggregate"},
                                                        {"groups", "same_group"},
                                                        {"groups", "same_attribute"}})
    EXPECT_GT(testing::RuleCount(*testing::Summary(run, test), rule), 0u) << test << " " << rule;
  // A selection that picks nothing: no pairs, a warning.
  const ClashTestSummary* nothing = testing::Summary(run, "nothing");
  EXPECT_EQ(nothing->selected_a, 0u);
  EXPECT_EQ(nothing->hard + nothing->touch, 0u);
  ASSERT_EQ(nothing->warnings.size(), 1u);
  EXPECT_NE(nothing->warnings[0].find("selection a picks no object"), std::string::npos);

  // Approved pairs, by key and by identities, are removed and counted.
  std::vector<ClashRecord> found;
  for (const testing::RunRecord& r : testing::Records(run))
    if (r.test == "structure") found.push_back(r);
  ASSERT_GE(found.size(), 2u);
  const std::string approving = R"({"tests": [
    {"name": "structure", "a": {}, "b": {"source": ["*structure.ifc"], "exclude": {"ifc_type": ["IfcSpace"]}},
     "rules": ["hosted_fillings", "same_aggregate", {"approved": [")" +
                                found[0].key + R"(", [")" + found[1].b->stable + R"(", ")" +
                                found[1].a->stable + R"("]]}]}]})";
  const ClashRun approved = testing::RunTests(*db, testing::Tests(approving));
  structure.rules.approved = {{found[0].pair.a, found[0].pair.b}, {found[1].pair.a, found[1].pair.b}};
  ExpectBrute(approved, structure, scene, all);
  EXPECT_EQ(testing::RuleCount(approved.tests[0], "approved"), 2u);
}

// Clearance and hard modes against the self-clash with the same options.
TEST(ClashTests, ModesAgainstTheSelfClash) {
  const auto scene = testing::AttributedScene(500, 5);
  const std::string path = TempPath("modes.mkt");
  testing::BuildScene(scene, path);
  auto db = testing::OpenStore(path);
  ClashOptions co;
  co.clearance = 0.05;
  const auto with_clearance = SelfClash(*db, co);
  const ClashRun run = testing::RunTests(*db, testing::Tests(R"({"tests": [
    {"name": "c", "a": {}, "clearance": 0.05, "keep_spatial": true, "rules": []},
    {"name": "h", "a": {}, "mode": "hard", "keep_spatial": true, "rules": []}]})"));
  std::set<std::pair<ObjectId, ObjectId>> want_c, want_h, got_c, got_h;
  for (const ClashPair& p : with_clearance) {
    want_c.insert({p.a, p.b});
    if (p.cls == ClashClass::kHard) want_h.insert({p.a, p.b});
  }
  for (const testing::RunRecord& r : testing::Records(run))
    (r.test == "c" ? got_c : got_h).insert({r.pair.a, r.pair.b});
  EXPECT_EQ(got_c, want_c);
  EXPECT_EQ(got_h, want_h);
  EXPECT_GT(testing::Summary(run, "c")->clearance_pairs, 0u);
  EXPECT_EQ(testing::Summary(run, "h")->touch, 0u);
  EXPECT_EQ(testing::Summary(run, "c")->mode, "clearance");
}

// A narrow test (5 % of the objects, in one band, against 20 %) reads fewer pages than the self-clash.
TEST(ClashTests, NarrowTestReadsFewerPages) {
  auto scene = testing::AttributedScene(3000, 7);
  std::mt19937_64 rng(8);
  for (SceneObject& o : scene) {
    if (o.mesh.Bounds().min[0] < 25 && rng() % 4 == 0) o.attributes.push_back({"zone", "a"});
    if (rng() % 5 == 0) o.attributes.push_back({"zone", "b"});
  }
  const std::string path = TempPath("narrow.mkt");
  testing::BuildScene(scene, path);
  auto db = testing::OpenStore(path, 0);
  const ClashTestFile narrow =
      testing::Tests(R"({"tests": [{"name": "n", "a": {"zone": ["a"]}, "b": {"zone": ["b"]}}]})");
  const ClashTestFile whole = testing::Tests(R"({"tests": [{"name": "w", "a": {}}]})");
  const ClashRun n = testing::RunTests(*db, narrow), w = testing::RunTests(*db, whole);
  const ClashStats &sn = n.tests[0].stats, &sw = w.tests[0].stats;
  EXPECT_LT(sn.pages_read, sw.pages_read);
  EXPECT_LT(2 * sn.pages_read, sw.pages_read);
  EXPECT_LT(sn.leaf_pairs_visited, sw.leaf_pairs_visited);
  EXPECT_LT(sn.candidate_pairs, sw.candidate_pairs);
  std::printf("self-clash: %llu pages read; 5 %% x 20 %%: %llu\n",
              static_cast<unsigned long long>(sw.pages_read), static_cast<unsigned long long>(sn.pages_read));
  // The narrow test's pairs are the whole test's pairs between the zones (rules as defaults in both).
  std::set<std::pair<ObjectId, ObjectId>> want, got;
  auto zone = [&](ObjectId id, const char* z) {
    for (const ObjectAttribute& a : scene[id].attributes)
      if (a.key == "zone" && a.value == z) return true;
    return false;
  };
  for (const testing::RunRecord& r : testing::Records(w)) {
    const ObjectId a = r.pair.a, b = r.pair.b;
    if ((zone(a, "a") && zone(b, "b")) || (zone(a, "b") && zone(b, "a"))) want.insert({a, b});
  }
  for (const testing::RunRecord& r : testing::Records(n)) got.insert({r.pair.a, r.pair.b});
  EXPECT_EQ(got, want);
  EXPECT_GT(got.size(), 5u);
}

}  // namespace
}  // namespace mktree
