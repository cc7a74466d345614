// mktree query STORE (--point | --box | --queries FILE) [--exact] [--cache-pages N] [--cold]:
// one JSON object per query per line, with the sorted hits and every per-query statistic.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "mktree/database.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
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
};

// Per query kind ("point", "box 2" for boxes of largest side 2): disk accesses and answers.
struct KindSummary {
  std::vector<double> pages_read;
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
    std::vector<double> v = k.pages_read;
    std::sort(v.begin(), v.end());
    const double n = static_cast<double>(v.size());
    double sum = 0;
    for (double x : v) sum += x;
    auto pct = [&](double q) { return v[std::min(v.size() - 1, static_cast<size_t>(q * (n - 1) + 0.5))]; };
    std::printf("%-12s %8zu %10.2f %10.3f %8.0f %8.0f %10.3f %10.3f\n", name.c_str(), v.size(), k.hits / n,
                sum / n, pct(0.5), pct(0.99), k.floor / n, k.leaves / n);
  }
}

int RunQuery(const QueryArgs& a) {
  std::vector<Query> queries;
  if (a.has_point) {
    auto q = ParsePointArg(a.point);
    if (!q.ok()) return Fail(q.status().message());
    queries.push_back(*q);
  }
  if (a.has_box) {
    auto q = ParseBoxArg(a.box);
    if (!q.ok()) return Fail(q.status().message());
    queries.push_back(*q);
  }
  if (a.has_file) {
    if (a.file.empty()) return Fail("--queries: empty file name");
    auto qs = ReadQueryFile(a.file);
    if (!qs.ok()) return Fail(qs.status().message());
    queries.insert(queries.end(), qs->begin(), qs->end());
  }
  OpenOptions oo;
  oo.cache_pages = a.cache_pages;
  oo.verify_checksums = !a.no_verify;
  oo.direct_io = a.direct_io;
  auto db = Database::Open(a.store, oo);
  if (!db.ok()) return Fail(db.status().message());
  for (Query& q : queries) q.mode = a.exact ? QueryMode::kExact : QueryMode::kAabb;
  QueryResult r;
  std::string line;
  std::map<std::string, KindSummary> kinds;
  const double per_page = (*db)->objects_per_page();
  for (size_t i = 0; i < queries.size(); ++i) {
    if (a.cold) (*db)->ClearCache();
    Status st = (*db)->Run(queries[i], &r);
    if (!st.ok()) return Fail("query " + std::to_string(i) + ": " + st.message());
    if (a.summary) {
      KindSummary& k = kinds[KindOf(queries[i])];
      k.pages_read.push_back(static_cast<double>(r.stats.pages_read));
      k.hits += static_cast<double>(r.hits.size());
      k.floor += per_page > 0 ? std::ceil(static_cast<double>(r.hits.size()) / per_page) : 0;
      k.leaves += static_cast<double>(r.stats.leaves_visited);
      continue;
    }
    line = "{\"query\": " + std::to_string(i) + ", \"kind\": \"" +
           (queries[i].kind == Query::Kind::kPoint ? "point" : "box") + "\", \"hits\": [";
    for (size_t k = 0; k < r.hits.size(); ++k) {
      if (k) line += ", ";
      line += std::to_string(r.hits[k]);
    }
    line += "], " + r.stats.ToJsonMembers() + "}\n";
    std::fwrite(line.data(), 1, line.size(), stdout);
  }
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
  cmd->callback([run, args, p, b, f] {
    if (p->count() + b->count() + f->count() == 0)
      throw CLI::RequiredError("one of --point, --box or --queries");
    args->has_point = p->count() > 0;
    args->has_box = b->count() > 0;
    args->has_file = f->count() > 0;
    *run = [args] { return RunQuery(*args); };
  });
}

}  // namespace mktree::tools
