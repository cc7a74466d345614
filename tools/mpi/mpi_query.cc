// mktree-mpi query: a query batch over a sharded store (docs/shards.md), each rank answering for its shards.
//   mpirun -n R mktree-mpi query MANIFEST --queries FILE [--exact] [--cold] [--threads N] [--cache-pages N]
//                                [--revision R]
// Rank r opens the parts it owns (tools/mpi/mpi_parts.h): the shards the build wrote there (RankOfShard),
// and of a store that has taken changes some of the revision's delta stores; each is an ordinary store
// answering with its local ids, checked as the one-process Database checks it. Every rank reads the query
// file and runs every query on its parts, in chunks, dropping the objects a part no longer answers for;
// rank 0 gathers each chunk, maps nothing (the ranks send global ids), merges each query's ids in order,
// sums the parts' statistics and prints one JSON line a query, as `mktree query` does (query, kind, hits,
// and the counts).
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "mktree/database.h"
#include "tools/mpi/mpi_cli.h"
#include "tools/mpi/mpi_parts.h"
#include "tools/mpi/mpi_util.h"
#include "tools/query_file.h"

namespace mktree {
namespace {

// Queries gathered on rank 0 at a time: bounds rank 0's memory by a chunk's answers, not the batch's.
constexpr size_t kChunk = 1024;

struct QueryArgs {
  std::string manifest, queries;
  bool exact = false, cold = false;
  unsigned threads = 1;         // as `mktree query`: ranks on one machine share its cores
  uint64_t cache_pages = 4096;  // over the manifest's shards, as `mktree query`
  std::optional<uint64_t> revision;
};

constexpr char kUsage[] =
    "usage: mktree-mpi query MANIFEST --queries FILE [--exact] [--cold] [--threads N] [--cache-pages N] "
    "[--revision R]";

// -1 to go on, else the exit status.
int ParseQuery(int argc, char** argv, int rank, QueryArgs* a) {
  CLI::App app{"mktree-mpi query: a query batch over a sharded store, each rank its shards", "query"};
  std::vector<std::string> manifests;
  std::string threads, cache_pages, revision;
  app.add_option("manifest", manifests, "The sharded store's manifest");
  app.add_option("--queries", a->queries, "File: one 'point X Y Z' or 'box X0 Y0 Z0 X1 Y1 Z1' a line");
  app.add_flag("--exact", a->exact, "Exact geometry instead of AABBs");
  app.add_flag("--cold", a->cold, "Empty the cache before each query");
  app.add_option("--threads", threads, "Each rank's query threads (0: one per core)");
  app.add_option("--cache-pages", cache_pages, "LRU page cache capacity in pages, over the shards");
  app.add_option("--revision", revision, "Answer this kept revision (default: the newest)");
  if (const int code = ParseMpiCommandLine(&app, argc, argv, rank); code >= 0) return code;
  if (manifests.size() > 1) return UsageError(rank, "one manifest only: " + manifests[1]);
  if (!threads.empty()) {
    const auto n = CountOption(threads, 65536);
    if (!n) return UsageError(rank, "--threads must be 0 to 65536");
    a->threads = static_cast<unsigned>(*n);
  }
  if (!cache_pages.empty()) {
    const auto n = CountOption(cache_pages, UINT64_MAX);
    if (!n) return UsageError(rank, "--cache-pages must be a whole number");
    a->cache_pages = *n;
  }
  if (!revision.empty()) {
    a->revision = CountOption(revision, UINT64_MAX);
    if (!a->revision) return UsageError(rank, "--revision must be a whole number");
  }
  if (manifests.empty() || a->queries.empty()) return UsageError(rank, kUsage);
  a->manifest = manifests[0];
  return -1;
}

constexpr int kStats = 11;
void PutStats(std::vector<uint8_t>* b, const QueryStats& s) {
  for (uint64_t v :
       {s.internal_nodes_visited, s.split_nodes_visited, s.leaves_visited, s.leaves_filtered, s.pages_touched,
        s.pages_read, s.cache_hits, s.bytes_read, s.candidates_tested, s.hits, s.leaves_with_hits})
    Put(b, v);
}
QueryStats GetStats(const std::vector<uint8_t>& b, size_t* at) {
  QueryStats s;
  for (uint64_t* v : {&s.internal_nodes_visited, &s.split_nodes_visited, &s.leaves_visited,
                      &s.leaves_filtered, &s.pages_touched, &s.pages_read, &s.cache_hits, &s.bytes_read,
                      &s.candidates_tested, &s.hits, &s.leaves_with_hits})
    *v = Get<uint64_t>(b, at);
  return s;
}

}  // namespace

int RunQuery(int argc, char** argv, int rank, int ranks) {
  QueryArgs a;
  if (const int code = ParseQuery(argc, argv, rank, &a); code >= 0) return code;
  auto fail = [&](const std::string& message) {
    std::fprintf(stderr, "error: rank %d: %s\n", rank, message.c_str());
    return false;
  };
  bool ok = true;
  auto r = HoldRankRevision(a.manifest, a.revision, rank);
  if (!r.ok() && !r.status().message().empty()) ok = fail(r.status().message());
  auto queries = tools::ReadQueryFile(a.queries);
  if (!queries.ok()) ok = fail(queries.status().message());
  if (!AllOk(ok) || !r.ok()) return 1;
  for (Query& q : *queries) q.mode = a.exact ? QueryMode::kExact : QueryMode::kAabb;
  // The parts this rank answers for: a delta left to another rank is not opened (its ids are read).
  std::vector<uint8_t> open(r->part_count(), 0);
  for (uint32_t i = 0; i < open.size(); ++i) open[i] = r->OwnerOf(i, ranks) == rank;
  auto parts = OpenRankStores(*r, open, a.cache_pages);
  if (!parts.ok()) ok = fail(parts.status().message());
  if (!AllOk(ok)) return 1;
  if (const Status live = CheckOwnedLive(*r, *parts, rank, ranks); !live.ok()) {
    if (!live.message().empty()) fail(live.message());
    return 1;
  }

  const size_t n = queries->size();
  uint64_t pages = 0, hits = 0;
  for (size_t first = 0; first < n; first += kChunk) {
    const size_t count = std::min(kChunk, n - first);
    const std::vector<Query> chunk(queries->begin() + first, queries->begin() + first + count);
    std::vector<std::vector<ObjectId>> answer(count);
    std::vector<QueryStats> stats(count);
    for (const RankStore& p : *parts) {
      if (!ok) break;
      Status st = p.db->RunBatchStreamed(chunk, {.threads = a.threads, .cold = a.cold},
                                         [&](uint64_t i, const QueryResult& result) {
                                           for (ObjectId local : result.hits)
                                             if (!p.Hidden(local)) answer[i].push_back(p.ids[local]);
                                           stats[i] += result.stats;
                                           return Status::Ok();
                                         });
      if (!st.ok()) ok = fail(st.message());
    }
    std::vector<uint8_t> mine;
    for (size_t i = 0; i < count; ++i) {
      Put<uint64_t>(&mine, answer[i].size());
      for (ObjectId id : answer[i]) Put(&mine, id);
      PutStats(&mine, stats[i]);
    }
    if (!AllOk(ok)) return 1;
    const auto all = Gather(mine, rank, ranks);
    if (rank != 0) continue;
    std::vector<size_t> at(all.size(), 0);
    for (size_t i = 0; i < count; ++i) {
      std::vector<ObjectId> ids;
      QueryStats total;
      for (size_t r = 0; r < all.size(); ++r) {
        const uint64_t c = Get<uint64_t>(all[r], &at[r]);
        for (uint64_t j = 0; j < c; ++j) ids.push_back(Get<ObjectId>(all[r], &at[r]));
        total += GetStats(all[r], &at[r]);
      }
      std::sort(ids.begin(), ids.end());  // an id is live in one part
      pages += total.pages_read;
      hits += ids.size();
      std::string line = "{\"query\": " + std::to_string(first + i) + ", \"kind\": \"" +
                         (chunk[i].kind == Query::Kind::kPoint ? "point" : "box") + "\", \"hits\": [";
      for (size_t j = 0; j < ids.size(); ++j) line += (j ? ", " : "") + std::to_string(ids[j]);
      line += "], \"pages_read\": " + std::to_string(total.pages_read) +
              ", \"pages_touched\": " + std::to_string(total.pages_touched) +
              ", \"leaves_visited\": " + std::to_string(total.leaves_visited) +
              ", \"bytes_read\": " + std::to_string(total.bytes_read) +
              ", \"candidates_tested\": " + std::to_string(total.candidates_tested) +
              ", \"hit_count\": " + std::to_string(ids.size()) + "}\n";
      std::fputs(line.c_str(), stdout);
    }
  }
  if (rank == 0)
    std::fprintf(stderr, "%zu queries on %u shards%s over %d ranks: %llu hits, %llu pages read\n", n,
                 r->shard_count(), r->DeltaNote().c_str(), ranks, static_cast<unsigned long long>(hits),
                 static_cast<unsigned long long>(pages));
  return 0;
}

}  // namespace mktree
