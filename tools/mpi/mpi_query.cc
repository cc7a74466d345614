// mktree-mpi query: a query batch over a sharded store (docs/shards.md), each rank answering for its shards.
//   mpirun -n R mktree-mpi query MANIFEST --queries FILE [--exact] [--cold] [--threads N] [--cache-pages N]
// Rank r opens the shards the build wrote there (RankOfShard), each an ordinary store answering with its
// local ids, checked as the one-process Database checks it (engine/query/shard_open.h); every rank reads the
// query file and runs every query on its shards, in chunks; rank 0 gathers each chunk, maps nothing (the
// ranks send global ids), merges each query's ids in order, sums the shards' statistics and prints one JSON
// line a query, as `mktree query` does (query, kind, hits, and the counts).
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/core/guarded.h"
#include "engine/query/shard_open.h"
#include "engine/revision/change_folder.h"
#include "engine/shard/manifest.h"
#include "mktree/database.h"
#include "tools/mpi/mpi_cli.h"
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
};

constexpr char kUsage[] =
    "usage: mktree-mpi query MANIFEST --queries FILE [--exact] [--cold] [--threads N] [--cache-pages N]";

// -1 to go on, else the exit status.
int ParseQuery(int argc, char** argv, int rank, QueryArgs* a) {
  CLI::App app{"mktree-mpi query: a query batch over a sharded store, each rank its shards", "query"};
  std::vector<std::string> manifests;
  std::string threads, cache_pages;
  app.add_option("manifest", manifests, "The sharded store's manifest");
  app.add_option("--queries", a->queries, "File: one 'point X Y Z' or 'box X0 Y0 Z0 X1 Y1 Z1' a line");
  app.add_flag("--exact", a->exact, "Exact geometry instead of AABBs");
  app.add_flag("--cold", a->cold, "Empty the cache before each query");
  app.add_option("--threads", threads, "Each rank's query threads (0: one per core)");
  app.add_option("--cache-pages", cache_pages, "LRU page cache capacity in pages, over the shards");
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

Result<Manifest> ReadManifestAsBuilt(const std::string& manifest) {
  MKTREE_ASSIGN_OR_RETURN(StoreRevision at, OpenStoreRevision(manifest, std::nullopt));
  if (at.hold && at.hold->manifest().revision != 0)
    return Status::Unsupported(manifest + ": has taken changes (revision " +
                               std::to_string(at.hold->manifest().revision) +
                               "); mktree-mpi answers a sharded store as built: use mktree query or clash, "
                               "which answer every kept revision");
  return ReadManifest(manifest);
}

Result<OpenShard> OpenOneShard(const std::string& manifest, const Manifest& m, uint32_t s,
                               uint64_t cache_pages) {
  return Guarded(manifest, [&]() -> Result<OpenShard> {
    const uint64_t k = m.shards.size();
    OpenOptions shard_options;
    shard_options.cache_pages = (cache_pages + k - 1) / k;  // as the one-process Database
    MKTREE_ASSIGN_OR_RETURN(ManifestShard shard, OpenManifestShard(manifest, m, s, shard_options));
    return OpenShard{s, std::move(shard.db), std::move(shard.ids)};
  });
}

int RunQuery(int argc, char** argv, int rank, int ranks) {
  QueryArgs a;
  if (const int code = ParseQuery(argc, argv, rank, &a); code >= 0) return code;
  auto fail = [&](const std::string& message) {
    std::fprintf(stderr, "error: rank %d: %s\n", rank, message.c_str());
    return false;
  };
  bool ok = true;
  auto m = ReadManifestAsBuilt(a.manifest);
  if (!m.ok()) ok = fail(m.status().message());
  auto queries = tools::ReadQueryFile(a.queries);
  if (!queries.ok()) ok = fail(queries.status().message());
  if (!AllOk(ok)) return 1;
  for (Query& q : *queries) q.mode = a.exact ? QueryMode::kExact : QueryMode::kAabb;
  const uint32_t k = static_cast<uint32_t>(m->shards.size());
  std::vector<OpenShard> shards;
  for (uint32_t s = 0; s < k && ok; ++s) {
    if (RankOfShard(s, k, ranks) != rank) continue;
    auto o = OpenOneShard(a.manifest, *m, s, a.cache_pages);
    if (!o.ok())
      ok = fail(o.status().message());
    else
      shards.push_back(std::move(*o));
  }
  if (!AllOk(ok)) return 1;

  const size_t n = queries->size();
  uint64_t pages = 0, hits = 0;
  for (size_t first = 0; first < n; first += kChunk) {
    const size_t count = std::min(kChunk, n - first);
    const std::vector<Query> chunk(queries->begin() + first, queries->begin() + first + count);
    std::vector<std::vector<ObjectId>> answer(count);
    std::vector<QueryStats> stats(count);
    for (const OpenShard& s : shards) {
      if (!ok) break;
      Status st = s.db->RunBatchStreamed(chunk, {.threads = a.threads, .cold = a.cold},
                                         [&](uint64_t i, const QueryResult& r) {
                                           for (ObjectId local : r.hits) answer[i].push_back(s.ids[local]);
                                           stats[i] += r.stats;
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
      std::sort(ids.begin(), ids.end());  // shards hold disjoint ids
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
    std::fprintf(stderr, "%zu queries on %u shards over %d ranks: %llu hits, %llu pages read\n", n, k, ranks,
                 static_cast<unsigned long long>(hits), static_cast<unsigned long long>(pages));
  return 0;
}

}  // namespace mktree
