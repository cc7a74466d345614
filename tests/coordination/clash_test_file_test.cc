// The clash-test file: what it reads (defaults, modes, rules, selections), the fingerprints that decide
// whether runs compare, and bad files refused with the file and line; the selections' globs and IFC
// supertypes.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "engine/coordination/selection.h"
#include "mktree/clash_tests.h"

namespace mktree {
namespace {

ClashTestFile Parse(const std::string& text) {
  auto f = ParseClashTests(text, "t.json");
  EXPECT_TRUE(f.ok()) << f.status().ToString();
  return f.ok() ? *f : ClashTestFile();
}

TEST(ClashTestFile, ReadsTestsWithTheirDefaults) {
  const ClashTestFile f = Parse(R"({"tests": [
    {"name": "mep-vs-structure", "a": {"ifc_type": ["IfcDuct*", "IfcPipe*"], "exclude": {"name": ["*temp*"]}},
     "b": {"ifc_type": "IfcBeam"}, "clearance": 0.05, "touch_tolerance": 0.001,
     "rules": ["hosted_fillings", {"same_group": "/"}, {"same_attribute": ["layer", "group"]},
               {"approved": ["0123456789abcdef", ["m.ifc|A", "m.ifc|B"]]}], "group": {"proximity": 0.5}},
    {"name": "self", "a": {}, "mode": "hard", "keep_spatial": true, "comment": "all against all"},
    {"name": "dups", "a": {}, "mode": "duplicates", "tolerance": 0.0005}]})");
  ASSERT_EQ(f.tests.size(), 3u);
  const ClashTest& t = f.tests[0];
  EXPECT_EQ(t.name, "mep-vs-structure");
  EXPECT_EQ(t.line, 2u);
  EXPECT_EQ(t.mode, ClashTestMode::kClearance);  // a clearance without a mode
  EXPECT_EQ(t.clearance, 0.05);
  EXPECT_EQ(t.touch_tolerance, 0.001);
  ASSERT_EQ(t.a.include.size(), 1u);
  EXPECT_EQ(t.a.include[0].second, (std::vector<std::string>{"IfcDuct*", "IfcPipe*"}));
  ASSERT_EQ(t.a.exclude.size(), 1u);
  EXPECT_EQ(t.a.exclude[0].first, "name");
  ASSERT_TRUE(t.b);
  EXPECT_EQ(t.b->include[0].second, std::vector<std::string>{"IfcBeam"});
  EXPECT_TRUE(t.rules.hosted_fillings);
  EXPECT_FALSE(t.rules.same_aggregate);  // a rules list says which
  EXPECT_EQ(t.rules.same_group_separator, "/");
  EXPECT_EQ(t.rules.same_attribute, (std::vector<std::string>{"layer", "group"}));
  EXPECT_EQ(t.rules.approved_keys, std::vector<std::string>{"0123456789abcdef"});
  ASSERT_EQ(t.rules.approved_pairs.size(), 1u);
  EXPECT_EQ(t.grouping, ClashGrouping::kProximity);
  EXPECT_EQ(t.group_distance, 0.5);
  const ClashTest& s = f.tests[1];
  EXPECT_FALSE(s.b);
  EXPECT_TRUE(s.a.everything());
  EXPECT_EQ(s.mode, ClashTestMode::kHard);
  EXPECT_EQ(s.touch_tolerance, 0.002);
  EXPECT_TRUE(s.rules.keep_spatial);
  EXPECT_TRUE(s.rules.hosted_fillings && s.rules.same_aggregate);  // no rules list: the defaults
  EXPECT_EQ(s.grouping, ClashGrouping::kElement);
  EXPECT_EQ(f.tests[2].mode, ClashTestMode::kDuplicates);
  EXPECT_EQ(f.tests[2].tolerance, 0.0005);
}

TEST(ClashTestFile, FingerprintFollowsTheDefinition) {
  const ClashTestFile f = Parse(R"({"tests": [{"name": "x", "a": {"name": "p*"}},
    {"name": "x2", "a": {"name": ["p*"]}, "touch_tolerance": 0.002}]})");
  // Defaults written out or not, a pattern or a list of one: the same definition but for the name.
  ClashTest second = f.tests[1];
  second.name = "x";
  EXPECT_EQ(ClashTestFingerprint(f.tests[0]), ClashTestFingerprint(second));
  second.touch_tolerance = 0.003;
  EXPECT_NE(ClashTestFingerprint(f.tests[0]), ClashTestFingerprint(second));
  second = f.tests[0];
  second.rules.keep_spatial = true;
  EXPECT_NE(ClashTestFingerprint(f.tests[0]), ClashTestFingerprint(second));
  EXPECT_EQ(ClashTestFingerprint(f.tests[0]).size(), 16u);
  EXPECT_NE(ClashTestDefinition(f.tests[0]).find("\"touch_tolerance\":0.002"), std::string::npos);
}

TEST(ClashTestFile, BadFilesNameTheFileAndLine) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"{\"tests\": [\n{\"name\": \"x\", \"a\": {}\n,,]}", "t.json:3: not JSON"},
      {"{\"tests\": [\n {\"name\": \"x\",\n  \"a\": {}, \"bogus\": 1}]}",
       "t.json:3: unknown key \"bogus\" in a test"},
      {"{\"tests\": []}", "t.json:1: \"tests\" is not a non-empty list"},
      {"{\"tets\": []}", "t.json:1: unknown key \"tets\" in the file"},
      {"[1]", "t.json:1: the file is not a JSON object"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {}},\n {\"name\": \"x\", \"a\": {}}]}",
       "t.json:2: a second test named \"x\""},
      {"{\"tests\": [{\"name\": \"x\"}]}", "t.json:1: test \"x\": no selection a"},
      {"{\"tests\": [{\"a\": {}}]}", "t.json:1: a test without a name"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {\"ifc_type\": []}}]}", "a.ifc_type is not a pattern"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {\"exclude\": {\"exclude\": {}}}}]}",
       "an exclude inside an exclude"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {},\n \"clearance\": -1}]}",
       "t.json:2: clearance must be a finite number >= 0"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {}, \"mode\": \"hard\",\n \"clearance\": 0.1}]}",
       "t.json:2: a clearance > 0 goes with mode clearance"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {}, \"mode\": \"clearance\"}]}",
       "mode clearance needs a clearance > 0"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {}, \"mode\": \"soft\"}]}", "unknown mode \"soft\""},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {},\n\n \"rules\": [\"same_colour\"]}]}",
       "t.json:3: unknown rule \"same_colour\""},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {}, \"rules\": [{\"approved\": [3]}]}]}",
       "an approved entry is neither"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {}, \"group\": {\"proximity\": 0}}]}",
       "group.proximity must be a finite number > 0"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {}, \"tolerance\": 0.1}]}",
       "tolerance goes with mode duplicates"},
      {"{\"tests\": [{\"name\": \"x\", \"a\": {}, \"a\": {}}]}", "t.json: a key repeats within an object"},
  };
  for (const auto& [text, want] : cases) {
    auto f = ParseClashTests(text, "t.json");
    ASSERT_FALSE(f.ok()) << text;
    EXPECT_EQ(f.status().code(), Status::Code::kInvalidArgument);
    EXPECT_NE(f.status().message().find(want), std::string::npos)
        << f.status().message() << "\nwant: " << want;
  }
  auto missing = ReadClashTests("/nonexistent/tests.json");
  EXPECT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("/nonexistent/tests.json"), std::string::npos);
}

TEST(Selection, GlobsKeysAndIfcSupertypes) {
  using coordination::GlobMatch;
  EXPECT_TRUE(GlobMatch("IfcDuct*", "IfcDuctSegment"));
  EXPECT_TRUE(GlobMatch("*temp*", "a_temp_b"));
  EXPECT_TRUE(GlobMatch("a?c", "abc"));
  EXPECT_FALSE(GlobMatch("a?c", "ac"));
  EXPECT_TRUE(GlobMatch("*", ""));
  EXPECT_FALSE(GlobMatch("IfcDuct*", "ifcductsegment"));
  EXPECT_TRUE(GlobMatch("IfcDuct*", "IFCDUCTSEGMENT", true));
  EXPECT_TRUE(GlobMatch("a*b*c", "aXbYbZc"));
  EXPECT_FALSE(GlobMatch("a*b*c", "aXbYbZ"));
  EXPECT_FALSE(GlobMatch(std::string(30, '*') + "b", std::string(60, 'a')));  // no exponential backtracking

  ObjectRecord wall;
  wall.name = "Wall-12";
  wall.source = "/models/a.ifc";
  wall.attributes = {
      {"ifc_type", "IFCWALLSTANDARDCASE"}, {"ifc_material", "Concrete"}, {"ifc_material", "Plaster"}};
  auto picks = [&](Selection s) { return coordination::SelectionMatcher(s).Matches(wall); };
  EXPECT_TRUE(picks({}));
  EXPECT_TRUE(picks({{{"ifc_type", {"IfcWall"}}}, {}}));  // a supertype selects its subtypes
  EXPECT_FALSE(picks({{{"ifc_type", {"IfcSlab"}}}, {}}));
  EXPECT_TRUE(picks({{{"ifc_type", {"IfcBuildingElement"}}}, {}}));
  EXPECT_TRUE(picks({{{"ifc_material", {"Plaster"}}}, {}}));                 // any value of a repeated key
  EXPECT_TRUE(picks({{{"source", {"*a.ifc"}}, {"name", {"Wall-*"}}}, {}}));  // every key
  EXPECT_FALSE(picks({{{"source", {"*a.ifc"}}, {"name", {"Door-*"}}}, {}}));
  EXPECT_FALSE(picks({{{"layer", {"*"}}}, {}}));                     // a key the object lacks
  EXPECT_FALSE(picks({{}, {{"name", {"*-12"}}}}));                   // excluded
  EXPECT_TRUE(picks({{}, {{"name", {"*-12"}}, {"layer", {"*"}}}}));  // the exclude needs every key too
}

}  // namespace
}  // namespace mktree
