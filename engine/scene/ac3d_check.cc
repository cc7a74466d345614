// CheckAc3dFile (assimp_input_checks.h): the AC3D grammar as assimp 5.2's importer reads it, line by
// line, with the object tree kept as a stack of children still expected per open object (no recursion).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <vector>

#include "engine/scene/assimp_input_checks.h"
#include "engine/scene/text_lines.h"

namespace mktree {

namespace {

// Keywords assimp acts on inside an object; a data block's line starting with one would be taken for it.
bool IsObjectKeyword(std::string_view t) {
  static constexpr std::string_view kWords[] = {"kids", "name",   "texture", "texrep",  "texoff", "rot",
                                                "loc",  "subdiv", "crease",  "numvert", "numsurf"};
  return std::find(std::begin(kWords), std::end(kWords), t) != std::end(kWords);
}

bool EqualsNoCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

// SURF flags as assimp's strtoul_cppstyle reads them: 0x hex, a leading 0 octal, else decimal.
bool ParseSurfFlags(std::string_view t, uint32_t* flags) {
  int base = 10;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X')) {
    base = 16;
    t.remove_prefix(2);
  } else if (t.size() > 1 && t[0] == '0') {
    base = 8;
  }
  if (t.empty()) return false;
  uint64_t v = 0;
  for (char c : t) {
    int d = c >= '0' && c <= '9'   ? c - '0'
            : c >= 'a' && c <= 'f' ? c - 'a' + 10
            : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                   : 99;
    if (d >= base) return false;
    v = v * base + d;
    if (v > UINT32_MAX) return false;
  }
  *flags = static_cast<uint32_t>(v);
  return true;
}

// True if the first `n` tokens after the keyword are finite decimal numbers and there are no more.
bool FiniteNumbers(const std::vector<std::string_view>& tokens, size_t first, size_t n) {
  if (tokens.size() != first + n) return false;
  for (size_t i = first; i < tokens.size(); ++i) {
    double v = 0;
    if (!ParseDecimal(tokens[i], &v) || !std::isfinite(v)) return false;
  }
  return true;
}

struct Object {
  uint64_t vertices = 0;
  int64_t max_ref = -1;  // largest vertex reference of its surfaces
  uint64_t max_ref_line = 0;
  uint32_t vertices_left = 0, surfaces_left = 0, refs_left = 0;
  uint64_t data_left = 0;  // bytes of a "data" block still to skip
  bool in_surface = false;
  uint32_t surface_type = 0;
  uint64_t surface_refs = 0, surface_line = 0;
};

class Ac3dCheck {
 public:
  explicit Ac3dCheck(TextLines* lines) : in_(*lines) {}

  Status Run() {
    std::string_view line;
    if (!in_.Next(&line))
      return in_.status().ok() ? Status::Corruption(in_.path() + ": empty file") : in_.status();
    if (line.substr(0, 3) == "\xEF\xBB\xBF") line.remove_prefix(3);  // a UTF-8 byte order mark
    if (line.substr(0, 4) != "AC3D") return Fail("not an AC3D file (no AC3D header)");
    while (in_.Next(&line)) MKTREE_RETURN_IF_ERROR(Line(line));
    MKTREE_RETURN_IF_ERROR(in_.status());
    if (!root_seen_) return Status::Corruption(in_.path() + ": no OBJECT in the file");
    if (!done_) {
      return Status::Corruption(in_.path() + ":" + std::to_string(in_.line_no()) +
                                ": unexpected end of file: an object or its kids are missing");
    }
    return Status::Ok();
  }

 private:
  Status Fail(const std::string& what) const { return Status::Corruption(in_.Where() + what); }
  // "KEYWORD COUNT" with COUNT in decimal digits (assimp reads "-3" as 0 and "3x" as 3).
  Status CountError(const std::vector<std::string_view>& t) const {
    return Fail(std::string(t[0]) + ": expected one count in decimal digits, got " +
                (t.size() == 2 ? QuotedToken(t[1]) : std::to_string(t.size() - 1) + " values"));
  }

  Status Line(std::string_view line) {
    SplitTokens(line, &tokens_);
    const std::vector<std::string_view>& t = tokens_;
    if (t.empty()) {
      // assimp skips empty lines, but a line of only spaces or tabs ends its object (or the file) there.
      if (line.empty() || done_) return Status::Ok();
      return Fail("a line of only spaces or tabs (assimp ends the object there)");
    }
    if (done_) {
      return Fail(t[0] == "OBJECT" ? "a second top-level object (assimp would drop it)"
                                   : "text after the end of the top-level object (assimp would misread it)");
    }
    if (!in_object_) return Between(t);
    Object& o = object_;
    if (o.vertices_left > 0) return Vertex(t);
    if (o.refs_left > 0) return Reference(t);
    if (o.data_left > 0) {
      if (IsObjectKeyword(t[0])) return Fail("a data block's line starts with " + QuotedToken(t[0]));
      o.data_left -= std::min<uint64_t>(o.data_left, line.size() + 1);
      return Status::Ok();
    }
    if (o.in_surface) {
      if (t[0] == "mat") {
        uint32_t m = 0;
        return t.size() == 2 && ParseCount(t[1], &m) ? Status::Ok() : CountError(t);
      }
      if (t[0] == "refs") {
        if (t.size() != 2 || !ParseCount(t[1], &o.refs_left)) return CountError(t);
        return Status::Ok();
      }
      MKTREE_RETURN_IF_ERROR(EndSurface());
    }
    if (o.surfaces_left > 0) {
      uint32_t flags = 0;
      if (t[0] != "SURF" || t.size() != 2 || !ParseSurfFlags(t[1], &flags))
        return Fail("expected 'SURF FLAGS' (numsurf announced " + std::to_string(o.surfaces_left) + " more)");
      o.surface_type = flags & 0xF;
      if (o.surface_type != 0 && o.surface_type != 1 && o.surface_type != 2 && o.surface_type != 4)
        return Fail("unknown surface type " + std::to_string(o.surface_type) + " (SURF " + QuotedToken(t[1]) +
                    ")");
      --o.surfaces_left;
      o.in_surface = true;
      o.surface_refs = 0;
      o.surface_line = in_.line_no();
      return Status::Ok();
    }
    return ObjectLine(line, t);
  }

  // Outside any object: MATERIAL lines before the top-level object, then OBJECT lines where kids are due.
  Status Between(const std::vector<std::string_view>& t) {
    if (t[0] == "OBJECT") return BeginObject(t);
    if (!root_seen_ && t[0] == "MATERIAL") return Status::Ok();
    if (!root_seen_) return Fail("expected MATERIAL or OBJECT, got " + QuotedToken(t[0]));
    return Fail("expected OBJECT: the enclosing object's kids announce " + std::to_string(kids_left_.back()) +
                " more");
  }

  Status BeginObject(const std::vector<std::string_view>& t) {
    if (t.size() != 2) return Fail("expected 'OBJECT TYPE'");
    if (!EqualsNoCase(t[1], "world") && !EqualsNoCase(t[1], "poly") && !EqualsNoCase(t[1], "group") &&
        !EqualsNoCase(t[1], "light"))
      return Fail("unknown object type " + QuotedToken(t[1]));
    if (kids_left_.empty()) {
      root_seen_ = true;  // (after it, Line refuses everything)
    } else {
      --kids_left_.back();
    }
    if (kids_left_.size() >= kMaxNodeDepth)
      return Fail("objects nested deeper than " + std::to_string(kMaxNodeDepth) + " levels");
    in_object_ = true;
    object_ = Object{};
    return Status::Ok();
  }

  Status Vertex(const std::vector<std::string_view>& t) {
    // assimp stops a vertex list at a line whose first character is not a digit or sign.
    const char first = t[0][0];
    if (!(first >= '0' && first <= '9') && first != '-' && first != '+')
      return Fail("expected a vertex 'X Y Z' (numvert announced " + std::to_string(object_.vertices_left) +
                  " more)");
    if (t.size() < 3) return Fail("a vertex needs 3 numbers, got " + std::to_string(t.size()));
    for (size_t i = 0; i < 3; ++i) {
      double v = 0;
      if (!ParseDecimal(t[i], &v)) return Fail(QuotedToken(t[i]) + " is not a number");
      if (!std::isfinite(v)) return Fail("non-finite coordinate " + QuotedToken(t[i]));
    }
    --object_.vertices_left;
    ++object_.vertices;
    return Status::Ok();
  }

  Status Reference(const std::vector<std::string_view>& t) {
    uint32_t index = 0;
    double u = 0, v = 0;
    if (t.size() != 3 || !ParseCount(t[0], &index) || !ParseDecimal(t[1], &u) || !ParseDecimal(t[2], &v))
      return Fail("expected a reference 'VERTEX U V' (refs announced " + std::to_string(object_.refs_left) +
                  " more)");
    if (index > object_.max_ref) {
      object_.max_ref = index;
      object_.max_ref_line = in_.line_no();
    }
    --object_.refs_left;
    ++object_.surface_refs;
    return Status::Ok();
  }

  Status EndSurface() {
    Object& o = object_;
    o.in_surface = false;
    const uint64_t need = o.surface_type == 4 ? 3 : o.surface_type == 0 ? 1 : 2;
    if (o.surface_refs < need) {
      const char* kind = o.surface_type == 4 ? "triangle strip" : o.surface_type == 0 ? "polygon" : "line";
      return Status::Corruption(in_.path() + ":" + std::to_string(o.surface_line) + ": a " + kind +
                                " surface with " + std::to_string(o.surface_refs) +
                                " vertex references (at least " + std::to_string(need) + ")");
    }
    return Status::Ok();
  }

  Status ObjectLine(std::string_view line, const std::vector<std::string_view>& t) {
    Object& o = object_;
    const std::string_view k = t[0];
    auto count = [&](uint32_t* out) { return t.size() == 2 && ParseCount(t[1], out); };
    if (k == "kids") {
      uint32_t kids = 0;
      if (!count(&kids)) return CountError(t);
      if (o.max_ref >= 0 && static_cast<uint64_t>(o.max_ref) >= o.vertices)
        return Status::Corruption(in_.path() + ":" + std::to_string(o.max_ref_line) + ": vertex reference " +
                                  std::to_string(o.max_ref) + " out of range (the object has " +
                                  std::to_string(o.vertices) + " vertices)");
      in_object_ = false;
      if (kids > 0) {
        kids_left_.push_back(kids);
      } else {
        while (!kids_left_.empty() && kids_left_.back() == 0) kids_left_.pop_back();
        done_ = kids_left_.empty();
      }
      return Status::Ok();
    }
    if (k == "numvert") return count(&o.vertices_left) ? Status::Ok() : CountError(t);
    if (k == "numsurf") return count(&o.surfaces_left) ? Status::Ok() : CountError(t);
    if (k == "data") {
      uint32_t bytes = 0;
      if (!count(&bytes)) return CountError(t);
      o.data_left = bytes;
      return Status::Ok();
    }
    if (k == "name") {
      const size_t open = line.find('"');
      if (open == std::string_view::npos || line.find('"', open + 1) == std::string_view::npos)
        return Fail("a name must be in double quotes on one line");
      return Status::Ok();
    }
    if (k == "loc")
      return FiniteNumbers(t, 1, 3) ? Status::Ok() : Fail("expected 'loc X Y Z' (finite numbers)");
    if (k == "rot")
      return FiniteNumbers(t, 1, 9) ? Status::Ok() : Fail("expected 'rot' and 9 finite numbers");
    if (k == "subdiv") {
      uint32_t levels = 0;
      if (!count(&levels)) return CountError(t);
      if (levels > kMaxAc3dSubdivision)
        return Fail("subdiv " + std::to_string(levels) + ": at most " + std::to_string(kMaxAc3dSubdivision) +
                    " levels (each multiplies the faces by 4)");
      return Status::Ok();
    }
    if (k == "OBJECT") return Fail("OBJECT before the enclosing object's 'kids' line");
    if (k == "SURF" || k == "mat" || k == "refs")
      return Fail(QuotedToken(k) + " outside a surface (numsurf announced fewer surfaces)");
    if ((k[0] >= '0' && k[0] <= '9') || k[0] == '-' || k[0] == '+' || k[0] == '.')
      return Fail("numbers outside a vertex or reference list (numvert or refs announced fewer lines)");
    return Status::Ok();  // texture, texrep, texoff, crease, url, hidden, ...: nothing geometric
  }

  TextLines& in_;
  bool root_seen_ = false, done_ = false, in_object_ = false;
  std::vector<uint32_t> kids_left_;  // per open object: children still to come
  Object object_;                    // the object whose header is being read
  std::vector<std::string_view> tokens_;
};

}  // namespace

Status CheckAc3dFile(const std::string& path) {
  auto lines = TextLines::Open(path);
  if (!lines.ok()) return lines.status();
  return Ac3dCheck(lines->get()).Run();
}

}  // namespace mktree
