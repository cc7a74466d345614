#include "engine/coordination/clash_compare.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string_view>
#include <unordered_map>
#include <unordered_set>

#include "engine/core/guarded.h"

namespace mktree {

namespace {

using Json = nlohmann::json;

std::string Str(const Json& j, const char* key) {
  auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}
uint64_t U64(const Json& j, const char* key) {
  auto it = j.find(key);
  return it != j.end() && it->is_number_unsigned() ? it->get<uint64_t>() : 0;
}
double Real(const Json& j, const char* key) {
  auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : 0;
}
Vec3d Point(const Json& j, const char* key) {
  Vec3d p;
  auto it = j.find(key);
  if (it != j.end() && it->is_array() && it->size() == 3)
    for (int i = 0; i < 3; ++i) p[i] = (*it)[i].is_number() ? (*it)[i].get<double>() : 0;
  return p;
}

ClashClass ClassOf(const std::string& name) {
  return name == "touch"       ? ClashClass::kTouch
         : name == "clearance" ? ClashClass::kClearance
                               : ClashClass::kHard;
}

// The source file name and GlobalId a stable identity holds ("duplex.ifc|2O2Fr$t4X7Zf8NOew3FNau"; none
// after "|name=").
void FromStable(ObjectIdentity* o) {
  const size_t bar = o->stable.find('|');
  if (bar == std::string::npos) return;
  o->source = o->stable.substr(0, bar);
  if (o->stable.compare(bar + 1, 5, "name=") != 0) o->global_id = o->stable.substr(bar + 1);
}

// The identities of a previous run's lines, each distinct (id, stable identity, name) once.
class PreviousIdentities {
 public:
  std::shared_ptr<const ObjectIdentity> Get(ObjectId id, std::string stable, std::string name) {
    std::string k = std::to_string(id) + '\n' + stable + '\n' + name;
    auto it = known_.find(k);
    if (it != known_.end()) return it->second;
    auto o = std::make_shared<ObjectIdentity>();
    o->id = id;
    o->stable = std::move(stable);
    o->name = std::move(name);
    FromStable(o.get());
    known_.emplace(std::move(k), o);
    return o;
  }

 private:
  std::unordered_map<std::string, std::shared_ptr<const ObjectIdentity>> known_;
};

// Distinct strings, each once, by index.
struct Interned {
  std::vector<std::string> names;
  std::unordered_map<std::string, uint32_t> index;
  uint32_t Index(std::string s) {
    auto [it, added] = index.try_emplace(std::move(s), static_cast<uint32_t>(names.size()));
    if (added) names.push_back(it->first);
    return it->second;
  }
};

// One pair line of a previous run as a record (its status as written).
ClashRecord RecordOf(const Json& j, PreviousIdentities* identities) {
  ClashRecord r;
  r.key = Str(j, "key");
  r.pair.a = static_cast<ObjectId>(U64(j, "a"));
  r.pair.b = static_cast<ObjectId>(U64(j, "b"));
  r.a = identities->Get(r.pair.a, Str(j, "id_a"), Str(j, "name_a"));
  r.b = identities->Get(r.pair.b, Str(j, "id_b"), Str(j, "name_b"));
  r.pair.cls = ClassOf(Str(j, "class"));
  r.pair.distance = Real(j, "distance");
  r.pair.depth_lower = Real(j, "depth_lower");
  r.pair.depth_upper = Real(j, "depth_upper");
  r.pair.point_a = Point(j, "point_a");
  r.pair.point_b = Point(j, "point_b");
  const std::string status = Str(j, "status");
  r.status = status == "new"        ? ClashStatus::kNew
             : status == "active"   ? ClashStatus::kActive
             : status == "resolved" ? ClashStatus::kResolved
                                    : ClashStatus::kNone;
  return r;
}

Status ReadSummaryLine(const Json& j, const std::string& where, PreviousClashRun::Test* t) {
  t->name = Str(j, "test");
  t->fingerprint = Str(j, "fingerprint");
  if (t->name.empty() || t->fingerprint.empty())
    return Status::InvalidArgument(where + ": a summary line without test and fingerprint");
  t->selected_a = U64(j, "selected_a");
  t->selected_b = U64(j, "selected_b");
  auto s = j.find("sources");
  if (s == j.end() || !s->is_array())
    return Status::InvalidArgument(where + ": a summary line without sources");
  for (const Json& x : *s) {
    if (!x.is_string()) return Status::InvalidArgument(where + ": a source that is not a string");
    t->sources.push_back(x.get<std::string>());
  }
  return Status::Ok();
}

Result<PreviousClashRun> ReadLines(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::NotFound(path + ": cannot open the previous run");
  PreviousClashRun run;
  run.file = path;
  std::map<std::string, size_t> test_at;
  // The pair lines are placed once the summaries are read (a test's summary follows its pairs): each
  // line's test and group as indices into the distinct names seen, the records not resolved.
  Interned tests, groups;
  std::vector<std::pair<uint32_t, uint64_t>> test_of_line;  // (test, line number), every pair line
  struct Pending {
    ClashRecord record;
    uint32_t test, group;
  };
  std::vector<Pending> pending;
  PreviousIdentities identities;
  std::string line;
  uint64_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty()) continue;
    const std::string where = path + ":" + std::to_string(n);
    Json j = Json::parse(line, nullptr, false);
    if (j.is_discarded() || !j.is_object()) return Status::InvalidArgument(where + ": not a JSON object");
    const auto summary = j.find("summary");
    if (summary != j.end() && !summary->is_boolean())
      return Status::InvalidArgument(where + ": \"summary\" is not true or false");
    if (summary != j.end() && summary->get<bool>()) {
      PreviousClashRun::Test t;
      MKTREE_RETURN_IF_ERROR(ReadSummaryLine(j, where, &t));
      if (test_at.count(t.name))
        return Status::InvalidArgument(where + ": a second summary of test \"" + t.name + "\"");
      test_at[t.name] = run.tests.size();
      run.tests.push_back(std::move(t));
      continue;
    }
    if (Str(j, "test").empty() || Str(j, "key").empty())
      return Status::InvalidArgument(
          where + ": a line without \"test\" and \"key\" (not written by mktree clash --tests)");
    const uint32_t test = tests.Index(Str(j, "test"));
    test_of_line.emplace_back(test, n);
    ClashRecord r = RecordOf(j, &identities);
    if (r.status != ClashStatus::kResolved)
      pending.push_back({std::move(r), test, groups.Index(Str(j, "group"))});
  }
  if (in.bad()) return Status::IOError(path + ": cannot read the previous run");
  if (run.tests.empty())
    return Status::InvalidArgument(path + ": no test summary line (not the output of mktree clash --tests)");
  std::vector<size_t> test_index(tests.names.size());
  for (const auto& [test, at] : test_of_line) {
    auto t = test_at.find(tests.names[test]);
    if (t == test_at.end())
      return Status::InvalidArgument(path + ":" + std::to_string(at) + ": a clash of test \"" +
                                     tests.names[test] + "\", which has no summary line");
    test_index[test] = t->second;
  }
  std::vector<std::unordered_map<uint32_t, uint32_t>> group_at(run.tests.size());
  for (Pending& p : pending) {
    PreviousClashRun::Test& test = run.tests[test_index[p.test]];
    auto [g, added] = group_at[test_index[p.test]].try_emplace(p.group, test.group_keys.size());
    if (added) test.group_keys.push_back(groups.names[p.group]);
    test.group_of.push_back(g->second);
    test.records.push_back(std::move(p.record));
  }
  return run;
}

}  // namespace

Result<PreviousClashRun> ReadPreviousClashRun(const std::string& path) {
  return Guarded(path, [&] { return ReadLines(path); });
}

namespace coordination {

Status CheckComparable(const PreviousClashRun& before, const std::vector<ClashTestSummary>& now) {
  const std::string why = before.file + ": not comparable with this run: ";
  std::map<std::string, const PreviousClashRun::Test*> old;
  for (const auto& t : before.tests) old[t.name] = &t;
  for (const ClashTestSummary& s : now)
    if (!old.count(s.name)) return Status::InvalidArgument(why + "test \"" + s.name + "\" is new");
  for (const auto& [name, t] : old) {
    auto it = std::find_if(now.begin(), now.end(), [&](const ClashTestSummary& s) { return s.name == name; });
    if (it == now.end())
      return Status::InvalidArgument(why + "test \"" + name + "\" is not in the test file now");
    if (it->fingerprint != t->fingerprint)
      return Status::InvalidArgument(why + "test \"" + name + "\" is defined otherwise (fingerprint " +
                                     t->fingerprint + ", now " + it->fingerprint + ")");
    if (it->selected_a == 0 && t->selected_a > 0)
      return Status::InvalidArgument(why + "selection a of test \"" + name + "\" picks no object now (" +
                                     std::to_string(t->selected_a) + " before)");
    if (it->selected_b == 0 && t->selected_b > 0)
      return Status::InvalidArgument(why + "selection b of test \"" + name + "\" picks no object now (" +
                                     std::to_string(t->selected_b) + " before)");
    for (const std::string& src : t->sources)
      if (!std::binary_search(it->sources.begin(), it->sources.end(), src))
        return Status::InvalidArgument(why + "test \"" + name + "\": source model \"" + src +
                                       "\" is missing now");
  }
  return Status::Ok();
}

std::vector<ResolvedClash> LabelAgainst(const PreviousClashRun::Test& before, std::vector<ClashRecord>* now) {
  // Views of keys that `before` and `*now` hold and outlive the sets.
  std::unordered_set<std::string_view> had, has;
  had.reserve(before.records.size());
  has.reserve(now->size());
  for (const ClashRecord& r : before.records) had.insert(r.key);
  for (ClashRecord& r : *now) {
    r.status = had.count(r.key) ? ClashStatus::kActive : ClashStatus::kNew;
    has.insert(r.key);
  }
  std::vector<ResolvedClash> resolved;
  for (size_t i = 0; i < before.records.size(); ++i) {
    const ClashRecord& r = before.records[i];
    if (!has.insert(r.key).second) continue;  // found now, or resolved already (a repeated line)
    resolved.push_back({r, before.group_keys[before.group_of[i]]});
    resolved.back().record.status = ClashStatus::kResolved;
  }
  return resolved;
}

}  // namespace coordination

}  // namespace mktree
