// CheckPlyFile (assimp_input_checks.h): the header's elements against the data that follows. assimp 5.2
// reads an element list that ends early as a shorter one (a file cut short loses faces silently) and a
// list property longer than its line as zeros; so every instance must be complete: in ASCII one line
// with exactly the declared values, in binary the exact bytes, and nothing may follow the last element.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "engine/scene/assimp_input_checks.h"
#include "engine/scene/text_lines.h"

namespace mktree {

namespace {

constexpr size_t kMaxHeaderBytes = 1 << 16;

// Bytes of a PLY scalar type, 0 if unknown.
int TypeBytes(std::string_view t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32") return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}
bool IsFloatType(std::string_view t) {
  return t == "float" || t == "float32" || t == "double" || t == "float64";
}

struct Property {
  bool list = false;
  std::string count_type, value_type;  // count_type for lists only
};
struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
};

bool IsInteger(std::string_view t) {
  size_t i = t.empty() || (t[0] != '-' && t[0] != '+') ? 0 : 1;
  if (i == t.size()) return false;
  for (; i < t.size(); ++i)
    if (t[i] < '0' || t[i] > '9') return false;
  return true;
}

bool ValidValue(std::string_view token, const std::string& type) {
  double v = 0;
  return IsFloatType(type) ? ParseDecimal(token, &v) : IsInteger(token);
}

Status CheckAscii(const std::string& path, uint64_t header_lines, const std::vector<Element>& elements) {
  // TextLines reads from the start: skip the header lines again.
  auto opened = TextLines::Open(path);
  if (!opened.ok()) return opened.status();
  TextLines& in = **opened;
  std::string_view line;
  for (uint64_t i = 0; i < header_lines; ++i) in.Next(&line);
  auto fail = [&](const std::string& what) { return Status::Corruption(in.Where() + what); };
  for (const Element& e : elements) {
    for (uint64_t k = 0; k < e.count; ++k) {
      if (!in.Next(&line)) {
        if (!in.status().ok()) return in.status();
        return Status::Corruption(path + ": unexpected end of file: element '" + e.name + "' has " +
                                  std::to_string(k) + " of its " + std::to_string(e.count) + " instances");
      }
      const std::vector<std::string_view> t = SplitTokens(line);
      size_t at = 0;
      for (const Property& p : e.properties) {
        uint32_t n = 1;
        if (p.list) {
          if (at >= t.size() || !ParseCount(t[at], &n))
            return fail("expected a list length in element '" + e.name + "'");
          ++at;
        }
        for (uint32_t j = 0; j < n; ++j, ++at) {
          if (at >= t.size())
            return fail("element '" + e.name + "' has fewer values on its line than its header declares");
          if (!ValidValue(t[at], p.value_type)) return fail(QuotedToken(t[at]) + " is not a " + p.value_type);
        }
      }
      if (at != t.size())
        return fail("element '" + e.name + "' has more values on its line than its header declares");
    }
  }
  while (in.Next(&line))
    if (!SplitTokens(line).empty()) return fail("data after the last element (do the element counts match?)");
  return in.status();
}

uint64_t ReadCount(const unsigned char* p, int bytes, bool big_endian) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= uint64_t{p[big_endian ? bytes - 1 - i : i]} << (8 * i);
  return v;
}

Status CheckBinary(const std::string& path, std::FILE* f, bool big_endian,
                   const std::vector<Element>& elements) {
  std::vector<unsigned char> buf(1 << 16);
  size_t at = 0, end = 0;
  auto need = [&](size_t n) {  // makes n bytes available at buf[at]
    if (end - at >= n) return true;
    std::memmove(buf.data(), buf.data() + at, end - at);
    end -= at;
    at = 0;
    end += std::fread(buf.data() + end, 1, buf.size() - end, f);
    return end - at >= n;
  };
  auto skip = [&](uint64_t n) {
    const uint64_t here = std::min<uint64_t>(n, end - at);
    at += here;
    n -= here;
    if (n == 0) return true;
    if (fseeko(f, static_cast<off_t>(n) - 1, SEEK_CUR) != 0) return false;
    unsigned char last = 0;
    return std::fread(&last, 1, 1, f) == 1;  // the skipped bytes exist
  };
  for (const Element& e : elements) {
    bool fixed = true;
    uint64_t fixed_bytes = 0;
    for (const Property& p : e.properties) {
      fixed &= !p.list;
      fixed_bytes += TypeBytes(p.value_type);
    }
    auto short_file = [&](uint64_t k) {
      return Status::Corruption(path + ": unexpected end of file: element '" + e.name + "' has " +
                                std::to_string(k) + " of its " + std::to_string(e.count) + " instances");
    };
    if (fixed) {
      if (e.count > 0 && !skip(e.count * fixed_bytes)) return short_file(0);
      continue;
    }
    for (uint64_t k = 0; k < e.count; ++k) {
      for (const Property& p : e.properties) {
        const int value = TypeBytes(p.value_type);
        uint64_t n = 1;
        if (p.list) {
          const int bytes = TypeBytes(p.count_type);
          if (!need(bytes)) return short_file(k);
          n = ReadCount(buf.data() + at, bytes, big_endian);
          at += bytes;
        }
        if (!skip(n * value)) return short_file(k);
      }
    }
  }
  if (at != end || std::fgetc(f) != EOF)
    return Status::Corruption(path + ": data after the last element (do the element counts match?)");
  return Status::Ok();
}

}  // namespace

Status CheckPlyFile(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) return Status::IOError(path + ": cannot open: " + std::strerror(errno));
  std::vector<Element> elements;
  std::string format;
  uint64_t line_no = 0, header_bytes = 0;
  for (bool done = false; !done;) {
    std::string line;
    for (int c; (c = std::fgetc(f.get())) != '\n';) {
      if (c == EOF || ++header_bytes > kMaxHeaderBytes)
        return Status::Corruption(path + ": PLY header without end_header");
      if (c != '\r') line.push_back(static_cast<char>(c));
    }
    ++line_no;
    const std::string where = path + ":" + std::to_string(line_no) + ": ";
    const std::vector<std::string_view> t = SplitTokens(line);
    if (line_no == 1) {
      if (t.size() != 1 || t[0] != "ply") return Status::Corruption(where + "not a PLY file (no 'ply' line)");
    } else if (t.empty() || t[0] == "comment" || t[0] == "obj_info") {
    } else if (t[0] == "format" && t.size() == 3) {
      format = t[1];
    } else if (t[0] == "element" && t.size() == 3) {
      uint32_t count = 0;
      if (!ParseCount(t[2], &count))
        return Status::Corruption(where + "element count " + QuotedToken(t[2]) + " is not in decimal digits");
      elements.push_back({std::string(t[1]), count, {}});
    } else if (t[0] == "property" && !elements.empty() && t.size() == 3 && TypeBytes(t[1]) > 0) {
      elements.back().properties.push_back({false, "", std::string(t[1])});
    } else if (t[0] == "property" && !elements.empty() && t.size() == 5 && t[1] == "list" &&
               TypeBytes(t[2]) > 0 && TypeBytes(t[3]) > 0 && !IsFloatType(t[2])) {
      elements.back().properties.push_back({true, std::string(t[2]), std::string(t[3])});
    } else if (t[0] == "end_header" && t.size() == 1) {
      done = true;
    } else {
      return Status::Corruption(where + "unsupported PLY header line '" + line + "'");
    }
  }
  if (format == "ascii") return CheckAscii(path, line_no, elements);
  if (format == "binary_little_endian" || format == "binary_big_endian")
    return CheckBinary(path, f.get(), format == "binary_big_endian", elements);
  return Status::Corruption(path + ": unknown PLY format '" + format + "'");
}

}  // namespace mktree
