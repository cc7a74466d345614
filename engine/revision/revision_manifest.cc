#include "engine/revision/revision_manifest.h"

#include <xxhash.h>

#include <algorithm>
#include <charconv>
#include <cinttypes>
#include <cstdio>
#include <sstream>

namespace mktree {

namespace {

constexpr char kMagicLine[] = "mktree-revision";

std::string Hex(uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016" PRIx64, v);
  return buf;
}

std::string Escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '\\')
      out += "\\\\";
    else if (c == '\n')
      out += "\\n";
    else if (c == '\r')
      out += "\\r";
    else
      out += c;
  }
  return out;
}

void PutFile(std::string* out, const RevisionFile& f) {
  *out += ' ' + (f.name.empty() ? std::string("-") : f.name) + ' ' + std::to_string(f.bytes) + ' ' +
          Hex(f.fingerprint);
}

// Splits a line into words on single spaces (the message line is taken whole).
std::vector<std::string> Words(const std::string& line) {
  std::vector<std::string> w;
  std::istringstream in(line);
  for (std::string s; in >> s;) w.push_back(s);
  return w;
}

class Parser {
 public:
  Parser(const std::string& what, int line) : what_(what), line_(line) {}
  Status Bad(const std::string& why) const {
    return Status::Corruption(what_ + " line " + std::to_string(line_) + ": " + why);
  }
  Status U64(const std::string& s, uint64_t* v, int base = 10) const {
    const auto r = std::from_chars(s.data(), s.data() + s.size(), *v, base);
    if (r.ec != std::errc() || r.ptr != s.data() + s.size() || s.empty())
      return Bad("bad number '" + s + "'");
    return Status::Ok();
  }
  Status File(const std::vector<std::string>& w, size_t at, RevisionFile* f) const {
    if (w.size() < at + 3) return Bad("a file needs a name, a size and a fingerprint");
    f->name = w[at] == "-" ? "" : w[at];
    if (f->name.find('/') != std::string::npos || f->name == "." || f->name == "..")
      return Bad("file name '" + f->name + "' is not a name in the changes folder");
    MKTREE_RETURN_IF_ERROR(U64(w[at + 1], &f->bytes));
    return U64(w[at + 2], &f->fingerprint, 16);
  }

 private:
  const std::string& what_;
  int line_;
};

}  // namespace

std::string RevisionFileName(uint64_t revision) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "rev-%012" PRIu64 ".rev", revision);
  return buf;
}

bool ParseRevisionFileName(const std::string& name, uint64_t* revision) {
  if (name.size() != 4 + 12 + 4 || name.compare(0, 4, "rev-") != 0 || name.compare(16, 4, ".rev") != 0)
    return false;
  uint64_t v = 0;
  for (size_t i = 4; i < 16; ++i) {
    if (name[i] < '0' || name[i] > '9') return false;
    v = v * 10 + static_cast<uint64_t>(name[i] - '0');
  }
  *revision = v;
  return true;
}

std::string EncodeRevisionManifest(const RevisionManifest& m) {
  std::string s;
  const bool routed = std::any_of(m.deltas.begin(), m.deltas.end(),
                                  [](const RevisionPart& d) { return d.shard != kNoShard; });
  s += std::string(kMagicLine) + ' ' + std::to_string(routed ? kRevisionFormat : 1) + '\n';
  s += "history " + Hex(m.history) + '\n';
  s += "revision " + std::to_string(m.revision) + '\n';
  s += "time " + std::to_string(m.time) + '\n';
  s += "message " + Escape(m.message) + '\n';
  s += "batch " + std::to_string(m.added) + ' ' + std::to_string(m.removed) + ' ' +
       std::to_string(m.replaced) + ' ' + (m.compaction ? "1" : "0") + '\n';
  s += "next_id " + std::to_string(m.next_id) + '\n';
  s += "live " + std::to_string(m.live) + '\n';
  s += "keep " + std::to_string(m.keep) + '\n';
  auto part = [&](const char* key, const RevisionPart& p) {
    s += key + (' ' + std::to_string(p.made_at));
    PutFile(&s, p.store);
    PutFile(&s, p.ids);
    s += ' ' + std::to_string(p.objects);
    if (routed && &p != &m.base)
      s += ' ' + (p.shard == kNoShard ? std::string("-") : std::to_string(p.shard));
    s += '\n';
  };
  auto list = [&](const char* key, const RevisionIdList& l) {
    s += key + (' ' + std::to_string(l.made_at));
    PutFile(&s, l.file);
    s += ' ' + std::to_string(l.count) + '\n';
  };
  part("base", m.base);
  for (const RevisionPart& d : m.deltas) part("delta", d);
  for (const RevisionIdList& r : m.removals) list("removal", r);
  for (const RevisionIdList& t : m.touched) list("touched", t);
  s += "checksum " + Hex(XXH3_64bits(s.data(), s.size())) + '\n';
  return s;
}

Result<RevisionManifest> DecodeRevisionManifest(const std::string& text, const std::string& what) {
  RevisionManifest m;
  size_t at = 0;
  int line_no = 0;
  bool have_base = false, have_checksum = false;
  uint64_t format = 0;
  while (at < text.size()) {
    const size_t end = text.find('\n', at);
    if (end == std::string::npos)
      return Status::Corruption(what + " line " + std::to_string(line_no + 1) +
                                ": truncated (no end of line)");
    const std::string line = text.substr(at, end - at);
    const size_t line_start = at;
    at = end + 1;
    ++line_no;
    const Parser p(what, line_no);
    if (have_checksum) return p.Bad("text after the checksum");
    const std::vector<std::string> w = Words(line);
    if (w.empty()) return p.Bad("empty line");
    const std::string& key = w[0];
    if (line_no == 1) {
      if (key != kMagicLine || w.size() != 2) return p.Bad("not a revision file of an mktree store");
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], &format));
      if (format < 1 || format > kRevisionFormat)
        return p.Bad("revision format " + std::to_string(format) + ", this mktree reads formats 1 to " +
                     std::to_string(kRevisionFormat));
      continue;
    }
    if (line.rfind("message", 0) == 0 && (line.size() == 7 || line[7] == ' ')) {
      const std::string raw = line.size() > 8 ? line.substr(8) : "";
      for (size_t i = 0; i < raw.size(); ++i) {
        if (raw[i] != '\\') {
          m.message += raw[i];
          continue;
        }
        if (++i == raw.size()) return p.Bad("message ends in an escape");
        if (raw[i] == 'n')
          m.message += '\n';
        else if (raw[i] == 'r')
          m.message += '\r';
        else if (raw[i] == '\\')
          m.message += '\\';
        else
          return p.Bad("unknown escape in the message");
      }
      continue;
    }
    auto want = [&](size_t n) { return w.size() == n ? Status::Ok() : p.Bad(key + ": wrong field count"); };
    if (key == "checksum") {
      MKTREE_RETURN_IF_ERROR(want(2));
      uint64_t sum = 0;
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], &sum, 16));
      if (sum != XXH3_64bits(text.data(), line_start)) return p.Bad("checksum mismatch (damaged file)");
      have_checksum = true;
    } else if (key == "history") {
      MKTREE_RETURN_IF_ERROR(want(2));
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], &m.history, 16));
    } else if (key == "revision" || key == "next_id" || key == "live") {
      MKTREE_RETURN_IF_ERROR(want(2));
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], key == "revision"  ? &m.revision
                                         : key == "next_id" ? &m.next_id
                                                            : &m.live));
    } else if (key == "time") {
      MKTREE_RETURN_IF_ERROR(want(2));
      uint64_t t = 0;
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], &t));
      m.time = static_cast<int64_t>(t);
    } else if (key == "keep") {
      MKTREE_RETURN_IF_ERROR(want(2));
      uint64_t k = 0;
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], &k));
      if (k < 1 || k > 1000000) return p.Bad("keep must be from 1 to 1000000");
      m.keep = static_cast<uint32_t>(k);
    } else if (key == "batch") {
      MKTREE_RETURN_IF_ERROR(want(5));
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], &m.added));
      MKTREE_RETURN_IF_ERROR(p.U64(w[2], &m.removed));
      MKTREE_RETURN_IF_ERROR(p.U64(w[3], &m.replaced));
      if (w[4] != "0" && w[4] != "1") return p.Bad("batch: compaction flag is not 0 or 1");
      m.compaction = w[4] == "1";
    } else if (key == "base" || key == "delta") {
      const bool routed = key == "delta" && format >= 2;  // its shard, or "-"
      MKTREE_RETURN_IF_ERROR(want(routed ? 10 : 9));
      RevisionPart part;
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], &part.made_at));
      MKTREE_RETURN_IF_ERROR(p.File(w, 2, &part.store));
      MKTREE_RETURN_IF_ERROR(p.File(w, 5, &part.ids));
      MKTREE_RETURN_IF_ERROR(p.U64(w[8], &part.objects));
      if (part.store.name.empty()) return p.Bad(key + ": no store file");
      if (key == "base") {
        if (have_base) return p.Bad("two bases");
        have_base = true;
        m.base = part;
      } else {
        if (part.ids.name.empty()) return p.Bad("delta: no id file");
        if (routed && w[9] != "-") {
          uint64_t shard = 0;
          MKTREE_RETURN_IF_ERROR(p.U64(w[9], &shard));
          if (shard >= kMaxShards) return p.Bad("delta: shard " + w[9] + " out of range");
          part.shard = static_cast<uint32_t>(shard);
        }
        m.deltas.push_back(part);
      }
    } else if (key == "removal" || key == "touched") {
      MKTREE_RETURN_IF_ERROR(want(6));
      RevisionIdList l;
      MKTREE_RETURN_IF_ERROR(p.U64(w[1], &l.made_at));
      MKTREE_RETURN_IF_ERROR(p.File(w, 2, &l.file));
      MKTREE_RETURN_IF_ERROR(p.U64(w[5], &l.count));
      if (l.file.name.empty()) return p.Bad(key + ": no file");
      (key == "removal" ? m.removals : m.touched).push_back(l);
    } else {
      return p.Bad("unknown field '" + key + "'");
    }
  }
  if (line_no == 0) return Status::Corruption(what + ": empty revision file");
  if (!have_checksum)
    return Status::Corruption(what + " line " + std::to_string(line_no) +
                              ": truncated (no checksum line after it)");
  if (!have_base) return Status::Corruption(what + ": no base store");
  return m;
}

}  // namespace mktree
