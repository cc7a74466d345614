#include "engine/scene/obj_chunk.h"

#include <fast_float/fast_float.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <string_view>

#include "mktree/scene.h"

namespace mktree {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

std::string_view Trim(std::string_view s) {
  while (!s.empty() && IsBlank(s.front())) s.remove_prefix(1);
  while (!s.empty() && IsBlank(s.back())) s.remove_suffix(1);
  return s;
}

std::string_view NextToken(std::string_view* s) { return ObjNextToken(s); }

// A coordinate as exporters write it, [sign]digits[.digits] with at most 15 digits and not zero, ending
// at a blank or the end: the digits' integer and 10^k (k <= 15) are exact doubles, so one division gives
// the correctly rounded value, the double fast_float returns (Clinger's fast path), without its general
// parse. False for anything else (exponents, long mantissas, zeros, nan), left to fast_float.
bool ParseShortDecimal(const char* p, const char* e, double* v, const char** end) {
  static constexpr double kPow10[16] = {1e0, 1e1, 1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                        1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15};
  const bool negative = p != e && *p == '-';
  p += p != e && (*p == '-' || *p == '+');
  uint64_t m = 0;
  const char* q = p;
  for (; q != e && static_cast<unsigned char>(*q - '0') < 10 && q - p < 16; ++q) m = 10 * m + (*q - '0');
  size_t digits = static_cast<size_t>(q - p), fraction = 0;
  if (q != e && *q == '.') {
    const char* f = ++q;
    for (; q != e && static_cast<unsigned char>(*q - '0') < 10 && digits + (q - f) < 16; ++q)
      m = 10 * m + (*q - '0');
    fraction = static_cast<size_t>(q - f);
    digits += fraction;
  }
  if (digits == 0 || digits > 15 || m == 0 || (q != e && !IsBlank(*q))) return false;
  const double x = static_cast<double>(m) / kPow10[fraction];
  *v = negative ? -x : x;
  *end = q;
  return true;
}

// Quoted token for messages, shortened so a garbage line cannot flood an error message.
std::string Quote(std::string_view s) {
  constexpr size_t kMax = 40;
  std::string q(1, '\'');
  q.append(s.substr(0, kMax));
  if (s.size() > kMax) q.append("...");
  q.push_back('\'');
  return q;
}

class ChunkParser {
 public:
  ChunkParser(const char* data, ObjChunk* c) : data_(data), c_(*c) {}
  void Run();

 private:
  bool NextRecord(std::string_view* line);
  void Fail(const std::string& what, bool unsupported = false) {
    c_.has_error = true;
    c_.error_unsupported = unsupported;
    c_.error_unterminated = unterminated_ && !unsupported;
    c_.error_line = record_line_;
    c_.error_what = what;
  }
  void AddOp(ObjOpKind kind, uint32_t count) {
    ObjOp op;
    op.kind = kind;
    op.count = count;
    op.line = record_line_;
    c_.ops.push_back(op);
  }
  void AddName(ObjOpKind kind, std::string_view name) {
    if (name.size() > UINT32_MAX) name = name.substr(0, UINT32_MAX);
    AddOp(kind, static_cast<uint32_t>(name.size()));
    c_.names.append(name);
  }
  void ParseVertex(std::string_view rest);
  void ParseFace(std::string_view rest);
  // Reads one index part; false (with the error set) when it is malformed or 0.
  bool ParseIndex(std::string_view token, std::string_view digits, const char* what, int64_t* index);

  const char* data_;
  ObjChunk& c_;
  const char* p_ = nullptr;
  const char* end_ = nullptr;
  uint64_t record_line_ = 0;
  bool unterminated_ = false;
  std::string joined_;
};

// The record (CR stripped, continuations joined) as in the single-threaded reader this replaces.
bool ChunkParser::NextRecord(std::string_view* line) {
  joined_.clear();
  bool continued = false;
  unterminated_ = false;
  while (true) {
    std::string_view raw;
    if (p_ == end_) {
      if (!continued) return false;
      unterminated_ = true;  // a continuation at the end of the file
      c_.unterminated_line = record_line_;
      *line = joined_;
      return true;
    }
    const char* nl = static_cast<const char*>(std::memchr(p_, '\n', end_ - p_));
    if (nl != nullptr) {
      raw = std::string_view(p_, nl - p_);
      p_ = nl + 1;
    } else {
      raw = std::string_view(p_, end_ - p_);
      p_ = end_;
      unterminated_ = true;
    }
    ++c_.lines;
    if (!continued) record_line_ = c_.lines;
    if (unterminated_) c_.unterminated_line = record_line_;
    if (!raw.empty() && raw.back() == '\r') raw.remove_suffix(1);
    if (!raw.empty() && raw.back() == '\\') {
      raw.remove_suffix(1);
      joined_.append(raw);
      joined_.push_back(' ');
      continued = true;
      continue;
    }
    if (!continued) {
      *line = raw;
    } else {
      joined_.append(raw);
      *line = joined_;
    }
    return true;
  }
}

void ChunkParser::ParseVertex(std::string_view rest) {
  double xyz[3];
  int n = 0;
  std::string why;
  const char* p = rest.data();
  const char* const e = rest.data() + rest.size();
  while (true) {
    while (p != e && IsBlank(*p)) ++p;
    if (p == e) break;
    // Fast path: a plain nonzero finite number ending at a blank; anything else is decided by
    // ParseObjCoordinate on the whole token.
    double v = 0;
    const char* q = nullptr;
    std::errc ec{};
    if (!ParseShortDecimal(p, e, &v, &q)) {
      const char* b = p + (*p == '+');
      const auto r = fast_float::from_chars(b, e, v);
      q = r.ptr;
      ec = r.ec;
    }
    if (ec != std::errc() || (q != e && !IsBlank(*q)) || v == 0 || !(std::fabs(v) <= kMaxCoordinate)) {
      q = p;
      while (q != e && !IsBlank(*q)) ++q;
      // Values past z (w, or r g b [a] colours) are checked as numbers but not kept.
      if (!ParseObjCoordinate(p, q, &v, &why)) return Fail("vertex: " + why);
    }
    if (n < 3) xyz[n] = v;
    ++n;
    p = q;
  }
  if (n < 3) return Fail("vertex: too few coordinates (" + std::to_string(n) + ", need x y z)");
  if (n > 7) return Fail("vertex: too many values (" + std::to_string(n) + ", at most 7)");
  c_.vertices.push_back(xyz[0]);
  c_.vertices.push_back(xyz[1]);
  c_.vertices.push_back(xyz[2]);
  if (!c_.ops.empty()) {
    ObjOp& last = c_.ops.back();
    // A run keeps line = first line + position, which the vertex-count check needs.
    if (last.kind == ObjOpKind::kVertices && last.line + last.count == record_line_ &&
        last.count < UINT32_MAX) {
      ++last.count;
      return;
    }
  }
  AddOp(ObjOpKind::kVertices, 1);
}

bool ChunkParser::ParseIndex(std::string_view token, std::string_view digits, const char* what,
                             int64_t* index) {
  int64_t i = 0;
  const char* b = digits.data();
  const char* e = digits.data() + digits.size();
  if (b != e && *b == '+') ++b;
  auto [p, ec] = std::from_chars(b, e, i);
  if (ec != std::errc() || p != e) {
    Fail("face: bad vertex reference " + Quote(token));
    return false;
  }
  if (i == 0) {
    Fail(std::string("face: ") + what + " index 0 in " + Quote(token) + " (indices start at 1)");
    return false;
  }
  *index = i;
  return true;
}

void ChunkParser::ParseFace(std::string_view rest) {
  // Plain faces (every token a v index) keep one reference per vertex; the first token with a slash turns
  // the face into v, vt, vn triples.
  const size_t first = c_.refs.size();
  uint32_t n = 0;
  uint8_t stride = 1;
  auto fail_at = [&](uint64_t stop) {
    AddOp(ObjOpKind::kFaceError, 1);
    c_.ops.back().stride = stride;
    c_.ops.back().corners = n;
    c_.error_stop = stop;
  };
  auto widen = [&] {
    if (stride == 3) return;
    stride = 3;
    c_.refs.resize(first + 3 * size_t{n});
    for (size_t i = n; i-- > 0;) {
      const int64_t v = c_.refs[first + i];
      c_.refs[first + 3 * i] = v;
      c_.refs[first + 3 * i + 1] = 0;
      c_.refs[first + 3 * i + 2] = 0;
    }
  };
  const char* const e = rest.data() + rest.size();
  while (true) {
    const char* p = rest.data();
    while (p != e && IsBlank(*p)) ++p;
    // Fast path: a plain index ([+-]digits, at most 18) ending at a blank.
    const char* q = p;
    const bool negative = q != e && *q == '-';
    q += q != e && (*q == '-' || *q == '+');
    const char* digits = q;
    int64_t value = 0;
    while (q != e && static_cast<unsigned char>(*q - '0') < 10 && q - digits < 18)
      value = 10 * value + (*q++ - '0');
    if (q != digits && value != 0 && (q == e || IsBlank(*q))) {
      c_.refs.push_back(negative ? -value : value);
      if (stride == 3) {
        c_.refs.push_back(0);
        c_.refs.push_back(0);
      }
      ++n;
      rest = std::string_view(q, e - q);
      continue;
    }
    std::string_view tok = NextToken(&rest);
    if (tok.empty()) break;
    widen();
    // v, v/vt, v//vn or v/vt/vn
    std::string_view parts[3];
    int nparts = 0;
    size_t start = 0;
    bool bad = false;
    while (true) {
      size_t slash = tok.find('/', start);
      if (nparts == 3) {
        bad = true;
        break;
      }
      parts[nparts++] = tok.substr(start, slash == std::string_view::npos ? slash : slash - start);
      if (slash == std::string_view::npos) break;
      start = slash + 1;
    }
    // Empty parts are allowed only for an absent vt (v//vn); "1/" or "1/2/" are malformed.
    if (bad || parts[0].empty() || (nparts == 2 && parts[1].empty()) || (nparts == 3 && parts[2].empty())) {
      Fail("face: bad vertex reference " + Quote(tok));
      return fail_at(3 * uint64_t{n});
    }
    int64_t idx[3] = {0, 0, 0};
    int failed = -1;  // the part that failed to parse
    if (!ParseIndex(tok, parts[0], "vertex", &idx[0])) {
      failed = 0;
    } else if (nparts >= 2 && !parts[1].empty() &&
               !ParseIndex(tok, parts[1], "texture coordinate", &idx[1])) {
      failed = 1;
    } else if (nparts == 3 && !ParseIndex(tok, parts[2], "normal", &idx[2])) {
      failed = 2;
    }
    c_.refs.push_back(idx[0]);
    c_.refs.push_back(idx[1]);
    c_.refs.push_back(idx[2]);
    if (failed >= 0) return fail_at(3 * uint64_t{n} + failed);
    ++n;
  }
  if (n < 3) {
    Fail("face: " + std::to_string(n) + " vertices (a face needs at least 3)");
    return fail_at(stride * uint64_t{n});
  }
  if (!c_.ops.empty()) {
    ObjOp& last = c_.ops.back();
    if (last.kind == ObjOpKind::kFaces && last.stride == stride && last.corners == n &&
        last.line + last.count == record_line_ && last.count < UINT32_MAX) {
      ++last.count;
      return;
    }
  }
  AddOp(ObjOpKind::kFaces, 1);
  c_.ops.back().stride = stride;
  c_.ops.back().corners = n;
}

void ChunkParser::Run() {
  p_ = data_;
  end_ = data_ + (c_.end - c_.begin);
  std::string_view line;
  while (!c_.has_error && NextRecord(&line)) {
    // Most records are "v x y z" and "f a b c": recognised without splitting off the key.
    if (line.size() >= 2 && IsBlank(line[1])) {
      if (line[0] == 'v') {
        ParseVertex(line.substr(1));
        continue;
      }
      if (line[0] == 'f') {
        ParseFace(line.substr(1));
        continue;
      }
    }
    std::string_view rest = line;
    std::string_view key = NextToken(&rest);
    if (key.empty() || key.front() == '#') continue;
    if (key == "v") {
      ParseVertex(rest);
    } else if (key == "f") {
      ParseFace(rest);
    } else if (key == "o") {
      AddName(ObjOpKind::kObject, Trim(rest));
    } else if (key == "g") {
      AddName(ObjOpKind::kGroup, Trim(rest));
    } else if (key == "usemtl") {
      AddName(ObjOpKind::kMaterial, Trim(rest));
    } else if (key == "vt" || key == "vn") {
      const ObjOpKind kind = key == "vt" ? ObjOpKind::kTexcoords : ObjOpKind::kNormals;
      if (!c_.ops.empty() && c_.ops.back().kind == kind && c_.ops.back().count < UINT32_MAX) {
        ++c_.ops.back().count;
      } else {
        AddOp(kind, 1);
      }
    } else if (key == "vp" || key == "l" || key == "p" || key == "s" || key == "mtllib" || key == "lod" ||
               key == "bevel" || key == "c_interp" || key == "d_interp" || key == "usemap" ||
               key == "maplib" || key == "shadow_obj" || key == "trace_obj" || key == "mg") {
      // Carries no triangle geometry.
    } else if (key == "cstype" || key == "deg" || key == "bmat" || key == "step" || key == "curv" ||
               key == "curv2" || key == "surf" || key == "parm" || key == "trim" || key == "hole" ||
               key == "scrv" || key == "sp" || key == "end" || key == "con") {
      Fail("free-form geometry (" + Quote(key) + ") is not supported", /*unsupported=*/true);
    } else {
      Fail("unknown directive " + Quote(key));
    }
  }
  if (c_.has_error && (c_.ops.empty() || c_.ops.back().kind != ObjOpKind::kFaceError))
    AddOp(ObjOpKind::kError, 0);
}

}  // namespace

std::string_view ObjNextToken(std::string_view* s) {
  size_t i = 0;
  while (i < s->size() && IsBlank((*s)[i])) ++i;
  size_t j = i;
  while (j < s->size() && !IsBlank((*s)[j])) ++j;
  std::string_view tok = s->substr(i, j - i);
  s->remove_prefix(j);
  return tok;
}

void ObjChunk::Reset(size_t b, size_t e) {
  begin = b;
  end = e;
  lines = unterminated_line = 0;
  vertices.clear();
  refs.clear();
  ops.clear();
  names.clear();
  has_error = error_unsupported = error_unterminated = false;
  error_line = error_stop = 0;
  error_what.clear();
}

void ParseObjChunk(const char* data, ObjChunk* chunk) { ChunkParser(data, chunk).Run(); }

size_t ObjLineBoundary(const char* data, size_t size, size_t from) {
  size_t at = from;
  while (at < size) {
    const char* nl = static_cast<const char*>(std::memchr(data + at, '\n', size - at));
    if (nl == nullptr) break;
    const size_t i = nl - data;
    // "\\\n" and "\\\r\n" continue the line (see NextRecord).
    const bool continued =
        (i >= 1 && data[i - 1] == '\\') || (i >= 2 && data[i - 1] == '\r' && data[i - 2] == '\\');
    if (!continued) return i + 1;
    at = i + 1;
  }
  return SIZE_MAX;
}

bool ParseObjCoordinate(const char* b, const char* e, double* out, std::string* why) {
  const std::string_view tok(b, e - b);
  if (b != e && *b == '+') ++b;  // OBJ writers sometimes emit a leading '+'; one is allowed
  double v = 0;
  auto [p, ec] = fast_float::from_chars(b, e, v);
  if (ec != std::errc() || p != e) {
    *why = "bad number " + Quote(tok);
    return false;
  }
  if (v == 0 || std::isinf(v)) {
    // fast_float rounds out-of-range decimals to 0 or infinity; tell those from written zeros and infinities.
    const char* m = b + (b != e && *b == '-');
    const bool literal_inf = m != e && (*m == 'i' || *m == 'I');
    bool nonzero_digit = false;
    for (const char* q = m; q != e && *q != 'e' && *q != 'E'; ++q) nonzero_digit |= *q >= '1' && *q <= '9';
    if (std::isinf(v) && !literal_inf) {
      *why = "coordinate out of range " + Quote(tok);
      return false;
    }
    if (v == 0 && nonzero_digit) {
      const size_t exp = tok.find_first_of("eE");
      const bool underflow = exp != std::string_view::npos && exp + 1 < tok.size() && tok[exp + 1] == '-';
      if (!underflow) {
        *why = "coordinate out of range " + Quote(tok);
        return false;
      }
      v = tok.front() == '-' ? -0.0 : 0.0;
    }
  }
  if (!std::isfinite(v)) {
    *why = "non-finite coordinate " + Quote(tok);
    return false;
  }
  if (std::fabs(v) > kMaxCoordinate) {
    *why = "coordinate out of range " + Quote(tok) + " (at most 2^124 in magnitude)";
    return false;
  }
  *out = v;
  return true;
}

}  // namespace mktree
