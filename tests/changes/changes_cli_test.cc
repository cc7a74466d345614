// The change commands of the command line (docs/cli.md): `mktree update`, `log`, `compact`, `--revision` on
// query, clash and info, and `clash --since`, end to end through the built tool. Answers at the newest
// revision are checked against a fresh `mktree build` of the live objects (by name), answers at an older
// revision against what the tool printed before the change; every bad change is one error line, a non-zero
// exit, and `mktree log` unchanged.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "mktree/changes.h"
#include "test_dirs.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::ToolRun;

// A cube of side `size` with its min corner at (x, y, z), as one OBJ object.
std::string CubeObj(const std::string& name, double x, double y, double z, double size) {
  std::ostringstream s;
  s << "o " << name << "\n";
  for (int k = 0; k < 8; ++k)
    s << "v " << x + size * (k & 1) << " " << y + size * ((k >> 1) & 1) << " " << z + size * ((k >> 2) & 1)
      << "\n";
  s << "f -8 -6 -5 -7\nf -4 -3 -1 -2\nf -8 -7 -3 -4\nf -6 -2 -1 -5\nf -8 -4 -2 -6\nf -7 -5 -1 -3\n";
  return s.str();
}

struct Cube {
  std::string name;
  double x, y, z, size;
};

std::string ObjOf(const std::vector<Cube>& cubes) {
  std::string s;
  for (const Cube& c : cubes) s += CubeObj(c.name, c.x, c.y, c.z, c.size);
  return s;
}

// The text between `key": [` and the next `]` of each line: a query line's hits or names.
std::vector<std::string> ListsOf(const std::string& out, const std::string& key) {
  std::vector<std::string> lists;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) {
    const std::string open = "\"" + key + "\": [";
    const size_t at = line.find(open);
    if (at == std::string::npos) continue;
    const size_t from = at + open.size();
    lists.push_back(line.substr(from, line.find(']', from) - from));
  }
  return lists;
}

// Each line's names list as a sorted list of names (names here hold no comma).
std::vector<std::vector<std::string>> SortedNames(const std::string& out) {
  std::vector<std::vector<std::string>> all;
  for (const std::string& list : ListsOf(out, "names")) {
    std::vector<std::string> names;
    std::istringstream in(list);
    for (std::string n; std::getline(in, n, ',');) {
      n.erase(0, n.find('"') + 1);
      n.erase(n.rfind('"'));
      names.push_back(n);
    }
    std::sort(names.begin(), names.end());
    all.push_back(names);
  }
  return all;
}

std::string Field(const std::string& line, const std::string& key) {
  const std::string k = "\"" + key + "\": ";
  const size_t at = line.find(k);
  if (at == std::string::npos) return "";
  const size_t from = at + k.size();
  if (line[from] == '"') return line.substr(from + 1, line.find('"', from + 1) - from - 1);
  return line.substr(from, line.find_first_of(",}", from) - from);
}

std::vector<std::string> Lines(const std::string& out) {
  std::vector<std::string> lines;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// Clash pair lines as (a, b) ids, or as sorted (name, name, class).
std::set<std::pair<std::string, std::string>> PairIds(const std::string& out,
                                                      const std::string& status = "") {
  std::set<std::pair<std::string, std::string>> pairs;
  for (const std::string& line : Lines(out))
    if (Field(line, "status") == status) pairs.emplace(Field(line, "a"), Field(line, "b"));
  return pairs;
}
std::set<std::tuple<std::string, std::string, std::string>> PairNames(const std::string& out) {
  std::set<std::tuple<std::string, std::string, std::string>> pairs;
  for (const std::string& line : Lines(out)) {
    std::string a = Field(line, "name_a"), b = Field(line, "name_b");
    if (b < a) std::swap(a, b);
    pairs.emplace(a, b, Field(line, "class"));
  }
  return pairs;
}

class ChangesCli : public ::testing::Test {
 protected:
  std::string P(const std::string& name) const { return (dir_.path() / name).string(); }
  ToolRun Mktree(const std::string& args) const { return testing::RunMktree(args, dir_); }
  void Write(const std::string& name, const std::string& text) const {
    std::ofstream(P(name), std::ios::binary) << text;
  }
  std::string Ok(const std::string& args) const {
    const ToolRun r = Mktree(args);
    EXPECT_EQ(r.code, 0) << args << "\n" << r.err;
    return r.out;
  }
  // A failed change: one line "error: ..." holding `named`, nothing on stdout, the log as it was.
  void ExpectRefused(const std::string& args, const std::string& named, const std::string& store) const {
    SCOPED_TRACE(args);
    const std::string log = Ok("log " + store + " --json");
    const ToolRun r = Mktree(args);
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(r.out, "");
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(named), std::string::npos) << r.err;
    EXPECT_EQ(Ok("log " + store + " --json"), log);
  }
  // Points and boxes over the cubes' extent, some of them exact.
  void WriteQueries(const std::string& name) const {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> x(-1, 7), y(-1, 4), z(-1, 3), side(0.1, 2.5);
    std::string text;
    for (int i = 0; i < 60; ++i) {
      const double x0 = x(rng), y0 = y(rng), z0 = z(rng), s = side(rng);
      text += i % 3 == 0 ? "point " + std::to_string(x0) + " " + std::to_string(y0) + " " + std::to_string(z0)
                         : "box " + std::to_string(x0) + " " + std::to_string(y0) + " " + std::to_string(z0) +
                               " " + std::to_string(x0 + s) + " " + std::to_string(y0 + s / 2) + " " +
                               std::to_string(z0 + s / 3);
      text += "\n";
    }
    Write(name, text);
  }

  testing::TempDir dir_{"mktree_changes_cli"};
};

// 30 cubes c0..c29 on a 5 x 3 x 2 grid, each overlapping its neighbours.
std::vector<Cube> Grid() {
  std::vector<Cube> cubes;
  for (int i = 0; i < 30; ++i)
    cubes.push_back({"c" + std::to_string(i), 1.0 * (i % 5), 1.0 * (i / 5 % 3), 1.0 * (i / 15), 1.1});
  return cubes;
}

// Every answer at the newest revision equals a fresh build's of the live objects (by name), every answer
// and the clash at revision 0 equal what the tool printed before the change, after the change and after
// compaction; replaced objects keep their ids.
TEST_F(ChangesCli, UpdateAnswersAsAFreshBuildOfTheLiveObjects) {
  WriteQueries("q.txt");
  for (const char* backend : {"hdf5", "pagefile"}) {
    SCOPED_TRACE(backend);
    const std::string store = P(std::string("grid-") + backend + ".mkt");
    std::vector<Cube> live = Grid();
    Write("grid.obj", ObjOf(live));
    Ok("build " + P("grid.obj") + " -o " + store + " --backend " + backend + " --quiet");
    const std::string q = " --queries " + P("q.txt");
    const std::string before = Ok("query " + store + q), before_exact = Ok("query " + store + q + " --exact");
    const std::string clash_before = Ok("clash " + store);
    ASSERT_FALSE(PairIds(clash_before).empty());

    const std::vector<Cube> added = {
        {"n0", 0.5, 0.5, 0.5, 1}, {"n1", 5.5, 2.5, 1.5, 0.4}, {"n2", 2.2, 1.1, 0.2, 2}};
    const std::vector<Cube> replacing = {{"c3", 6, 3, 2, 0.5}, {"c20", 0.2, 0.2, -0.9, 0.7}};
    Write("add.obj", ObjOf(added));
    Write("replace.obj", ObjOf(replacing));
    Write("names.txt", "c12\n");
    const std::string out =
        Ok("update " + store + " --add " + P("add.obj") + " --remove-ids 0,7 --remove-names " +
           P("names.txt") + " --replace " + P("replace.obj") + " --message 'grid \"edit\"' --json");
    EXPECT_EQ(Field(out, "revision"), "1");
    EXPECT_EQ(Field(out, "added"), "3");
    EXPECT_EQ(Field(out, "removed"), "3");
    EXPECT_EQ(Field(out, "replaced"), "2");
    EXPECT_EQ(Field(out, "objects"), "30");
    std::erase_if(live, [](const Cube& c) { return c.name == "c0" || c.name == "c7" || c.name == "c12"; });
    for (Cube& c : live)
      for (const Cube& r : replacing)
        if (c.name == r.name) c = r;
    live.insert(live.end(), added.begin(), added.end());
    Write("fresh.obj", ObjOf(live));
    Ok("build " + P("fresh.obj") + " -o " + P("fresh.mkt") + " --backend " + backend + " --quiet");

    for (const char* when : {"after the update", "after compaction"}) {
      SCOPED_TRACE(when);
      for (const char* mode : {"", " --exact"}) {
        const auto got = SortedNames(Ok("query " + store + q + mode + " --names"));
        ASSERT_EQ(got.size(), 60u);
        EXPECT_EQ(got, SortedNames(Ok("query " + P("fresh.mkt") + q + mode + " --names")));
      }
      EXPECT_EQ(ListsOf(Ok("query " + store + q + " --revision 0"), "hits"), ListsOf(before, "hits"));
      EXPECT_EQ(ListsOf(Ok("query " + store + q + " --exact --revision 0"), "hits"),
                ListsOf(before_exact, "hits"));
      EXPECT_EQ(Ok("clash " + store + " --revision 0"), clash_before);
      EXPECT_EQ(PairNames(Ok("clash " + store + " --names")),
                PairNames(Ok("clash " + P("fresh.mkt") + " --names")));
      const std::string rec = Ok("info " + store + " --object 3 --json");
      EXPECT_EQ(Field(rec, "name"), "c3");
      EXPECT_NE(rec.find("\"box\": [[6, 3, 2]"), std::string::npos) << rec;
      const std::string info = Ok("info " + store + " --json");
      EXPECT_EQ(Field(info, "objects"), "30");
      EXPECT_EQ(Field(Ok("info " + store + " --json --revision 0"), "objects"), "30");
      EXPECT_EQ(Field(Ok("info " + store + " --json --revision 0"), "revision"), "0");
      Ok("compact " + store);
    }
    const std::vector<std::string> log = Lines(Ok("log " + store + " --json"));
    ASSERT_EQ(log.size(), 3u);  // built, the update, one compaction (the second had nothing to fold)
    EXPECT_NE(log[1].find("\"message\": \"grid \\\"edit\\\"\""), std::string::npos) << log[1];
    EXPECT_EQ(Field(log[2], "compaction"), "true");
  }
}

// clash --since R: the new pairs are those now that were not at R, the resolved ones those at R that are
// not now (by id), so that the full clash at R, less the resolved pairs, plus the new ones is the clash now.
TEST_F(ChangesCli, ClashSinceGivesTheNewAndResolvedPairs) {
  const std::string store = P("grid.mkt");
  Write("grid.obj", ObjOf(Grid()));
  Ok("build " + P("grid.obj") + " -o " + store + " --quiet");
  Write("add.obj", ObjOf({{"n0", 0.5, 0.5, 0.5, 1}, {"n1", 9, 9, 9, 1}}));
  Write("replace.obj", ObjOf({{"c3", 6, 3, 2, 0.5}, {"c20", 0.2, 0.2, -0.9, 0.7}}));
  Ok("update " + store + " --add " + P("add.obj") + " --remove-ids 0,7");
  Ok("update " + store + " --replace " + P("replace.obj"));
  const auto then = PairIds(Ok("clash " + store + " --revision 0"));
  const auto now = PairIds(Ok("clash " + store));
  std::set<std::pair<std::string, std::string>> want_new, want_resolved;
  std::set_difference(now.begin(), now.end(), then.begin(), then.end(),
                      std::inserter(want_new, want_new.end()));
  std::set_difference(then.begin(), then.end(), now.begin(), now.end(),
                      std::inserter(want_resolved, want_resolved.end()));
  ASSERT_FALSE(want_new.empty());
  ASSERT_FALSE(want_resolved.empty());
  for (const char* names : {"", " --names"}) {
    SCOPED_TRACE(names);
    const std::string since = Ok("clash " + store + " --since 0" + names);
    EXPECT_EQ(PairIds(since, "new"), want_new);
    EXPECT_EQ(PairIds(since, "resolved"), want_resolved);
    EXPECT_EQ(Lines(since).size(), want_new.size() + want_resolved.size());
  }
  // A resolved pair of a removed object still has its names, as they were.
  EXPECT_NE(Ok("clash " + store + " --since 0 --names").find("\"name_a\": \"c0\""), std::string::npos);
  EXPECT_EQ(Ok("clash " + store + " --since 2"), "");
  const std::string summary = Lines(Ok("clash " + store + " --since 1 --summary")).back();
  EXPECT_FALSE(Field(summary, "new").empty()) << summary;
  EXPECT_NE(Mktree("clash " + store + " --since 5").code, 0);
  EXPECT_NE(Mktree("clash " + store + " --revision 1 --since 2").code, 0);
}

// A tanker store: update, log, compact --keep; each bad change or revision is one error line, a non-zero
// exit, and the log unchanged.
TEST_F(ChangesCli, TankerStoreRefusesBadChangesAndKeepsItsLog) {
  const std::string store = P("s.mkt");
  Ok("build tanker:2000 -o " + store + " --backend pagefile --quiet");
  EXPECT_EQ(Lines(Ok("log " + store)).size(), 1u);
  Write("a.obj", ObjOf({{"dup", 0, 0, 0, 1}, {"dup", 2, 0, 0, 1}, {"solo", 4, 0, 0, 1}}));
  const std::string first =
      Ok("update " + store + " --add " + P("a.obj") + " --remove-ids 1 --message first");
  EXPECT_EQ(first.rfind("revision 1: 3 added, 1 removed, 0 replaced, 2002 objects", 0), 0u) << first;
  EXPECT_EQ(Field(Ok("info " + store + " --json"), "revision"), "1");

  ExpectRefused("update " + store + " --remove-ids 99999", "99999", store);
  ExpectRefused("update " + store + " --remove-ids 1", "no object 1", store);  // removed already
  ExpectRefused("update " + store + " --remove-ids 5,5", "object 5", store);
  ExpectRefused("update " + store + " --remove-ids 5,x", "'x'", store);
  Write("nosuch.obj", CubeObj("nosuch", 0, 0, 0, 1));
  ExpectRefused("update " + store + " --replace " + P("nosuch.obj"), "'nosuch'", store);
  Write("dup.obj", CubeObj("dup", 0, 0, 5, 1));
  ExpectRefused("update " + store + " --replace " + P("dup.obj"), "2 objects", store);
  std::string nan = CubeObj("bad", 0, 0, 0, 1);
  nan.replace(nan.find("v 1 0 0"), 7, "v 1 nan 0");
  Write("nan.obj", nan);
  ExpectRefused("update " + store + " --add " + P("nan.obj") + " --remove-ids 5", "nan.obj:3", store);
  Write("names.txt", "solo\n\ndup\n");
  ExpectRefused("update " + store + " --remove-names " + P("names.txt"), "names.txt:2", store);
  ExpectRefused("update " + store + " --remove-names " + P("none.txt"), "none.txt", store);
  Write("names.txt", "plate_000005\nnot_there\n");
  ExpectRefused("update " + store + " --remove-names " + P("names.txt"), "'not_there'", store);
  ExpectRefused("update " + store + " --add " + P("missing.obj"), "missing.obj", store);
  ExpectRefused("query " + store + " --point 0,0,0 --revision 7", "revision 7", store);
  ExpectRefused("clash " + store + " --revision 7", "revision 7", store);
  ExpectRefused("info " + store + " --revision 7", "revision 7", store);
  {
    auto writer = ChangeWriter::Open(store);
    ASSERT_TRUE(writer.ok()) << writer.status().ToString();
    ExpectRefused("update " + store + " --remove-ids 5", store, store);
    ExpectRefused("compact " + store, store, store);
  }
  ExpectRefused("compact " + store + " --keep 0", "--keep", store);

  Write("names.txt", "solo\nplate_000005\n");
  const std::string second = Ok("update " + store + " --remove-names " + P("names.txt") + " --json");
  EXPECT_EQ(Field(second, "removed"), "2");
  EXPECT_EQ(Field(second, "objects"), "2000");
  const std::string at1 =
      Ok("query " + store + " --box -1000,-1000,-1000,1000,1000,1000 --revision 1 --count");
  EXPECT_EQ(Field(at1, "hit_count"), "2002");
  const std::string compacted = Ok("compact " + store + " --keep 2 --json");
  EXPECT_EQ(Field(compacted, "revision"), "3");
  EXPECT_EQ(Field(compacted, "objects"), "2000");
  EXPECT_EQ(Field(compacted, "retired"), "2");  // revisions 0 and 1
  const std::vector<std::string> log = Lines(Ok("log " + store + " --json"));
  ASSERT_EQ(log.size(), 2u);
  EXPECT_EQ(Field(log[0], "revision"), "2");
  EXPECT_EQ(Field(log[0], "removed"), "2");
  EXPECT_EQ(Field(log[1], "compaction"), "true");
  for (const std::string& line : log)
    for (const char* key : {"revision", "time", "added", "removed", "replaced", "message", "objects"})
      EXPECT_NE(line.find(std::string("\"") + key + "\": "), std::string::npos) << line;
  ExpectRefused("query " + store + " --point 0,0,0 --revision 1", "revision 1", store);
  EXPECT_EQ(Field(Ok("query " + store + " --box -1000,-1000,-1000,1000,1000,1000 --count --revision 2"),
                  "hit_count"),
            "2000");
}

// A sharded store takes changes as a store file does: update, log, --revision, clash --since, compact and
// info, through the tool; the clash now is the clash at the older revision with its new and resolved pairs.
TEST_F(ChangesCli, AShardedStoreTakesChangesLikeAStoreFile) {
  const std::string store = P("sh.mkt");
  Ok("build tanker:500 -o " + store + " --shards 2 --quiet");
  std::vector<std::string> log = Lines(Ok("log " + store + " --json"));
  ASSERT_EQ(log.size(), 1u);
  EXPECT_EQ(Field(log[0], "revision"), "0");
  EXPECT_EQ(Field(log[0], "objects"), "500");
  // Two cubes across the tanker's middle, where they meet its objects.
  Write("add.obj", ObjOf({{"new_a", 120, -2, 2, 3}, {"new_b", 150, -2, 2, 3}}));
  const std::string clash0 = Ok("clash " + store);
  const std::string out =
      Ok("update " + store + " --add " + P("add.obj") + " --remove-ids 1,2,3 --message edit");
  EXPECT_NE(out.find("revision 1"), std::string::npos) << out;
  log = Lines(Ok("log " + store + " --json"));
  ASSERT_EQ(log.size(), 2u);
  EXPECT_EQ(Field(log[1], "added"), "2");
  EXPECT_EQ(Field(log[1], "removed"), "3");
  EXPECT_EQ(Field(log[1], "message"), "edit");
  const std::string box = " --box -1000,-1000,-1000,1000,1000,1000 --count";
  EXPECT_EQ(Field(Ok("query " + store + box), "hit_count"), "499");
  EXPECT_EQ(Field(Ok("query " + store + box + " --revision 0"), "hit_count"), "500");
  ExpectRefused("update " + store + " --remove-ids 2", "no object 2", store);
  // clash --since 0: the clash at 0 with the resolved pairs out and the new ones in is the clash now.
  const std::string since = Ok("clash " + store + " --since 0");
  std::set<std::pair<std::string, std::string>> want = PairIds(clash0);
  for (const auto& p : PairIds(since, "resolved")) EXPECT_EQ(want.erase(p), 1u) << p.first << " " << p.second;
  const auto added = PairIds(since, "new");
  EXPECT_FALSE(added.empty());
  want.insert(added.begin(), added.end());
  EXPECT_EQ(want, PairIds(Ok("clash " + store)));
  const std::string compact = Ok("compact " + store);
  EXPECT_NE(compact.find("revision 2"), std::string::npos) << compact;
  EXPECT_EQ(Field(Ok("query " + store + box), "hit_count"), "499");
  EXPECT_EQ(Field(Ok("query " + store + box + " --revision 1"), "hit_count"), "499");
  EXPECT_EQ(want, PairIds(Ok("clash " + store)));
  const std::string info = Ok("info " + store + " --json");
  EXPECT_EQ(Field(info, "objects"), "499");
  EXPECT_EQ(Field(info, "revision"), "2");
  EXPECT_EQ(Field(info, "shards"), "2");
  ExpectRefused("query " + store + box + " --revision 9", "revision 9", store);
}

}  // namespace
}  // namespace mktree
