// ParseClashTests, ReadClashTests and a test's canonical definition (mktree/clash_tests.h). nlohmann-json
// parses the file; the line of each value comes from a scan of the text alongside (the DOM keeps none).
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <utility>

#include "engine/coordination/clash_keys.h"
#include "engine/core/guarded.h"
#include "mktree/clash_tests.h"

namespace mktree {

namespace {

using Json = nlohmann::ordered_json;

// The line of every value of a valid JSON text, in document order (objects and arrays at their opening
// bracket): the order in which a pre-order walk of the parsed document meets them.
std::vector<uint64_t> ValueLines(const std::string& text) {
  std::vector<uint64_t> lines;
  uint64_t line = 1;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
    } else if (c == '{' || c == '[') {
      lines.push_back(line);
    } else if (c == '"') {
      const uint64_t at = line;
      for (++i; i < text.size() && text[i] != '"'; ++i)
        if (text[i] == '\\') ++i;
      size_t k = i + 1;
      while (k < text.size() && (text[k] == ' ' || text[k] == '\t' || text[k] == '\r' || text[k] == '\n'))
        ++k;
      if (k >= text.size() || text[k] != ':') lines.push_back(at);  // a string value, not a key
    } else if (c == '-' || (c >= '0' && c <= '9') || c == 't' || c == 'f' || c == 'n') {
      lines.push_back(line);
      while (i + 1 < text.size() &&
             std::string_view(",]}: \t\r\n").find(text[i + 1]) == std::string_view::npos)
        ++i;
    }
  }
  return lines;
}

// The parsed file and the line of each of its values.
class Located {
 public:
  Located(const std::string& file, const Json& root, const std::vector<uint64_t>& lines) : file_(file) {
    size_t next = 0;
    Walk(root, lines, &next);
    complete_ = next == lines.size();
  }
  bool complete() const { return complete_; }
  uint64_t line(const Json& v) const {
    auto it = lines_.find(&v);
    return it == lines_.end() ? 0 : it->second;
  }
  Status Error(const Json& at, const std::string& what) const {
    return Status::InvalidArgument(file_ + ":" + std::to_string(line(at)) + ": " + what);
  }

 private:
  void Walk(const Json& v, const std::vector<uint64_t>& lines, size_t* next) {
    lines_[&v] = *next < lines.size() ? lines[*next] : 0;
    ++*next;
    if (v.is_object() || v.is_array())
      for (const Json& c : v) Walk(c, lines, next);
  }
  std::string file_;
  std::map<const Json*, uint64_t> lines_;
  bool complete_ = false;
};

Status CheckKeys(const Located& at, const Json& object, const std::set<std::string>& allowed,
                 const std::string& what) {
  for (auto it = object.begin(); it != object.end(); ++it)
    if (!allowed.count(it.key()) && it.key() != "comment")
      return at.Error(it.value(), "unknown key \"" + it.key() + "\" in " + what);
  return Status::Ok();
}

Status ReadNumber(const Located& at, const Json& v, const std::string& what, bool positive, double* out) {
  if (!v.is_number()) return at.Error(v, what + " is not a number");
  const double d = v.get<double>();
  if (!std::isfinite(d) || d < 0 || (positive && d == 0))
    return at.Error(v, what + " must be a finite number " + (positive ? "> 0" : ">= 0"));
  *out = d;
  return Status::Ok();
}

Status ReadString(const Located& at, const Json& v, const std::string& what, std::string* out) {
  if (!v.is_string()) return at.Error(v, what + " is not a string");
  *out = v.get<std::string>();
  return Status::Ok();
}

// key -> a glob or a list of globs.
Status ReadPatterns(const Located& at, const Json& object, const std::string& what, bool allow_exclude,
                    Selection* out) {
  if (!object.is_object()) return at.Error(object, what + " is not an object of key: [patterns]");
  for (auto it = object.begin(); it != object.end(); ++it) {
    if (it.key() == "comment") continue;
    if (it.key() == "exclude") {
      if (!allow_exclude) return at.Error(it.value(), what + ": an exclude inside an exclude");
      Selection ex;
      MKTREE_RETURN_IF_ERROR(ReadPatterns(at, it.value(), what + ".exclude", false, &ex));
      out->exclude = std::move(ex.include);
      continue;
    }
    if (it.key().empty()) return at.Error(it.value(), what + ": an empty key");
    std::vector<std::string> globs;
    const Json& v = it.value();
    if (v.is_string()) {
      globs.push_back(v.get<std::string>());
    } else if (v.is_array() && !v.empty()) {
      for (const Json& g : v) {
        if (!g.is_string()) return at.Error(g, what + "." + it.key() + ": a pattern is not a string");
        globs.push_back(g.get<std::string>());
      }
    } else {
      return at.Error(v, what + "." + it.key() + " is not a pattern or a non-empty list of patterns");
    }
    out->include.emplace_back(it.key(), std::move(globs));
  }
  return Status::Ok();
}

Status ReadApproved(const Located& at, const Json& v, ClashRules* rules) {
  if (!v.is_array()) return at.Error(v, "approved is not a list of clash keys or identity pairs");
  for (const Json& e : v) {
    if (e.is_string()) {
      rules->approved_keys.push_back(e.get<std::string>());
    } else if (e.is_array() && e.size() == 2 && e[0].is_string() && e[1].is_string()) {
      rules->approved_pairs.emplace_back(e[0].get<std::string>(), e[1].get<std::string>());
    } else {
      return at.Error(e, "an approved entry is neither a clash key nor a pair of stable identities");
    }
  }
  return Status::Ok();
}

Status ReadRule(const Located& at, const Json& r, ClashRules* rules) {
  if (r.is_string()) {
    const std::string name = r.get<std::string>();
    if (name == "hosted_fillings") {
      rules->hosted_fillings = true;
    } else if (name == "same_aggregate") {
      rules->same_aggregate = true;
    } else {
      return at.Error(r, "unknown rule \"" + name +
                             "\" (hosted_fillings, same_aggregate, or an object: "
                             "same_group, same_attribute, approved)");
    }
    return Status::Ok();
  }
  if (!r.is_object() || r.size() != 1) return at.Error(r, "a rule is a name or an object with one key");
  const std::string key = r.begin().key();
  const Json& v = r.begin().value();
  if (key == "same_group") {
    MKTREE_RETURN_IF_ERROR(ReadString(at, v, "same_group", &rules->same_group_separator));
    if (rules->same_group_separator.empty()) return at.Error(v, "same_group: an empty separator");
  } else if (key == "same_attribute") {
    std::vector<std::string> keys;
    if (v.is_string()) keys.push_back(v.get<std::string>());
    if (v.is_array())
      for (const Json& k : v) {
        if (!k.is_string()) return at.Error(k, "same_attribute: a key is not a string");
        keys.push_back(k.get<std::string>());
      }
    if (keys.empty()) return at.Error(v, "same_attribute is not a key or a non-empty list of keys");
    rules->same_attribute.insert(rules->same_attribute.end(), keys.begin(), keys.end());
  } else if (key == "approved") {
    MKTREE_RETURN_IF_ERROR(ReadApproved(at, v, rules));
  } else {
    return at.Error(r, "unknown rule \"" + key + "\" (same_group, same_attribute, approved)");
  }
  return Status::Ok();
}

Status ReadMode(const Located& at, const Json& t, ClashTest* test) {
  const bool has_clearance = t.contains("clearance");
  if (!t.contains("mode")) {
    test->mode = has_clearance && test->clearance > 0 ? ClashTestMode::kClearance : ClashTestMode::kTouch;
    return Status::Ok();
  }
  const Json& m = t["mode"];
  std::string mode;
  MKTREE_RETURN_IF_ERROR(ReadString(at, m, "mode", &mode));
  if (mode == "hard") {
    test->mode = ClashTestMode::kHard;
  } else if (mode == "touch") {
    test->mode = ClashTestMode::kTouch;
  } else if (mode == "clearance") {
    test->mode = ClashTestMode::kClearance;
    if (!(test->clearance > 0)) return at.Error(m, "mode clearance needs a clearance > 0");
  } else if (mode == "duplicates") {
    test->mode = ClashTestMode::kDuplicates;
  } else {
    return at.Error(m, "unknown mode \"" + mode + "\" (hard, touch, clearance, duplicates)");
  }
  if (test->mode != ClashTestMode::kClearance && has_clearance && test->clearance > 0)
    return at.Error(t["clearance"], "a clearance > 0 goes with mode clearance, not " + mode);
  return Status::Ok();
}

Status ReadGrouping(const Located& at, const Json& g, ClashTest* test) {
  if (g.is_string()) {
    const std::string by = g.get<std::string>();
    if (by == "element") {
      test->grouping = ClashGrouping::kElement;
      return Status::Ok();
    }
    return at.Error(g, "group: \"element\" or {\"proximity\": DISTANCE}");
  }
  if (!g.is_object() || g.size() != 1 || !g.contains("proximity"))
    return at.Error(g, "group: \"element\" or {\"proximity\": DISTANCE}");
  test->grouping = ClashGrouping::kProximity;
  return ReadNumber(at, g["proximity"], "group.proximity", true, &test->group_distance);
}

Status ReadTest(const Located& at, const Json& t, const std::string& file, ClashTest* test) {
  if (!t.is_object()) return at.Error(t, "a test is not an object");
  MKTREE_RETURN_IF_ERROR(CheckKeys(at, t,
                                   {"name", "a", "b", "mode", "clearance", "touch_tolerance", "tolerance",
                                    "rules", "keep_spatial", "group"},
                                   "a test"));
  test->file = file;
  test->line = at.line(t);
  if (!t.contains("name")) return at.Error(t, "a test without a name");
  MKTREE_RETURN_IF_ERROR(ReadString(at, t["name"], "name", &test->name));
  if (test->name.empty()) return at.Error(t["name"], "a test with an empty name");
  const std::string what = "test \"" + test->name + "\": ";
  if (!t.contains("a")) return at.Error(t, what + "no selection a");
  MKTREE_RETURN_IF_ERROR(ReadPatterns(at, t["a"], "a", true, &test->a));
  if (t.contains("b")) {
    test->b.emplace();
    MKTREE_RETURN_IF_ERROR(ReadPatterns(at, t["b"], "b", true, &*test->b));
  }
  if (t.contains("clearance"))
    MKTREE_RETURN_IF_ERROR(ReadNumber(at, t["clearance"], "clearance", false, &test->clearance));
  if (t.contains("touch_tolerance"))
    MKTREE_RETURN_IF_ERROR(
        ReadNumber(at, t["touch_tolerance"], "touch_tolerance", false, &test->touch_tolerance));
  if (t.contains("tolerance"))
    MKTREE_RETURN_IF_ERROR(ReadNumber(at, t["tolerance"], "tolerance", false, &test->tolerance));
  MKTREE_RETURN_IF_ERROR(ReadMode(at, t, test));
  if (t.contains("tolerance") && test->mode != ClashTestMode::kDuplicates)
    return at.Error(t["tolerance"], what + "tolerance goes with mode duplicates");
  if (t.contains("keep_spatial")) {
    if (!t["keep_spatial"].is_boolean())
      return at.Error(t["keep_spatial"], "keep_spatial is not true or false");
    test->rules.keep_spatial = t["keep_spatial"].get<bool>();
  }
  if (t.contains("rules")) {
    const Json& rules = t["rules"];
    if (!rules.is_array()) return at.Error(rules, what + "rules is not a list");
    test->rules.hosted_fillings = test->rules.same_aggregate = false;  // the list says which
    for (const Json& r : rules) MKTREE_RETURN_IF_ERROR(ReadRule(at, r, &test->rules));
  }
  if (t.contains("group")) MKTREE_RETURN_IF_ERROR(ReadGrouping(at, t["group"], test));
  return Status::Ok();
}

Json PatternsJson(const Selection::Patterns& p) {
  Json j = Json::array();
  for (const auto& [key, globs] : p) j.push_back(Json::array({key, globs}));
  return j;
}

Json SelectionJson(const Selection& s) {
  return Json{{"include", PatternsJson(s.include)}, {"exclude", PatternsJson(s.exclude)}};
}

const char* ModeName(ClashTestMode m) {
  switch (m) {
    case ClashTestMode::kHard:
      return "hard";
    case ClashTestMode::kTouch:
      return "touch";
    case ClashTestMode::kClearance:
      return "clearance";
    case ClashTestMode::kDuplicates:
      return "duplicates";
  }
  return "touch";
}

}  // namespace

const char* ClashTestModeName(ClashTestMode m) { return ModeName(m); }

namespace {

Result<ClashTestFile> Parse(const std::string& text, const std::string& file) {
  Json root;
  try {
    root = Json::parse(text);
  } catch (const Json::parse_error& e) {
    // e.byte: the byte (from 1) where parsing failed.
    const size_t upto = std::min<size_t>(e.byte > 0 ? e.byte - 1 : 0, text.size());
    const uint64_t line = 1 + static_cast<uint64_t>(std::count(text.begin(), text.begin() + upto, '\n'));
    std::string what = e.what();
    const size_t colon = what.find("syntax error");
    if (colon != std::string::npos) what = what.substr(colon);
    return Status::InvalidArgument(file + ":" + std::to_string(line) + ": not JSON: " + what);
  }
  const Located at(file, root, ValueLines(text));
  if (!at.complete()) return Status::InvalidArgument(file + ": a key repeats within an object");
  if (!root.is_object()) return at.Error(root, "the file is not a JSON object {\"tests\": [...]}");
  MKTREE_RETURN_IF_ERROR(CheckKeys(at, root, {"tests"}, "the file"));
  if (!root.contains("tests") || !root["tests"].is_array() || root["tests"].empty())
    return at.Error(root.contains("tests") ? root["tests"] : root,
                    "\"tests\" is not a non-empty list of tests");
  ClashTestFile out;
  std::set<std::string> names;
  for (const Json& t : root["tests"]) {
    ClashTest test;
    MKTREE_RETURN_IF_ERROR(ReadTest(at, t, file, &test));
    if (!names.insert(test.name).second) return at.Error(t, "a second test named \"" + test.name + "\"");
    out.tests.push_back(std::move(test));
  }
  return out;
}

}  // namespace

Result<ClashTestFile> ParseClashTests(const std::string& text, const std::string& file) {
  return Guarded(file, [&] { return Parse(text, file); });
}

Result<ClashTestFile> ReadClashTests(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::NotFound(path + ": cannot open the clash-test file");
  std::stringstream text;
  text << in.rdbuf();
  if (in.bad()) return Status::IOError(path + ": cannot read the clash-test file");
  return ParseClashTests(text.str(), path);
}

std::string ClashTestDefinition(const ClashTest& t) {
  Json rules{{"keep_spatial", t.rules.keep_spatial},     {"hosted_fillings", t.rules.hosted_fillings},
             {"same_aggregate", t.rules.same_aggregate}, {"same_group", t.rules.same_group_separator},
             {"same_attribute", t.rules.same_attribute}, {"approved_keys", t.rules.approved_keys},
             {"approved_pairs", t.rules.approved_pairs}};
  Json j{{"name", t.name},
         {"a", SelectionJson(t.a)},
         {"b", t.b ? SelectionJson(*t.b) : Json(nullptr)},
         {"mode", ModeName(t.mode)},
         {"clearance", t.clearance},
         {"touch_tolerance", t.touch_tolerance},
         {"tolerance", t.tolerance},
         {"rules", rules},
         {"group",
          t.grouping == ClashGrouping::kElement ? Json("element") : Json{{"proximity", t.group_distance}}}};
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

std::string ClashTestFingerprint(const ClashTest& t) {
  return coordination::Hex64(coordination::StableHash(ClashTestDefinition(t)));
}

}  // namespace mktree
