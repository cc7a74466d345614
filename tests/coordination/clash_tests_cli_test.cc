// `mktree clash STORE --tests FILE [--names] [--compare PREVIOUS.jsonl]` end to end through the built tool:
// the lines per test (pairs with test, key, group and identities; a summary with the rule counts and
// warnings) agree with RunClashTests; a second store with one clash fewer and one more compares as one
// resolved line, one new and the rest active; bad test files and previous files are one error line naming
// the file and line, a non-zero exit and nothing on standard output.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "coordination/coordination_fixtures.h"
#include "test_dirs.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using Json = nlohmann::json;

using testing::ProgramDir;
using testing::TempPath;

void Write(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

std::vector<Json> Lines(const std::string& out) {
  std::vector<Json> lines;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) {
    lines.push_back(Json::parse(line, nullptr, false));
    EXPECT_FALSE(lines.back().is_discarded()) << line;
  }
  return lines;
}

testing::ToolRun Clash(const std::string& args) {
  return testing::RunMktree("clash " + args, ProgramDir().path());
}

const char* kTests = R"({"tests": [
  {"name": "mep-vs-structure", "a": {"ifc_type": ["IfcDuct*", "IfcPipe*"]}, "b": {"source": ["*structure.ifc"]}},
  {"name": "all", "a": {}, "rules": ["hosted_fillings", {"same_group": "/"}], "group": {"proximity": 1.5}},
  {"name": "nothing", "a": {"name": ["no such object"]}}
]})";

class ClashTestsCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = new std::vector<SceneObject>(testing::AttributedScene(500, 23));
    testing::BuildScene(*scene_, TempPath("s1.mkt"));
    Write(TempPath("tests.json"), kTests);
  }
  static void TearDownTestSuite() { delete scene_; }
  static std::vector<SceneObject>* scene_;
};
std::vector<SceneObject>* ClashTestsCli::scene_ = nullptr;

TEST_F(ClashTestsCli, LinesPerTestAgreeWithTheLibrary) {
  const auto r = Clash(TempPath("s1.mkt") + " --tests " + TempPath("tests.json") + " --names");
  ASSERT_EQ(r.code, 0) << r.err;
  auto db = testing::OpenStore(TempPath("s1.mkt"));
  const ClashRun run = testing::RunTests(*db, testing::Tests(kTests));
  std::map<std::string, std::set<std::string>> keys_by_test;  // from the pair lines
  std::map<std::string, Json> summary;
  std::vector<std::string> order;
  for (const Json& j : Lines(r.out)) {
    const std::string test = j.at("test");
    if (j.value("summary", false)) {
      summary[test] = j;
      order.push_back(test);
      continue;
    }
    EXPECT_EQ(summary.count(test), 0u) << "a pair line after its test's summary";
    EXPECT_TRUE(keys_by_test[test].insert(j.at("key").get<std::string>()).second);
    for (const char* k : {"group", "id_a", "id_b", "name_a", "name_b", "class", "point_a"})
      EXPECT_TRUE(j.contains(k)) << k;
    EXPECT_FALSE(j.contains("status"));
    EXPECT_EQ((*scene_)[j.at("a").get<ObjectId>()].name, j.at("name_a").get<std::string>());
  }
  EXPECT_EQ(order, (std::vector<std::string>{"mep-vs-structure", "all", "nothing"}));
  for (const ClashTestSummary& s : run.tests) {
    std::set<std::string> want;
    for (const testing::RunRecord& rec : testing::Records(run))
      if (rec.test == s.name) want.insert(rec.key);
    EXPECT_EQ(keys_by_test[s.name], want) << s.name;
    const Json& j = summary[s.name];
    EXPECT_EQ(j.at("pairs").get<uint64_t>(), want.size());
    EXPECT_EQ(j.at("fingerprint").get<std::string>(), s.fingerprint);
    EXPECT_EQ(j.at("selected_a").get<uint64_t>(), s.selected_a);
    uint64_t excluded = 0;
    for (const auto& [rule, n] : s.excluded_by_rule) {
      EXPECT_EQ(j.at("excluded_by_rule").at(rule).get<uint64_t>(), n) << rule;
      excluded += n;
    }
    EXPECT_EQ(j.at("excluded").get<uint64_t>(), excluded);
  }
  EXPECT_GT(summary["all"]["excluded_by_rule"]["same_group"].get<uint64_t>(), 0u);
  EXPECT_EQ(summary["nothing"]["warning_count"], 1);
  EXPECT_EQ(summary["nothing"]["pairs"], 0);
}

TEST_F(ClashTestsCli, CompareWithAnotherStore) {
  const auto first = Clash(TempPath("s1.mkt") + " --tests " + TempPath("tests.json") + " --names");
  ASSERT_EQ(first.code, 0) << first.err;
  Write(TempPath("previous.jsonl"), first.out);
  // One object with a single clash in "all" removed, one cube clashing with one object added.
  std::map<ObjectId, int> degree;
  std::vector<std::pair<ObjectId, ObjectId>> all_pairs;
  for (const Json& j : Lines(first.out))
    if (j.at("test") == "all" && !j.value("summary", false)) {
      all_pairs.emplace_back(j.at("a"), j.at("b"));
      ++degree[all_pairs.back().first], ++degree[all_pairs.back().second];
    }
  ObjectId lone = 0, partner = 0;
  for (const auto& [a, b] : all_pairs)
    if (degree[a] == 1 && (*scene_)[a].source == "models/mep.ifc") {
      lone = a, partner = b;
      break;
    }
  ASSERT_NE(lone, partner);
  std::vector<SceneObject> second;
  for (const SceneObject& o : *scene_)
    if (o.id != lone) second.push_back(o);
  ObjectId host = 0;
  second.push_back(testing::CubeClashingWithOne(*scene_, lone, partner, "added", "GADDED", &host));
  for (size_t i = 0; i < second.size(); ++i) second[i].id = static_cast<ObjectId>(i);
  testing::BuildScene(second, TempPath("s2.mkt"));
  const auto r = Clash(TempPath("s2.mkt") + " --tests " + TempPath("tests.json") + " --compare " +
                       TempPath("previous.jsonl") + " --names");
  ASSERT_EQ(r.code, 0) << r.err;
  std::map<std::string, std::map<std::string, int>> statuses;
  for (const Json& j : Lines(r.out)) {
    if (j.value("summary", false)) {
      if (j.at("test") == "all") {
        EXPECT_EQ(j.at("new"), 1);
        EXPECT_EQ(j.at("resolved"), 1);
        EXPECT_EQ(j.at("active").get<int>() + 1, static_cast<int>(all_pairs.size()));
      }
      continue;
    }
    ++statuses[j.at("test")][j.at("status")];
    if (j.at("test") == "all" && j.at("status") == "resolved") {
      const auto prev = ReadPreviousClashRun(TempPath("previous.jsonl"));
      ASSERT_TRUE(prev.ok()) << prev.status().ToString();
      bool seen = false;
      for (const auto& t : prev->tests)
        for (const ClashRecord& rec : t.records)
          if (rec.key == j.at("key")) {
            seen = true;
            for (const ObjectIdentity* o : {rec.a.get(), rec.b.get()}) {
              EXPECT_TRUE(o->source == "mep.ifc" || o->source == "structure.ifc") << o->source;
              if (o->stable.find("|name=") == std::string::npos) {
                EXPECT_EQ(o->stable, o->source + "|" + o->global_id);
                EXPECT_EQ(o->global_id.substr(0, 1), "G");
              } else {
                EXPECT_TRUE(o->global_id.empty());
              }
            }
          }
      EXPECT_TRUE(seen);
      EXPECT_TRUE(j.at("name_a") == (*scene_)[lone].name || j.at("name_b") == (*scene_)[lone].name);
      EXPECT_EQ(j.at("a").get<ObjectId>(), std::min(lone, partner));  // the previous run's values
    }
    if (j.at("test") == "all" && j.at("status") == "new")
      EXPECT_TRUE(j.at("name_a") == "added" || j.at("name_b") == "added");
  }
  EXPECT_EQ(statuses["all"]["new"], 1);
  EXPECT_EQ(statuses["all"]["resolved"], 1);
  EXPECT_EQ(statuses["all"]["active"] + 1, static_cast<int>(all_pairs.size()));
  // A store compared with its own run: everything active.
  const auto same = Clash(TempPath("s1.mkt") + " --tests " + TempPath("tests.json") + " --compare " +
                          TempPath("previous.jsonl"));
  ASSERT_EQ(same.code, 0) << same.err;
  for (const Json& j : Lines(same.out))
    if (!j.value("summary", false)) EXPECT_EQ(j.at("status"), "active");
}

// Each bad invocation: exit 1, one error line naming what is wrong, nothing on standard output.
void ExpectRefused(const std::string& args, const std::string& want) {
  const auto r = Clash(args);
  EXPECT_EQ(r.code, 1) << args;
  EXPECT_TRUE(r.out.empty()) << r.out.substr(0, 300);
  EXPECT_NE(r.err.find(want), std::string::npos) << r.err << "\nwant: " << want;
}

TEST_F(ClashTestsCli, BadInputIsRefusedNamingFileAndLine) {
  const std::string store = TempPath("s1.mkt");
  Write(TempPath("unknown.json"), "{\"tests\": [\n  {\"name\": \"x\", \"a\": {},\n   \"colour\": \"red\"}]}");
  ExpectRefused(store + " --tests " + TempPath("unknown.json"), "unknown.json:3: unknown key \"colour\"");
  Write(TempPath("broken.json"), "{\"tests\": [\n  {\"name\": \"x\", \"a\": {}\n  ]}");
  ExpectRefused(store + " --tests " + TempPath("broken.json"), "broken.json:3: not JSON");
  ExpectRefused(store + " --tests " + TempPath("absent.json"), "absent.json: cannot open");
  // Previous files that are not a test run's lines.
  const auto first = Clash(store + " --tests " + TempPath("tests.json"));
  ASSERT_EQ(first.code, 0);
  std::string damaged = first.out;
  damaged.insert(damaged.find('\n', damaged.find('\n') + 1) + 1, "{\"test\": \"all\", \"key\n");
  Write(TempPath("damaged.jsonl"), damaged);
  ExpectRefused(store + " --tests " + TempPath("tests.json") + " --compare " + TempPath("damaged.jsonl"),
                "damaged.jsonl:3: not a JSON object");
  const auto plain = Clash(store);
  Write(TempPath("plain.jsonl"), plain.out);
  ExpectRefused(store + " --tests " + TempPath("tests.json") + " --compare " + TempPath("plain.jsonl"),
                "plain.jsonl:1: a line without \"test\" and \"key\"");
  Write(TempPath("flag.jsonl"), "{\"test\": \"all\", \"summary\": 1}\n");
  ExpectRefused(store + " --tests " + TempPath("tests.json") + " --compare " + TempPath("flag.jsonl"),
                "flag.jsonl:1: \"summary\" is not true or false");
  Write(TempPath("empty.jsonl"), "");
  ExpectRefused(store + " --tests " + TempPath("tests.json") + " --compare " + TempPath("empty.jsonl"),
                "empty.jsonl: no test summary line");
  // Not comparable: another test set, a test defined otherwise.
  Write(TempPath("previous.jsonl"), first.out);
  Write(TempPath("other.json"), "{\"tests\": [{\"name\": \"all\", \"a\": {}}]}");
  ExpectRefused(store + " --tests " + TempPath("other.json") + " --compare " + TempPath("previous.jsonl"),
                "previous.jsonl: not comparable with this run: test \"all\" is defined otherwise");
  // Options a test file decides.
  ExpectRefused(store + " --tests " + TempPath("tests.json") + " --clearance 0.1",
                "--clearance does not go with --tests");
  ExpectRefused(store + " --compare " + TempPath("previous.jsonl"), "--compare goes with --tests");
}

}  // namespace
}  // namespace mktree
