#include "tools/query_file.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <string_view>

#include "tools/path_checks.h"

namespace mktree::tools {

namespace {

// Splits on spaces/tabs or commas; false if a token is not a finite number.
bool ParseNumbers(std::string_view text, std::vector<double>* out, std::string* bad) {
  out->clear();
  size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t' || text[i] == ',' || text[i] == '\r')) ++i;
    if (i >= text.size()) break;
    size_t j = i;
    while (j < text.size() && text[j] != ' ' && text[j] != '\t' && text[j] != ',' && text[j] != '\r') ++j;
    std::string_view tok = text.substr(i, j - i);
    double v = 0;
    auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec != std::errc() || p != tok.data() + tok.size() || !std::isfinite(v)) {
      *bad = std::string(tok);
      return false;
    }
    out->push_back(v);
    i = j;
  }
  return true;
}

Result<Query> MakeQuery(const std::string& kind, const std::vector<double>& v, const std::string& where) {
  if (kind == "point") {
    if (v.size() != 3)
      return Status::InvalidArgument(where + ": a point needs 3 numbers, got " + std::to_string(v.size()));
    return Query::Point(Vec3d{v[0], v[1], v[2]});
  }
  if (v.size() != 6)
    return Status::InvalidArgument(where + ": a box needs 6 numbers, got " + std::to_string(v.size()));
  Box3d b;
  for (int i = 0; i < 3; ++i) {
    b.min[i] = v[i];
    b.max[i] = v[i + 3];
    if (b.min[i] > b.max[i])
      return Status::InvalidArgument(where + ": box min > max on axis " + std::to_string(i));
  }
  return Query::Box(b);
}

Result<DistanceQuery> MakeNearest(const std::vector<double>& v, const std::string& where) {
  if (v.size() != 4 && v.size() != 5)
    return Status::InvalidArgument(where + ": a nearest query needs X Y Z K [D], got " +
                                   std::to_string(v.size()) + " numbers");
  if (v[3] < 1 || v[3] != std::floor(v[3]) || v[3] > 1e18)
    return Status::InvalidArgument(where + ": nearest query: k must be a whole number >= 1");
  const double d = v.size() == 5 ? v[4] : std::numeric_limits<double>::infinity();
  if (d < 0) return Status::InvalidArgument(where + ": nearest query: max distance must be >= 0");
  return DistanceQuery::Nearest(Vec3d{v[0], v[1], v[2]}, static_cast<uint64_t>(v[3]), d);
}

Result<RayQuery> MakeRay(const std::vector<double>& v, const std::string& where, bool all_hits) {
  if (v.size() != 6 && v.size() != 7)
    return Status::InvalidArgument(where + ": a ray needs OX OY OZ DX DY DZ [L], got " +
                                   std::to_string(v.size()) + " numbers");
  if (v[3] == 0 && v[4] == 0 && v[5] == 0)
    return Status::InvalidArgument(where + ": ray query: zero direction");
  const double l = v.size() == 7 ? v[6] : std::numeric_limits<double>::infinity();
  if (l < 0) return Status::InvalidArgument(where + ": ray query: max length must be >= 0");
  return Query::Ray(Vec3d{v[0], v[1], v[2]}, Vec3d{v[3], v[4], v[5]}, l, all_hits);
}

}  // namespace

Result<std::unique_ptr<QueryFileReader>> QueryFileReader::Open(const std::string& path) {
  MKTREE_RETURN_IF_ERROR(CheckInputFile(path));  // a FIFO would block the read
  std::unique_ptr<QueryFileReader> r(new QueryFileReader(path));
  if (!r->in_) return Status::NotFound(path + ": cannot open query file");
  return r;
}

Result<bool> QueryFileReader::Next(Query* q) {
  FileQuery f;
  MKTREE_ASSIGN_OR_RETURN(const bool more, Next(&f));
  if (!more) return false;
  if (f.kind != FileQuery::Kind::kQuery)
    return Status::InvalidArgument(path_ + ":" + std::to_string(line_no_) +
                                   ": a nearest or ray query where only point and box queries are taken");
  *q = f.query;
  return true;
}

Result<bool> QueryFileReader::Next(FileQuery* q) {
  while (std::getline(in_, line_)) {
    ++line_no_;
    std::string& line = line_;
    if (auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    size_t s = line.find_first_not_of(" \t\r");
    if (s == std::string::npos) continue;
    const std::string where = path_ + ":" + std::to_string(line_no_);
    size_t e = line.find_first_of(" \t", s);
    const std::string kind = line.substr(s, e == std::string::npos ? std::string::npos : e - s);
    if (kind != "point" && kind != "box" && kind != "nearest" && kind != "ray")
      return Status::InvalidArgument(where + ": unknown query '" + kind +
                                     "' (expected point, box, nearest or ray)");
    std::string bad;
    if (!ParseNumbers(e == std::string::npos ? std::string_view() : std::string_view(line).substr(e),
                      &numbers_, &bad))
      return Status::InvalidArgument(where + ": '" + bad + "' is not a finite number");
    if (kind == "nearest") {
      q->kind = FileQuery::Kind::kNearest;
      MKTREE_ASSIGN_OR_RETURN(q->nearest, MakeNearest(numbers_, where));
    } else if (kind == "ray") {
      q->kind = FileQuery::Kind::kRay;
      MKTREE_ASSIGN_OR_RETURN(q->ray, MakeRay(numbers_, where, false));
    } else {
      q->kind = FileQuery::Kind::kQuery;
      MKTREE_ASSIGN_OR_RETURN(q->query, MakeQuery(kind, numbers_, where));
    }
    return true;
  }
  if (in_.bad()) return Status::IOError(path_ + ": read failed");
  return false;
}

Result<std::vector<Query>> ReadQueryFile(const std::string& path) {
  MKTREE_ASSIGN_OR_RETURN(std::unique_ptr<QueryFileReader> reader, QueryFileReader::Open(path));
  std::vector<Query> queries;
  Query q;
  while (true) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, reader->Next(&q));
    if (!more) return queries;
    queries.push_back(q);
  }
}

namespace {

// "X,Y,Z" on the command line: exactly comma-separated finite numbers (spaces around them allowed), so that
// an empty value or field ("", "1,,2,3") is an error rather than a different query.
Result<std::vector<double>> ParseArgNumbers(const std::string& text, const std::string& option) {
  std::vector<double> v;
  if (text.empty()) return Status::InvalidArgument(option + ": empty value");
  size_t start = 0;
  while (true) {
    const size_t comma = std::min(text.find(',', start), text.size());
    std::string_view field = std::string_view(text).substr(start, comma - start);
    while (!field.empty() && (field.front() == ' ' || field.front() == '\t')) field.remove_prefix(1);
    while (!field.empty() && (field.back() == ' ' || field.back() == '\t')) field.remove_suffix(1);
    double d = 0;
    auto [p, ec] = std::from_chars(field.data(), field.data() + field.size(), d);
    if (field.empty() || ec != std::errc() || p != field.data() + field.size() || !std::isfinite(d))
      return Status::InvalidArgument(option + ": '" + std::string(field) + "' in '" + text +
                                     "' is not a finite number");
    v.push_back(d);
    if (comma == text.size()) return v;
    start = comma + 1;
  }
}

}  // namespace

Result<Query> ParsePointArg(const std::string& text) {
  auto v = ParseArgNumbers(text, "--point");
  if (!v.ok()) return v.status();
  return MakeQuery("point", *v, "--point");
}

Result<Query> ParseBoxArg(const std::string& text) {
  auto v = ParseArgNumbers(text, "--box");
  if (!v.ok()) return v.status();
  return MakeQuery("box", *v, "--box");
}

Result<DistanceQuery> ParseNearestArg(const std::string& text, uint64_t k, double max_distance) {
  auto v = ParseArgNumbers(text, "--nearest");
  if (!v.ok()) return v.status();
  if (v->size() != 3)
    return Status::InvalidArgument("--nearest: a point needs 3 numbers, got " + std::to_string(v->size()));
  if (k < 1) return Status::InvalidArgument("--nearest: --k must be at least 1");
  if (std::isnan(max_distance) || max_distance < 0)
    return Status::InvalidArgument("--nearest: --max-distance must be >= 0");
  return DistanceQuery::Nearest(Vec3d{(*v)[0], (*v)[1], (*v)[2]}, k, max_distance);
}

Result<RayQuery> ParseRayArg(const std::string& text, double max_length, bool all_hits) {
  auto v = ParseArgNumbers(text, "--ray");
  if (!v.ok()) return v.status();
  if (v->size() != 6)
    return Status::InvalidArgument("--ray: a ray needs 6 numbers, got " + std::to_string(v->size()));
  if (std::isnan(max_length) || max_length < 0)
    return Status::InvalidArgument("--ray: --max-distance must be >= 0");
  MKTREE_ASSIGN_OR_RETURN(RayQuery q, MakeRay(*v, "--ray", all_hits));
  q.max_length = max_length;
  return q;
}

}  // namespace mktree::tools
