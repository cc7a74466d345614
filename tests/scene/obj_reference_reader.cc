// Test oracle: see obj_reference_reader.h.
#include "scene/obj_reference_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <string_view>
#include <vector>

namespace mktree::reference {
namespace {

constexpr size_t kReadBufferBytes = size_t{1} << 20;

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

std::string_view Trim(std::string_view s) {
  while (!s.empty() && IsBlank(s.front())) s.remove_prefix(1);
  while (!s.empty() && IsBlank(s.back())) s.remove_suffix(1);
  return s;
}

// Splits off the next whitespace-separated token of `*s` (empty when none is left).
std::string_view NextToken(std::string_view* s) {
  size_t i = 0;
  while (i < s->size() && IsBlank((*s)[i])) ++i;
  size_t j = i;
  while (j < s->size() && !IsBlank((*s)[j])) ++j;
  std::string_view tok = s->substr(i, j - i);
  s->remove_prefix(j);
  return tok;
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

std::string Errno(const std::string& path) { return path + ": " + std::strerror(errno); }

// Open-addressing map from global vertex index to local (per-object) index. Its size follows the current
// object only, so memory stays bounded by the largest object.
class VertexIndexMap {
 public:
  // Returns the local index of `global`, inserting `next_local` when absent (then *inserted = true).
  uint32_t FindOrInsert(uint32_t global, uint32_t next_local, bool* inserted) {
    if ((size_ + 1) * 2 > slots_.size()) Grow();
    const uint32_t key = global + 1;  // 0 marks an empty slot
    size_t mask = slots_.size() - 1;
    size_t i = Hash(key) & mask;
    while (true) {
      Slot& s = slots_[i];
      if (s.key == key) {
        *inserted = false;
        return s.local;
      }
      if (s.key == 0) {
        s = Slot{key, next_local};
        ++size_;
        *inserted = true;
        return next_local;
      }
      i = (i + 1) & mask;
    }
  }

  void Clear() {
    // Drop a table that a huge object left behind rather than clearing it for every small object.
    if (slots_.size() > 4096 && size_ * 8 < slots_.size()) {
      slots_.assign(4096, Slot{});
    } else {
      std::fill(slots_.begin(), slots_.end(), Slot{});
    }
    size_ = 0;
  }

 private:
  struct Slot {
    uint32_t key = 0;
    uint32_t local = 0;
  };
  static size_t Hash(uint32_t k) { return (static_cast<uint64_t>(k) * 0x9E3779B97F4A7C15ull) >> 32; }

  void Grow() {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(old.empty() ? 1024 : old.size() * 2, Slot{});
    size_t mask = slots_.size() - 1;
    for (const Slot& s : old) {
      if (s.key == 0) continue;
      size_t i = Hash(s.key) & mask;
      while (slots_[i].key != 0) i = (i + 1) & mask;
      slots_[i] = s;
    }
  }

  std::vector<Slot> slots_;
  size_t size_ = 0;
};

// The global vertex table, in fixed-size blocks: growth never copies the table or needs twice its size,
// so its footprint stays 24 bytes per vertex (plus at most one partly filled block). Doubles, because
// coordinates far from 0 (UTM, geocentric) lose their detail in float32.
class VertexTable {
 public:
  size_t size() const { return size_; }
  void Push(const double xyz[3]) {
    if ((size_ & kBlockMask) == 0)
      blocks_.emplace_back(new double[3 * kBlockVertices]);  // uninitialised: filled by Push
    std::memcpy(&blocks_.back()[3 * (size_ & kBlockMask)], xyz, 3 * sizeof(double));
    ++size_;
  }
  const double* At(uint32_t v) const { return &blocks_[v >> kBlockShift][3 * (v & kBlockMask)]; }

 private:
  static constexpr int kBlockShift = 16;
  static constexpr size_t kBlockVertices = size_t{1} << kBlockShift;
  static constexpr size_t kBlockMask = kBlockVertices - 1;
  std::vector<std::unique_ptr<double[]>> blocks_;
  size_t size_ = 0;
};

enum class GroupRule { kUnknown, kGroupsStartObjects, kGroupsIgnored };

class ObjReader final : public SceneSource {
 public:
  ObjReader(std::string path, int fd, ObjectId first_id)
      : path_(std::move(path)), fd_(fd), next_id_(first_id), buf_(new char[kReadBufferBytes]) {}
  ~ObjReader() override { ::close(fd_); }
  ObjReader(const ObjReader&) = delete;
  ObjReader& operator=(const ObjReader&) = delete;

  Result<bool> Next(SceneObject* out) override;

 private:
  // Sets *line to the next record (CR stripped, continuations joined) and record_line_ to its first line
  // number. Returns false at the end of the file.
  Result<bool> NextRecord(std::string_view* line);
  Status Fill();
  Status ParseVertex(std::string_view rest);
  Status ParseFace(std::string_view rest);
  Result<bool> ResolveIndex(std::string_view token, std::string_view digits, uint64_t count, const char* what,
                            uint32_t* index);
  Result<bool> FileHasObjectLines();
  // Ends the current object (emitting it into *out when it has faces) and starts one named `name`.
  Result<bool> StartObject(std::string_view name, SceneObject* out);
  Result<bool> Emit(SceneObject* out);
  Status Error(const std::string& what) const;

  const std::string path_;
  const int fd_;
  uint64_t next_id_;

  // Read buffer (uninitialised; grows only to hold the longest line): bytes [begin_, end_) are unread.
  std::unique_ptr<char[]> buf_;
  size_t capacity_ = kReadBufferBytes;
  size_t begin_ = 0, end_ = 0;
  bool eof_ = false;
  uint64_t line_no_ = 0;              // lines consumed so far
  uint64_t record_line_ = 0;          // line number of the record being parsed
  bool record_unterminated_ = false;  // the record is the last line and has no newline
  std::string joined_;                // a record spread over lines joined by a trailing backslash

  VertexTable positions_;
  uint64_t texcoord_count_ = 0, normal_count_ = 0;

  GroupRule group_rule_ = GroupRule::kUnknown;
  std::string name_;  // current object's name; empty = unnamed
  Mesh mesh_;
  VertexIndexMap local_of_global_;
  std::vector<uint32_t> face_;  // scratch: the current face's local indices

  std::vector<std::string> groups_;
  std::string material_;
  std::vector<ObjectAttribute> attributes_;

  Status error_;  // sticky: once failed, every later call fails the same way
  bool done_ = false;
};

Status ObjReader::Error(const std::string& what) const {
  std::string msg = path_ + ":" + std::to_string(record_line_) + ": " + what;
  if (record_unterminated_) msg += " (the file ends inside this line: truncated?)";
  return Status::Corruption(std::move(msg));
}

Status ObjReader::Fill() {
  if (begin_ > 0) {
    std::memmove(buf_.get(), buf_.get() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  if (end_ == capacity_) {  // a line longer than the buffer
    std::unique_ptr<char[]> bigger(new char[2 * capacity_]);
    std::memcpy(bigger.get(), buf_.get(), end_);
    buf_ = std::move(bigger);
    capacity_ *= 2;
  }
  while (true) {
    ssize_t n = ::read(fd_, buf_.get() + end_, capacity_ - end_);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return Status::IOError(Errno(path_));
    if (n == 0) eof_ = true;
    end_ += static_cast<size_t>(n);
    return Status::Ok();
  }
}

Result<bool> ObjReader::NextRecord(std::string_view* line) {
  joined_.clear();
  bool continued = false;
  record_unterminated_ = false;
  while (true) {
    std::string_view raw;
    const char* nl = nullptr;
    while (true) {
      nl = static_cast<const char*>(std::memchr(buf_.get() + begin_, '\n', end_ - begin_));
      if (nl != nullptr || eof_) break;
      MKTREE_RETURN_IF_ERROR(Fill());
    }
    if (nl != nullptr) {
      raw = std::string_view(buf_.get() + begin_, nl - (buf_.get() + begin_));
      begin_ = nl - buf_.get() + 1;
    } else if (begin_ < end_) {
      raw = std::string_view(buf_.get() + begin_, end_ - begin_);
      begin_ = end_;
      record_unterminated_ = true;
    } else if (continued) {
      record_unterminated_ = true;
      *line = joined_;
      return true;
    } else {
      return false;
    }
    ++line_no_;
    if (!continued) record_line_ = line_no_;
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

// Parses one coordinate token as a double. Overflow is an error; underflow reads as the nearest double (0
// or a subnormal) like any other rounding.
bool ParseCoordinateImpl(std::string_view tok, double* out, std::string* why) {
  const char* b = tok.data();
  const char* e = tok.data() + tok.size();
  if (b != e && *b == '+') ++b;  // from_chars rejects a leading '+'; OBJ writers sometimes emit it
  double v = 0;
  auto [p, ec] = std::from_chars(b, e, v);
  if (ec == std::errc::result_out_of_range && p == e) {
    const size_t exp = tok.find_first_of("eE");
    const bool underflow = exp != std::string_view::npos && exp + 1 < tok.size() && tok[exp + 1] == '-';
    if (!underflow) {
      *why = "coordinate out of range " + Quote(tok);
      return false;
    }
    v = tok.front() == '-' ? -0.0 : 0.0;
  } else if (ec != std::errc() || p != e) {
    *why = "bad number " + Quote(tok);
    return false;
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

Status ObjReader::ParseVertex(std::string_view rest) {
  double xyz[3];
  int n = 0;
  std::string why;
  for (std::string_view tok = NextToken(&rest); !tok.empty(); tok = NextToken(&rest), ++n) {
    double v;
    // Values past z (w, or r g b [a] colours) are checked as numbers but not kept.
    if (!ParseCoordinateImpl(tok, &v, &why)) return Error("vertex: " + why);
    if (n < 3) xyz[n] = v;
  }
  if (n < 3) return Error("vertex: too few coordinates (" + std::to_string(n) + ", need x y z)");
  if (n > 7) return Error("vertex: too many values (" + std::to_string(n) + ", at most 7)");
  if (positions_.size() >= std::numeric_limits<uint32_t>::max() - 1)
    return Error("more than 2^32 - 2 vertices");
  positions_.Push(xyz);
  return Status::Ok();
}

// Resolves an OBJ index (1-based, or negative = relative to the last `count` entries) to 0-based.
// Returns false (with *index untouched) when `digits` is empty and the part is optional.
Result<bool> ObjReader::ResolveIndex(std::string_view token, std::string_view digits, uint64_t count,
                                     const char* what, uint32_t* index) {
  int64_t i = 0;
  const char* b = digits.data();
  const char* e = digits.data() + digits.size();
  if (b != e && *b == '+') ++b;
  auto [p, ec] = std::from_chars(b, e, i);
  if (ec != std::errc() || p != e) return Error("face: bad vertex reference " + Quote(token));
  if (i == 0)
    return Error(std::string("face: ") + what + " index 0 in " + Quote(token) + " (indices start at 1)");
  int64_t resolved = i > 0 ? i - 1 : static_cast<int64_t>(count) + i;
  if (resolved < 0 || static_cast<uint64_t>(resolved) >= count) {
    return Error(std::string("face: ") + what + " index " + std::to_string(i) + " out of range (" +
                 std::to_string(count) + " defined so far)");
  }
  *index = static_cast<uint32_t>(resolved);
  return true;
}

Status ObjReader::ParseFace(std::string_view rest) {
  face_.clear();
  const uint64_t vertex_count = positions_.size();
  for (std::string_view tok = NextToken(&rest); !tok.empty(); tok = NextToken(&rest)) {
    // v, v/vt, v//vn or v/vt/vn
    std::string_view parts[3];
    int nparts = 0;
    size_t start = 0;
    while (true) {
      size_t slash = tok.find('/', start);
      if (nparts == 3) return Error("face: bad vertex reference " + Quote(tok));
      parts[nparts++] = tok.substr(start, slash == std::string_view::npos ? slash : slash - start);
      if (slash == std::string_view::npos) break;
      start = slash + 1;
    }
    // Empty parts are allowed only for an absent vt (v//vn); "1/" or "1/2/" are malformed.
    if (parts[0].empty() || (nparts == 2 && parts[1].empty()) || (nparts == 3 && parts[2].empty())) {
      return Error("face: bad vertex reference " + Quote(tok));
    }
    uint32_t v = 0, unused = 0;
    auto r = ResolveIndex(tok, parts[0], vertex_count, "vertex", &v);
    if (!r.ok()) return r.status();
    if (nparts >= 2 && !parts[1].empty()) {
      r = ResolveIndex(tok, parts[1], texcoord_count_, "texture coordinate", &unused);
      if (!r.ok()) return r.status();
    }
    if (nparts == 3) {
      r = ResolveIndex(tok, parts[2], normal_count_, "normal", &unused);
      if (!r.ok()) return r.status();
    }
    bool inserted = false;
    uint32_t local = local_of_global_.FindOrInsert(v, static_cast<uint32_t>(mesh_.vertex_count()), &inserted);
    if (inserted) {
      const double* p = positions_.At(v);
      mesh_.vertices.insert(mesh_.vertices.end(), p, p + 3);
    }
    face_.push_back(local);
  }
  if (face_.size() < 3) {
    return Error("face: " + std::to_string(face_.size()) + " vertices (a face needs at least 3)");
  }
  for (size_t i = 1; i + 1 < face_.size(); ++i) {
    mesh_.triangles.insert(mesh_.triangles.end(), {face_[0], face_[i], face_[i + 1]});
  }
  auto add = [this](const std::string& key, const std::string& value) {
    ObjectAttribute a{key, value};
    if (std::find(attributes_.begin(), attributes_.end(), a) == attributes_.end()) attributes_.push_back(a);
  };
  for (const std::string& g : groups_) add("group", g);
  if (!material_.empty()) add("material", material_);
  return Status::Ok();
}

// True when some line of the file starts with the `o` directive. Reads the file through its own
// descriptor so the main read position is untouched; stops at the first hit.
Result<bool> ObjReader::FileHasObjectLines() {
  int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Status::IOError(Errno(path_));
  std::unique_ptr<char[]> buf(new char[kReadBufferBytes]);
  enum { kLineStart, kSawO, kInLine } state = kLineStart;
  bool found = false;
  while (!found) {
    ssize_t n = ::read(fd, buf.get(), kReadBufferBytes);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      Status st = Status::IOError(Errno(path_));
      ::close(fd);
      return st;
    }
    if (n == 0) {
      found = state == kSawO;
      break;
    }
    const char* p = buf.get();
    const char* end = p + n;
    while (p < end && !found) {
      char c = *p;
      if (state == kInLine) {
        const void* nl = std::memchr(p, '\n', end - p);
        if (nl == nullptr) break;
        p = static_cast<const char*>(nl) + 1;
        state = kLineStart;
        continue;
      }
      if (state == kLineStart) {
        state = c == 'o' ? kSawO : (c == ' ' || c == '\t' ? kLineStart : (c == '\n' ? kLineStart : kInLine));
      } else {  // kSawO: "o" must be the whole directive
        found = c == ' ' || c == '\t' || c == '\r' || c == '\n';
        state = c == '\n' ? kLineStart : kInLine;
      }
      ++p;
    }
  }
  ::close(fd);
  return found;
}

Result<bool> ObjReader::Emit(SceneObject* out) {
  if (next_id_ > std::numeric_limits<ObjectId>::max()) return Error("more than 2^32 objects");
  out->id = static_cast<ObjectId>(next_id_++);
  out->name = name_.empty() ? "object_" + std::to_string(out->id) : name_;
  out->source = path_;
  out->attributes = std::move(attributes_);
  attributes_.clear();
  out->mesh = std::move(mesh_);
  mesh_ = Mesh();
  local_of_global_.Clear();
  return true;
}

Result<bool> ObjReader::StartObject(std::string_view name, SceneObject* out) {
  // Vertices enter an object's mesh only through its faces, so a faceless object left nothing behind.
  bool emitted = false;
  if (mesh_.triangle_count() > 0) {
    auto r = Emit(out);
    if (!r.ok()) return r;
    emitted = true;
  }
  name_.assign(Trim(name));
  return emitted;
}

Result<bool> ObjReader::Next(SceneObject* out) {
  if (!error_.ok()) return error_;
  if (done_) return false;
  auto fail = [this](Status st) -> Result<bool> {
    error_ = std::move(st);
    return error_;
  };
  std::string_view line;
  while (true) {
    auto more = NextRecord(&line);
    if (!more.ok()) return fail(more.status());
    if (!*more) {
      done_ = true;
      if (mesh_.triangle_count() == 0) return false;
      auto r = Emit(out);
      if (!r.ok()) return fail(r.status());
      return true;
    }
    std::string_view rest = line;
    std::string_view key = NextToken(&rest);
    if (key.empty() || key.front() == '#') continue;
    Status st;
    if (key == "v") {
      st = ParseVertex(rest);
    } else if (key == "f") {
      st = ParseFace(rest);
    } else if (key == "o" || key == "g") {
      if (key == "g") {
        groups_.clear();
        std::string_view names = rest;
        for (std::string_view n = NextToken(&names); !n.empty(); n = NextToken(&names))
          groups_.emplace_back(n);
      }
      if (key == "o") {
        group_rule_ = GroupRule::kGroupsIgnored;
      } else if (group_rule_ == GroupRule::kUnknown) {
        auto has_o = FileHasObjectLines();
        if (!has_o.ok()) return fail(has_o.status());
        group_rule_ = *has_o ? GroupRule::kGroupsIgnored : GroupRule::kGroupsStartObjects;
      }
      if (key == "o" || group_rule_ == GroupRule::kGroupsStartObjects) {
        auto r = StartObject(rest, out);
        if (!r.ok()) return fail(r.status());
        if (*r) return true;
      }
    } else if (key == "vt") {
      ++texcoord_count_;
    } else if (key == "vn") {
      ++normal_count_;
    } else if (key == "usemtl") {
      material_.assign(Trim(rest));
    } else if (key == "vp" || key == "l" || key == "p" || key == "s" || key == "mtllib" || key == "lod" ||
               key == "bevel" || key == "c_interp" || key == "d_interp" || key == "usemap" ||
               key == "maplib" || key == "shadow_obj" || key == "trace_obj" || key == "mg") {
      // Carries no triangle geometry.
    } else if (key == "cstype" || key == "deg" || key == "bmat" || key == "step" || key == "curv" ||
               key == "curv2" || key == "surf" || key == "parm" || key == "trim" || key == "hole" ||
               key == "scrv" || key == "sp" || key == "end" || key == "con") {
      st = Status::Unsupported(path_ + ":" + std::to_string(record_line_) + ": free-form geometry (" +
                               Quote(key) + ") is not supported");
    } else {
      st = Error("unknown directive " + Quote(key));
    }
    if (!st.ok()) return fail(std::move(st));
  }
}

}  // namespace

bool ParseCoordinate(std::string_view tok, double* out, std::string* why) {
  return ParseCoordinateImpl(tok, out, why);
}

Result<std::unique_ptr<SceneSource>> OpenObjFile(const std::string& path, ObjectId first_id) {
  auto fd = OpenSceneInput(path);
  if (!fd.ok()) return fd.status();
  ::posix_fadvise(*fd, 0, 0, POSIX_FADV_SEQUENTIAL);
  return std::unique_ptr<SceneSource>(new ObjReader(path, *fd, first_id));
}

}  // namespace mktree::reference
