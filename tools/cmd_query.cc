// mktree query STORE (--point | --box | --nearest | --ray | --queries FILE) [--exact] [--cache-pages N]
// [--cold] [--threads N] [--limit N | --any] [--count | --summary] [--names] [--revision R]
// [--k K] [--max-distance D] [--all-hits]: one JSON object per query per line, with the sorted hits (and
// with --names their names, in the same order) and every per-query statistic, written as each answer is
// complete (Database::RunBatchStreamed). Nearest and ray queries (from --nearest, --ray or the file's
// nearest and ray lines) run one after the other on the calling thread, their hits in answer order with
// "distances" and "points", or "t", "points" and "normals".
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "mktree/database.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/json_text.h"
#include "tools/query_file.h"

namespace mktree::tools {

namespace {

struct QueryArgs {
  std::string store;
  std::string point, box, file, nearest, ray;
  bool has_point = false, has_box = false, has_file = false;  // given, even if empty
  bool has_nearest = false, has_ray = false;
  uint64_t k = 1;
  double max_distance = std::numeric_limits<double>::infinity();
  bool all_hits = false;
  bool exact = false;
  bool cold = false;
  uint64_t cache_pages = 4096;
  bool no_verify = false;
  bool direct_io = false;
  bool summary = false;
  bool count = false;
  bool any = false;
  bool has_limit = false;
  uint64_t limit = 0;
  uint64_t threads = 1;
  bool names = false;
  uint64_t revision = 0;
  bool has_revision = false;
};

// Per query kind ("point", "box 2" for boxes of largest side 2): disk accesses and answers. Pages read
// are kept as a histogram (value -> queries), so that memory does not grow with the number of queries.
struct KindSummary {
  std::map<uint64_t, uint64_t> pages_read;
  uint64_t queries = 0;
  double hits = 0, floor = 0, leaves = 0, touched = 0;
};

std::string KindOf(const Query& q) {
  if (q.kind == Query::Kind::kPoint) return "point";
  double side = 0;
  for (int i = 0; i < 3; ++i) side = std::max(side, q.box.max[i] - q.box.min[i]);
  char buf[48];
  std::snprintf(buf, sizeof buf, "box %.3g", side);
  return buf;
}

void PrintSummary(const std::map<std::string, KindSummary>& kinds, double per_page, bool cold) {
  std::printf("disk accesses per query (%s cache; B = %.2f objects per page; floor = ceil(hits / B))\n",
              cold ? "cold" : "warm", per_page);
  std::printf("%-12s %8s %10s %10s %8s %8s %10s %10s\n", "kind", "queries", "mean hits", "pages read", "p50",
              "p99", "floor", "leaves");
  for (const auto& [name, k] : kinds) {
    const double n = static_cast<double>(k.queries);
    double sum = 0;
    for (const auto& [pages, count] : k.pages_read)
      sum += static_cast<double>(pages) * static_cast<double>(count);
    // The value at rank round(q * (n - 1)) of the sorted pages read.
    auto pct = [&](double q) {
      const uint64_t rank = std::min<uint64_t>(k.queries - 1, static_cast<uint64_t>(q * (n - 1) + 0.5));
      uint64_t below = 0;
      for (const auto& [pages, count] : k.pages_read) {
        below += count;
        if (rank < below) return static_cast<double>(pages);
      }
      return 0.0;
    };
    std::printf("%-12s %8llu %10.2f %10.3f %8.0f %8.0f %10.3f %10.3f\n", name.c_str(),
                static_cast<unsigned long long>(k.queries), k.hits / n, sum / n, pct(0.5), pct(0.99),
                k.floor / n, k.leaves / n);
  }
}

// The queries of the command line, in order: --point, --box, then the lines of --queries.
class CommandQueries {
 public:
  explicit CommandQueries(const QueryArgs& a) : a_(a) {}

  // Parses the arguments and reads the whole file once, keeping nothing, so that a bad line is refused
  // before the store is opened or anything is printed.
  Status Check() {
    if (a_.has_point) {
      MKTREE_ASSIGN_OR_RETURN(point_, ParsePointArg(a_.point));
    }
    if (a_.has_box) {
      MKTREE_ASSIGN_OR_RETURN(box_, ParseBoxArg(a_.box));
    }
    if (a_.has_nearest) {
      MKTREE_ASSIGN_OR_RETURN(nearest_, ParseNearestArg(a_.nearest, a_.k, a_.max_distance));
    }
    if (a_.has_ray) {
      MKTREE_ASSIGN_OR_RETURN(ray_, ParseRayArg(a_.ray, a_.max_distance, a_.all_hits));
    }
    geometric_ = a_.has_nearest || a_.has_ray;
    if (!a_.has_file) return Status::Ok();
    if (a_.file.empty()) return Status::InvalidArgument("--queries: empty file name");
    MKTREE_ASSIGN_OR_RETURN(std::unique_ptr<QueryFileReader> r, QueryFileReader::Open(a_.file));
    FileQuery q;
    while (true) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, r->Next(&q));
      if (!more) return Status::Ok();
      geometric_ = geometric_ || q.kind != FileQuery::Kind::kQuery;
    }
  }

  // Whether nearest or ray queries are among them (they then all run one at a time: NextFile).
  bool geometric() const { return geometric_; }

  // Every query in order: --point, --box, --nearest, --ray, then the file's lines.
  Result<bool> NextFile(FileQuery* q) {
    if (point_ || box_) {
      q->kind = FileQuery::Kind::kQuery;
      return Next(&q->query);
    }
    if (nearest_) {
      q->kind = FileQuery::Kind::kNearest;
      q->nearest = *std::exchange(nearest_, std::nullopt);
      return true;
    }
    if (ray_) {
      q->kind = FileQuery::Kind::kRay;
      q->ray = *std::exchange(ray_, std::nullopt);
      return true;
    }
    if (!a_.has_file) return false;
    if (!file_) {
      MKTREE_ASSIGN_OR_RETURN(file_, QueryFileReader::Open(a_.file));
    }
    MKTREE_ASSIGN_OR_RETURN(const bool more, file_->Next(q));
    if (more && q->kind == FileQuery::Kind::kQuery) Adjust(&q->query);
    if (more && q->kind == FileQuery::Kind::kRay) q->ray.all_hits = a_.all_hits;
    return more;
  }

  Result<bool> Next(Query* q) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, NextGiven(q));
    if (more) Adjust(q);
    return more;
  }

 private:
  Result<bool> NextGiven(Query* q) {
    if (point_) {
      *q = *std::exchange(point_, std::nullopt);
      return true;
    }
    if (box_) {
      *q = *std::exchange(box_, std::nullopt);
      return true;
    }
    if (!a_.has_file) return false;
    if (!file_) {
      MKTREE_ASSIGN_OR_RETURN(file_, QueryFileReader::Open(a_.file));
    }
    return file_->Next(q);
  }

  void Adjust(Query* q) const {
    q->mode = a_.exact ? QueryMode::kExact : QueryMode::kAabb;
    if (a_.any) {
      q->limit = 0;  // no id, but truncated says whether there is one
    } else if (a_.has_limit) {
      q->limit = a_.limit;
    }
  }

  const QueryArgs& a_;
  std::optional<Query> point_, box_;
  std::optional<DistanceQuery> nearest_;
  std::optional<RayQuery> ray_;
  bool geometric_ = false;
  std::unique_ptr<QueryFileReader> file_;
};

// The JSON line of a point or box query's answer.
Result<std::string> AnswerLine(uint64_t i, bool point, const QueryResult& r, const QueryArgs& a,
                               const Database* names_db) {
  std::string line =
      "{\"query\": " + std::to_string(i) + ", \"kind\": \"" + (point ? "point" : "box") + "\", ";
  if (a.any) {
    line += std::string("\"any\": ") + (r.truncated ? "true" : "false") + ", ";
  } else if (!a.count) {
    line += "\"hits\": [";
    for (size_t k = 0; k < r.hits.size(); ++k) {
      if (k) line += ", ";
      line += std::to_string(r.hits[k]);
    }
    line += "], ";
    if (names_db) {
      line += "\"names\": [";
      for (size_t k = 0; k < r.hits.size(); ++k) {
        MKTREE_ASSIGN_OR_RETURN(const std::string name, names_db->ObjectName(r.hits[k]));
        if (k) line += ", ";
        line += "\"" + JsonText(name) + "\"";
      }
      line += "], ";
    }
  }
  line += r.stats.ToJsonMembers();
  if (a.has_limit) line += std::string(", \"truncated\": ") + (r.truncated ? "true" : "false");
  line += "}\n";
  return line;
}

// "[x, y, z]" with every digit a double needs.
std::string JsonVec(const Vec3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "[%.17g, %.17g, %.17g]", v.x, v.y, v.z);
  return buf;
}

std::string JsonReal(double d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", d);
  return buf;
}

// The names of `ids` as a JSON member, or nothing without --names.
Result<std::string> NamesMember(const std::vector<ObjectId>& ids, const Database* names_db) {
  if (!names_db) return std::string();
  std::string out = "\"names\": [";
  for (size_t k = 0; k < ids.size(); ++k) {
    MKTREE_ASSIGN_OR_RETURN(const std::string name, names_db->ObjectName(ids[k]));
    out += (k ? ", \"" : "\"") + JsonText(name) + "\"";
  }
  return out + "], ";
}

// One JSON member of a list: "key": [f(0), f(1), ...].
template <typename F>
std::string ListMember(const char* key, size_t n, F&& f) {
  std::string out = std::string("\"") + key + "\": [";
  for (size_t k = 0; k < n; ++k) out += (k ? ", " : "") + f(k);
  return out + "], ";
}

// The JSON line of a nearest or ray query's answer (hits in answer order).
Result<std::string> GeometricLine(uint64_t i, const FileQuery& q, const Database& db,
                                  const Database* names_db) {
  std::string line = "{\"query\": " + std::to_string(i) + ", ";
  QueryStats s;
  std::vector<ObjectId> ids;
  if (q.kind == FileQuery::Kind::kNearest) {
    std::vector<NearestHit> hits;
    MKTREE_RETURN_IF_ERROR(db.Nearest(q.nearest, &hits, &s));
    for (const NearestHit& h : hits) ids.push_back(h.id);
    line += "\"kind\": \"nearest\", ";
    line += ListMember("hits", ids.size(), [&](size_t k) { return std::to_string(ids[k]); });
    MKTREE_ASSIGN_OR_RETURN(const std::string names, NamesMember(ids, names_db));
    line += names;
    line += ListMember("distances", hits.size(), [&](size_t k) { return JsonReal(hits[k].distance); });
    line += ListMember("points", hits.size(), [&](size_t k) { return JsonVec(hits[k].point); });
  } else {
    std::vector<RayHit> hits;
    MKTREE_RETURN_IF_ERROR(db.Ray(q.ray, &hits, &s));
    for (const RayHit& h : hits) ids.push_back(h.id);
    line += "\"kind\": \"ray\", ";
    line += ListMember("hits", ids.size(), [&](size_t k) { return std::to_string(ids[k]); });
    MKTREE_ASSIGN_OR_RETURN(const std::string names, NamesMember(ids, names_db));
    line += names;
    line += ListMember("t", hits.size(), [&](size_t k) { return JsonReal(hits[k].t); });
    line += ListMember("points", hits.size(), [&](size_t k) { return JsonVec(hits[k].point); });
    line += ListMember("normals", hits.size(), [&](size_t k) { return JsonVec(hits[k].normal); });
  }
  return line + s.ToJsonMembers() + "}\n";
}

// Queries that include nearest or ray ones: one at a time, in order, on this thread.
int RunOneByOne(const QueryArgs& a, CommandQueries& queries, const Database& db, Database& cache_owner,
                const Database* names_db) {
  FileQuery q;
  std::string line;
  for (uint64_t i = 0;; ++i) {
    Result<bool> more = queries.NextFile(&q);
    if (!more.ok()) return Fail(more.status().message());
    if (!*more) break;
    if (a.cold) cache_owner.ClearCache();
    Result<std::string> text = Status::Ok();
    if (q.kind == FileQuery::Kind::kQuery) {
      QueryResult r;
      const Status st = db.Run(q.query, &r);
      text = st.ok() ? AnswerLine(i, q.query.kind == Query::Kind::kPoint, r, a, names_db)
                     : Result<std::string>(st);
    } else {
      text = GeometricLine(i, q, db, names_db);
    }
    if (!text.ok()) return Fail("query " + std::to_string(i) + ": " + text.status().message());
    if (std::fwrite(text->data(), 1, text->size(), stdout) != text->size())
      return Fail("cannot write to standard output");
  }
  return std::fflush(stdout) == 0 ? 0 : Fail("cannot write to standard output");
}

int RunQuery(const QueryArgs& a) {
  CommandQueries queries(a);
  if (Status st = queries.Check(); !st.ok()) return Fail(st.message());
  OpenOptions oo;
  oo.cache_pages = a.cache_pages;
  oo.verify_checksums = !a.no_verify;
  oo.direct_io = a.direct_io;
  if (a.has_revision) oo.revision = a.revision;
  auto db = Database::Open(a.store, oo);
  if (!db.ok()) return Fail(db.status().message());
  std::unique_ptr<Database> names_db;
  if (a.names) {
    auto n = OpenNamesHandle(a.store, oo);
    if (!n.ok()) return Fail(n.status().message());
    names_db = std::move(*n);
  }
  if (queries.geometric()) {
    if (a.any || a.has_limit || a.count || a.summary)
      return Fail("--any, --limit, --count and --summary apply to point and box queries only: " + a.file +
                  " holds nearest or ray queries");
    return RunOneByOne(a, queries, **db, **db, names_db.get());
  }
  BatchOptions bo;
  bo.threads = static_cast<unsigned>(a.threads);
  bo.cold = a.cold;
  bo.ids = !(a.summary || a.count || a.any);  // counted answers are streamed, never collected
  std::string line;
  std::map<std::string, KindSummary> kinds;
  const double per_page = (*db)->objects_per_page();
  // The kind of each query, as RunBatchStreamed's results carry no query: delivery is in query order, so
  // a FIFO of the kinds of the queries read but not yet delivered (at most the window).
  std::deque<std::pair<bool, std::string>> pending;  // (is a point, summary kind)
  auto source = [&](Query* q) -> Result<bool> {
    MKTREE_ASSIGN_OR_RETURN(const bool more, queries.Next(q));
    if (more) pending.emplace_back(q->kind == Query::Kind::kPoint, a.summary ? KindOf(*q) : std::string());
    return more;
  };
  auto deliver = [&](uint64_t i, const QueryResult& r) -> Status {
    const auto [point, kind] = std::move(pending.front());
    pending.pop_front();
    if (a.summary) {
      KindSummary& k = kinds[kind];
      ++k.pages_read[r.stats.pages_read];
      ++k.queries;
      k.hits += static_cast<double>(r.stats.hits);
      k.floor += per_page > 0 ? std::ceil(static_cast<double>(r.stats.hits) / per_page) : 0;
      k.leaves += static_cast<double>(r.stats.leaves_visited);
      return Status::Ok();
    }
    MKTREE_ASSIGN_OR_RETURN(line, AnswerLine(i, point, r, a, names_db.get()));
    if (std::fwrite(line.data(), 1, line.size(), stdout) != line.size())
      return Status::IOError("cannot write to standard output");
    return Status::Ok();
  };
  if (Status st = (*db)->RunBatchStreamed(source, bo, deliver); !st.ok()) return Fail(st.message());
  if (a.summary) PrintSummary(kinds, per_page, a.cold);
  return std::fflush(stdout) == 0 ? 0 : Fail("cannot write to standard output");
}

}  // namespace

void RegisterQuery(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<QueryArgs>();
  CLI::App* cmd = app.add_subcommand("query", "Run point and box queries; prints one JSON line per query");
  cmd->add_option("store", args->store, "Store file")->required();
  auto* p = cmd->add_option("--point", args->point, "X,Y,Z");
  auto* b = cmd->add_option("--box", args->box, "X0,Y0,Z0,X1,Y1,Z1");
  auto* f = cmd->add_option("--queries", args->file,
                            "File: one 'point X Y Z', 'box X0 Y0 Z0 X1 Y1 Z1', 'nearest X Y Z K' or "
                            "'ray OX OY OZ DX DY DZ' a line");
  auto* nearest = cmd->add_option("--nearest", args->nearest, "X,Y,Z: the K nearest objects (--k)");
  auto* ray = cmd->add_option("--ray", args->ray, "OX,OY,OZ,DX,DY,DZ: the first object the ray hits");
  auto* k = AddNumberOption(cmd, "--k", &args->k, "Objects a nearest query answers (default 1)");
  auto* max_distance = AddNumberOption(cmd, "--max-distance", &args->max_distance,
                                       "Farthest a nearest answer, or a ray hit, may be (default: no limit)");
  auto* all_hits = cmd->add_flag("--all-hits", args->all_hits, "Every object a ray hits, in order");
  cmd->add_flag("--exact", args->exact, "Exact geometry instead of AABBs");
  AddNumberOption(cmd, "--cache-pages", &args->cache_pages, "LRU page cache capacity in pages");
  cmd->add_flag("--cold", args->cold, "Empty the cache before each query");
  cmd->add_flag("--no-verify", args->no_verify, "Skip page checksum verification");
  cmd->add_flag("--summary", args->summary, "Instead of JSON lines, a table of disk accesses per query kind");
  cmd->add_flag("--direct-io", args->direct_io, "Bypass the OS page cache (paged-file backend)");
  auto* count = cmd->add_flag("--count", args->count, "Print each answer's statistics without its ids");
  auto* any = cmd->add_flag("--any", args->any, "Print whether anything answers; stops at the first hit");
  auto* limit = AddNumberOption(cmd, "--limit", &args->limit, "At most N ids per answer (the first read)");
  AddNumberOption(cmd, "--threads", &args->threads, "Threads running the queries (answers stay in order)");
  auto* names =
      cmd->add_flag("--names", args->names, "Print each hit's name (\"names\", in the order of \"hits\")");
  auto* revision =
      AddNumberOption(cmd, "--revision", &args->revision, "Answer this kept revision (default: the newest)");
  cmd->callback(
      [run, args, p, b, f, count, any, limit, names, revision, nearest, ray, k, max_distance, all_hits] {
        if (p->count() + b->count() + f->count() + nearest->count() + ray->count() == 0)
          throw CLI::RequiredError("one of --point, --box, --nearest, --ray or --queries");
        if (k->count() && !nearest->count())
          throw CLI::ValidationError("--k", "needs --nearest (a file's nearest lines carry their own k)");
        if (max_distance->count() && !nearest->count() && !ray->count())
          throw CLI::ValidationError("--max-distance", "needs --nearest or --ray");
        if (all_hits->count() && !ray->count() && !f->count())
          throw CLI::ValidationError("--all-hits", "needs --ray or --queries");
        if ((nearest->count() || ray->count()) &&
            (any->count() || limit->count() || count->count() || args->summary))
          throw CLI::ValidationError("--nearest/--ray", "exclude --any, --limit, --count and --summary");
        args->has_nearest = nearest->count() > 0;
        args->has_ray = ray->count() > 0;
        if (any->count() && (limit->count() || count->count() || args->summary))
          throw CLI::ValidationError("--any", "excludes --limit, --count and --summary");
        if (count->count() && args->summary) throw CLI::ValidationError("--count", "excludes --summary");
        if (names->count() && (any->count() || count->count() || args->summary))
          throw CLI::ValidationError("--names", "needs the ids: excludes --any, --count and --summary");
        if (args->threads == 0 || args->threads > 1024)
          throw CLI::ValidationError("--threads", "must be from 1 to 1024");
        args->has_limit = limit->count() > 0;
        args->has_revision = revision->count() > 0;
        args->has_point = p->count() > 0;
        args->has_box = b->count() > 0;
        args->has_file = f->count() > 0;
        *run = [args] { return RunQuery(*args); };
      });
}

}  // namespace mktree::tools
