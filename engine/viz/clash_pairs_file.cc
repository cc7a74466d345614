#include "engine/viz/clash_pairs_file.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string_view>
#include <utility>

namespace mktree {

const char* ClashMarkName(ClashMark c) {
  switch (c) {
    case ClashMark::kNone:
      return "none";
    case ClashMark::kClearance:
      return "clearance";
    case ClashMark::kTouch:
      return "touch";
    case ClashMark::kHard:
      return "hard";
  }
  return "?";
}

namespace {

// A pair line is a few hundred bytes; a longer line is not one, and must not make the reader allocate.
constexpr size_t kMaxLine = size_t{1} << 20;
constexpr int kMaxDepth = 64;

// One JSON object on one line: the three keys a pair needs, the rest checked for syntax and skipped.
class LineParser {
 public:
  explicit LineParser(std::string_view s) : s_(s) {}

  struct Fields {
    std::string_view a, b, cls;  // values as written (the class without its quotes if a string)
    bool has_a = false, has_b = false, has_cls = false;
    bool cls_is_string = false;
  };

  // Parses the whole line; on error returns the reason.
  std::string Parse(Fields* out) {
    Ws();
    if (!Eat('{')) return "not a JSON object";
    Ws();
    if (!Eat('}')) {
      for (;;) {
        Ws();
        std::string_view key;
        if (!String(&key)) return Error("a key in quotes");
        Ws();
        if (!Eat(':')) return Error("':'");
        Ws();
        const size_t start = i_;
        const bool is_string = Peek() == '"';
        if (!Value(1)) return Error("a JSON value");
        const std::string_view text = s_.substr(start, i_ - start);
        std::string_view* slot = nullptr;
        bool* seen = nullptr;
        if (key == "a") slot = &out->a, seen = &out->has_a;
        if (key == "b") slot = &out->b, seen = &out->has_b;
        if (key == "class") {
          slot = &out->cls, seen = &out->has_cls;
          out->cls_is_string = is_string;
        }
        if (seen) {
          if (*seen) return "key \"" + std::string(key) + "\" given twice";
          *seen = true;
          *slot = is_string && slot == &out->cls ? text.substr(1, text.size() - 2) : text;
        }
        Ws();
        if (Eat('}')) break;
        if (!Eat(',')) return Error("',' or '}'");
      }
    }
    Ws();
    if (i_ != s_.size()) return "text after the JSON object at column " + std::to_string(i_ + 1);
    return "";
  }

 private:
  char Peek() const { return i_ < s_.size() ? s_[i_] : '\0'; }
  bool Eat(char c) {
    if (Peek() != c || i_ >= s_.size()) return false;
    ++i_;
    return true;
  }
  void Ws() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\r')) ++i_;
  }
  std::string Error(const char* expected) const {
    return std::string("expected ") + expected + " at column " + std::to_string(i_ + 1);
  }
  static bool IsDigit(char c) { return c >= '0' && c <= '9'; }
  static bool IsHex(char c) { return IsDigit(c) || (c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F'); }

  // A string; *raw is its text between the quotes (escapes not decoded).
  bool String(std::string_view* raw) {
    if (!Eat('"')) return false;
    const size_t start = i_;
    while (i_ < s_.size()) {
      const unsigned char c = static_cast<unsigned char>(s_[i_]);
      if (c == '"') {
        *raw = s_.substr(start, i_ - start);
        ++i_;
        return true;
      }
      if (c < 0x20) return false;
      if (c == '\\') {
        ++i_;
        const char e = Peek();
        if (e == 'u') {
          for (int k = 1; k <= 4; ++k)
            if (i_ + k >= s_.size() || !IsHex(s_[i_ + k])) return false;
          i_ += 4;
        } else if (!std::strchr("\"\\/bfnrt", e) || e == '\0') {
          return false;
        }
      }
      ++i_;
    }
    return false;
  }
  bool Number() {
    Eat('-');
    if (Eat('0')) {
    } else if (IsDigit(Peek())) {
      while (IsDigit(Peek())) ++i_;
    } else {
      return false;
    }
    if (Eat('.')) {
      if (!IsDigit(Peek())) return false;
      while (IsDigit(Peek())) ++i_;
    }
    if (Peek() == 'e' || Peek() == 'E') {
      ++i_;
      if (Peek() == '+' || Peek() == '-') ++i_;
      if (!IsDigit(Peek())) return false;
      while (IsDigit(Peek())) ++i_;
    }
    return true;
  }
  bool Word(std::string_view w) {
    if (s_.substr(i_, w.size()) != w) return false;
    i_ += w.size();
    return true;
  }
  bool Value(int depth) {
    if (depth > kMaxDepth) return false;
    std::string_view ignored;
    switch (Peek()) {
      case '"':
        return String(&ignored);
      case 't':
        return Word("true");
      case 'f':
        return Word("false");
      case 'n':
        return Word("null");
      case '[':
        ++i_;
        Ws();
        if (Eat(']')) return true;
        for (;;) {
          Ws();
          if (!Value(depth + 1)) return false;
          Ws();
          if (Eat(']')) return true;
          if (!Eat(',')) return false;
        }
      case '{':
        ++i_;
        Ws();
        if (Eat('}')) return true;
        for (;;) {
          Ws();
          if (!String(&ignored)) return false;
          Ws();
          if (!Eat(':')) return false;
          Ws();
          if (!Value(depth + 1)) return false;
          Ws();
          if (Eat('}')) return true;
          if (!Eat(',')) return false;
        }
      default:
        return Number();
    }
  }

  std::string_view s_;
  size_t i_ = 0;
};

// An object id as written: digits only (JSON's integer form, no sign, fraction or exponent).
bool ParseId(std::string_view text, uint64_t* id) {
  if (text.empty() || text.size() > 20) return false;
  uint64_t v = 0;
  for (char c : text) {
    if (c < '0' || c > '9') return false;
    const uint64_t d = static_cast<uint64_t>(c - '0');
    if (v > (UINT64_MAX - d) / 10) return false;
    v = v * 10 + d;
  }
  *id = v;
  return true;
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

}  // namespace

Result<ClashMarks> ReadClashPairs(const std::string& path, uint64_t object_count, uint64_t focus) {
  std::unique_ptr<std::FILE, FileCloser> file(std::fopen(path.c_str(), "rb"));
  if (!file) return Status::IOError(path + ": cannot open the pairs file: " + std::strerror(errno));
  ClashMarks marks;
  marks.worst.assign(object_count, static_cast<uint8_t>(ClashMark::kNone));
  uint64_t pair_lines = 0;

  auto line_error = [&](uint64_t line_no, const std::string& why) {
    return Status::InvalidArgument(path + ":" + std::to_string(line_no) + ": " + why);
  };
  auto take_line = [&](std::string_view line, uint64_t line_no) -> Status {
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) return Status::Ok();
    LineParser::Fields f;
    if (std::string why = LineParser(line).Parse(&f); !why.empty())
      return line_error(line_no, "not a pair line of mktree clash: " + why);
    if (!f.has_a && !f.has_b && !f.has_cls) {
      ++marks.other_lines;
      return Status::Ok();
    }
    for (const auto& [has, key] : {std::pair{f.has_a, "a"}, {f.has_b, "b"}, {f.has_cls, "class"}})
      if (!has) return line_error(line_no, std::string("a pair line without \"") + key + "\"");
    uint64_t id[2];
    const std::string_view text[2] = {f.a, f.b};
    for (int k = 0; k < 2; ++k) {
      const char* name = k == 0 ? "a" : "b";
      if (!ParseId(text[k], &id[k]))
        return line_error(line_no, std::string(name) + " = " + std::string(text[k]) +
                                       " is not an object id (a non-negative integer)");
      if (id[k] >= object_count)
        return line_error(line_no, std::string(name) + " = " + std::string(text[k]) +
                                       " is not an object of the store, which has " +
                                       std::to_string(object_count) + " objects");
    }
    if (id[0] >= id[1])
      return line_error(line_no, "a = " + std::to_string(id[0]) + " and b = " + std::to_string(id[1]) +
                                     ": a pair has a < b");
    ClashMark cls = ClashMark::kNone;
    if (f.cls_is_string) {
      if (f.cls == "hard") cls = ClashMark::kHard;
      if (f.cls == "touch") cls = ClashMark::kTouch;
      if (f.cls == "clearance") cls = ClashMark::kClearance;
    }
    if (cls == ClashMark::kNone)
      return line_error(line_no,
                        "class " + std::string(f.cls) + " is not \"hard\", \"touch\" or \"clearance\"");
    ++marks.pairs[static_cast<int>(cls)];
    for (uint64_t i : id) marks.worst[i] = std::max(marks.worst[i], static_cast<uint8_t>(cls));
    if (++pair_lines == focus) marks.focus = MarkedPair{id[0], id[1], cls, line_no};
    return Status::Ok();
  };

  // Lines split out of 64 KiB blocks, so a line is never longer in RAM than kMaxLine.
  std::string line;
  std::vector<char> block(64 << 10);
  uint64_t line_no = 1;
  for (;;) {
    const size_t n = std::fread(block.data(), 1, block.size(), file.get());
    if (n == 0) {
      if (std::ferror(file.get())) return Status::IOError(path + ": reading the pairs file failed");
      break;
    }
    size_t start = 0;
    for (size_t i = 0; i < n; ++i) {
      if (block[i] != '\n') continue;
      line.append(block.data() + start, i - start);
      if (line.size() > kMaxLine)
        return line_error(line_no, "longer than " + std::to_string(kMaxLine) + " bytes: not a pair line");
      MKTREE_RETURN_IF_ERROR(take_line(line, line_no));
      line.clear();
      ++line_no;
      start = i + 1;
    }
    line.append(block.data() + start, n - start);
    if (line.size() > kMaxLine)
      return line_error(line_no, "longer than " + std::to_string(kMaxLine) + " bytes: not a pair line");
  }
  MKTREE_RETURN_IF_ERROR(take_line(line, line_no));  // a last line without its newline

  for (uint8_t w : marks.worst) ++marks.objects[w];
  if (focus > 0 && !marks.focus)
    return Status::InvalidArgument(path + ": has " + std::to_string(pair_lines) +
                                   " pairs; there is no pair " + std::to_string(focus) + " to focus on");
  return marks;
}

}  // namespace mktree
