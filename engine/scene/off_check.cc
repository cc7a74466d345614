// CheckOffFile (assimp_input_checks.h): the OFF files assimp 5.2's reader reads as written. Its reader
// takes the header and counts as tokens (comment lines skipped), then exactly NV and NF lines with a
// fixed 4096-byte buffer (blank lines skipped, comment lines not), and ignores what follows.
#include <cmath>
#include <string>
#include <vector>

#include "engine/scene/assimp_input_checks.h"
#include "engine/scene/text_lines.h"

namespace mktree {

namespace {

constexpr size_t kAssimpLineBytes = 4095;  // GetNextLine's buffer holds 4096 bytes with the NUL
constexpr uint32_t kMaxFaceVertices = 9;   // assimp drops larger faces

bool IsCommentOrBlank(std::string_view line) {
  const size_t s = line.find_first_not_of(" \t");
  return s == std::string_view::npos || line[s] == '#';
}

// Tokens before a '#' that starts a token (what assimp's token readers stop at).
std::vector<std::string_view> TokensBeforeComment(std::string_view line) {
  std::vector<std::string_view> t = SplitTokens(line);
  for (size_t i = 0; i < t.size(); ++i) {
    if (const size_t hash = t[i].find('#'); hash != std::string_view::npos) {
      t[i] = t[i].substr(0, hash);
      t.resize(t[i].empty() ? i : i + 1);
      break;
    }
  }
  return t;
}

// The keyword [ST][C][N][4][n]OFF; sets *homogeneous for 4OFF. False if it is not one.
bool ParseKeyword(std::string_view k, bool* homogeneous, bool* dimension) {
  if (k.substr(0, 2) == "ST") k.remove_prefix(2);
  if (!k.empty() && k[0] == 'C') k.remove_prefix(1);
  if (!k.empty() && k[0] == 'N') k.remove_prefix(1);
  *homogeneous = !k.empty() && k[0] == '4';
  if (*homogeneous) k.remove_prefix(1);
  *dimension = !k.empty() && k[0] == 'n';
  if (*dimension) k.remove_prefix(1);
  return k == "OFF";
}

}  // namespace

Status CheckOffFile(const std::string& path) {
  auto opened = TextLines::Open(path);
  if (!opened.ok()) return opened.status();
  TextLines& in = **opened;
  auto fail = [&](const std::string& what) { return Status::Corruption(in.Where() + what); };
  std::string_view line;
  auto next_meaningful = [&]() {
    while (in.Next(&line))
      if (!IsCommentOrBlank(line)) return true;
    return false;
  };
  auto end_of_file = [&](const std::string& what) {
    if (!in.status().ok()) return in.status();
    return Status::Corruption(path + ":" + std::to_string(in.line_no()) +
                              ": unexpected end of file: " + what);
  };

  if (!next_meaningful()) return end_of_file("no OFF header");
  std::vector<std::string_view> t = TokensBeforeComment(line);
  bool homogeneous = false, dimension = false;
  if (!ParseKeyword(t[0], &homogeneous, &dimension))
    return fail("expected the OFF keyword (OFF, COFF, NOFF, STOFF, 4OFF, ...), got " + QuotedToken(t[0]));
  if (dimension) return fail("nOFF (vertices of another dimension than 3) is not supported");
  t.erase(t.begin());
  if (t.empty()) {
    if (!next_meaningful()) return end_of_file("no vertex, face and edge counts");
    t = TokensBeforeComment(line);
  }
  uint32_t vertices = 0, faces = 0, edges = 0;
  if (t.size() != 3 || !ParseCount(t[0], &vertices) || !ParseCount(t[1], &faces) || !ParseCount(t[2], &edges))
    return fail("expected the counts 'VERTICES FACES EDGES' on one line (decimal, not negative)");
  if (vertices == 0) return fail("no vertices");
  if (faces == 0) return fail("no faces");

  const size_t coords = homogeneous ? 4 : 3;
  // The next line of the vertex or face list: assimp skips empty lines there, and before the first vertex
  // also lines of spaces and comment lines.
  auto next_data_line = [&](bool first) {
    while (in.Next(&line))
      if (!line.empty() && !(first && IsCommentOrBlank(line))) return true;
    return false;
  };
  for (uint32_t v = 0; v < vertices; ++v) {
    if (!next_data_line(v == 0))
      return end_of_file(std::to_string(vertices - v) + " of " + std::to_string(vertices) +
                         " vertices missing");
    if (line.size() > kAssimpLineBytes) return fail("line longer than 4095 bytes");
    if (IsCommentOrBlank(line)) return fail("a comment or blank-looking line inside the vertex list");
    t = TokensBeforeComment(line);
    if (t.size() < coords) return fail("a vertex needs " + std::to_string(coords) + " numbers");
    for (size_t i = 0; i < coords; ++i) {
      double x = 0;
      if (!ParseDecimal(t[i], &x)) return fail(QuotedToken(t[i]) + " is not a number");
      if (!std::isfinite(x) || (i == 3 && x == 0)) return fail("non-finite coordinate " + QuotedToken(t[i]));
    }
  }
  for (uint32_t f = 0; f < faces; ++f) {
    if (!next_data_line(false))
      return end_of_file(std::to_string(faces - f) + " of " + std::to_string(faces) + " faces missing");
    if (line.size() > kAssimpLineBytes) return fail("line longer than 4095 bytes");
    if (IsCommentOrBlank(line)) return fail("a comment or blank-looking line inside the face list");
    t = TokensBeforeComment(line);
    uint32_t n = 0;
    if (t.empty() || !ParseCount(t[0], &n)) return fail("expected a face 'N V1 ... VN'");
    if (n == 0 || n > kMaxFaceVertices)
      return fail("a face of " + std::to_string(n) + " vertices (from 1 to " +
                  std::to_string(kMaxFaceVertices) + ")");
    if (t.size() < 1 + n)
      return fail("a face of " + std::to_string(n) + " vertices lists " + std::to_string(t.size() - 1) +
                  " indices");
    for (uint32_t i = 1; i <= n; ++i) {
      uint32_t index = 0;
      if (!ParseCount(t[i], &index))
        return fail("vertex index " + QuotedToken(t[i]) + " is not a decimal number");
      if (index >= vertices)
        return fail("vertex index " + std::to_string(index) + " out of range (" + std::to_string(vertices) +
                    " vertices)");
    }
  }
  while (in.Next(&line))
    if (!IsCommentOrBlank(line)) return fail("text after the last face (do the counts match the file?)");
  return in.status();
}

}  // namespace mktree
