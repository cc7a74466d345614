// mktree query STORE (--point | --box | --queries FILE) [--exact] [--cache-pages N] [--cold] [--threads N]
// [--limit N | --any] [--count | --summary] [--names] [--revision R]: one JSON object per query per line,
// with the sorted hits (and with --names their names, in the same order) and every per-query statistic,
// written as each answer is complete (Database::RunBatchStreamed).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
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
  std::string point, box, file;
  bool has_point = false, has_box = false, has_file = false;  // given, even if empty
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
    if (!a_.has_file) return Status::Ok();
    if (a_.file.empty()) return Status::InvalidArgument("--queries: empty file name");
    MKTREE_ASSIGN_OR_RETURN(std::unique_ptr<QueryFileReader> r, QueryFileReader::Open(a_.file));
    Query q;
    while (true) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, r->Next(&q));
      if (!more) return Status::Ok();
    }
  }

  Result<bool> Next(Query* q) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, NextGiven(q));
    if (more) {
      q->mode = a_.exact ? QueryMode::kExact : QueryMode::kAabb;
      if (a_.any) {
        q->limit = 0;  // no id, but truncated says whether there is one
      } else if (a_.has_limit) {
        q->limit = a_.limit;
      }
    }
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

  const QueryArgs& a_;
  std::optional<Query> point_, box_;
  std::unique_ptr<QueryFileReader> file_;
};

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
    line = "{\"query\": " + std::to_string(i) + ", \"kind\": \"" + (point ? "point" : "box") + "\", ";
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
  auto* f =
      cmd->add_option("--queries", args->file, "File: one 'point X Y Z' or 'box X0 Y0 Z0 X1 Y1 Z1' a line");
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
  cmd->callback([run, args, p, b, f, count, any, limit, names, revision] {
    if (p->count() + b->count() + f->count() == 0)
      throw CLI::RequiredError("one of --point, --box or --queries");
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
