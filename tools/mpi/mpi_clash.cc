// mktree-mpi clash: the self-clash of a sharded store (docs/shards.md, "Clash on MPI ranks"), each rank
// finding the pairs of its shard group.
//   mpirun -n R mktree-mpi clash MANIFEST [--clearance C] [--touch-tolerance T] [--max-pairs N] [--no-touch]
//                                [--exclude-group SEP] [--threads N] [--summary]
// Rank r owns the shards the build wrote there (RankOfShard). A pair of objects in shards i <= j is found by
// the owner of i alone: the pairs inside its shards and, for j > i whose root box grown by C meets i's, the
// pairs between i and j (j's store opened read-only on r too, checked as the Database checks it). Each rank
// runs one RunMultiClash over the shards it opened, limited to those part pairs, and spills its pairs to an
// unnamed temporary file; when every rank has finished without error, rank 0 prints its own pairs, then
// rank 1's, ... (each rank's in its sweep's order), streamed in 1 MiB messages, applying the cap, and the
// summed statistics. The pairs are `mktree clash`'s lines on the one-process Database, in rank order.
#include <sys/resource.h>

#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "engine/clash/clash_engine.h"
#include "engine/clash/pair_rules.h"
#include "engine/query/store_database.h"
#include "tools/clash_lines.h"
#include "tools/cli_numbers.h"
#include "tools/mpi/mpi_util.h"

namespace mktree {
namespace {

static_assert(std::is_trivially_copyable_v<ClashPair> && std::is_trivially_copyable_v<ClashStats>);

constexpr size_t kMessageBytes = size_t{1} << 20;
constexpr int kPairsTag = 7;

struct ClashArgs {
  std::string manifest;
  ClashOptions o;
  bool summary = false;
};

bool ParseClash(int argc, char** argv, ClashArgs* a, std::string* err) {
  a->o.threads = 1;  // as `mktree-mpi query`: ranks on one machine share its cores
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const std::string v = i + 1 < argc ? argv[i + 1] : "";
    auto real = [&](double* out) {
      auto d = tools::ParseReal(v);
      ++i;
      if (!d || !std::isfinite(*d) || *d < 0) return *err = arg + " must be a finite number >= 0", false;
      *out = *d;
      return true;
    };
    auto count = [&](uint64_t* out, uint64_t most) {
      uint64_t n = 0;
      auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), n);
      ++i;
      if (v.empty() || ec != std::errc() || end != v.data() + v.size() || n > most)
        return *err = arg + " must be 0 to " + std::to_string(most), false;
      *out = n;
      return true;
    };
    if (arg == "--clearance") {
      if (!real(&a->o.clearance)) return false;
    } else if (arg == "--touch-tolerance") {
      if (!real(&a->o.touch_tolerance)) return false;
    } else if (arg == "--max-pairs") {
      if (!count(&a->o.max_pairs, std::numeric_limits<uint64_t>::max())) return false;
    } else if (arg == "--threads") {
      uint64_t n = 0;
      if (!count(&n, 65536)) return false;
      a->o.threads = static_cast<unsigned>(n);
    } else if (arg == "--exclude-group") {
      if (v.empty()) return *err = "--exclude-group needs a separator", false;
      a->o.exclude_group_separator = v;
      ++i;
    } else if (arg == "--no-touch") {
      a->o.report_touch = false;
    } else if (arg == "--summary") {
      a->summary = true;
    } else if (!arg.empty() && arg[0] == '-') {
      return *err = "unknown option " + arg, false;
    } else if (a->manifest.empty()) {
      a->manifest = arg;
    } else {
      return *err = "one manifest only: " + arg, false;
    }
  }
  if (a->manifest.empty())
    return *err =
               "usage: mktree-mpi clash MANIFEST [--clearance C] [--touch-tolerance T] [--max-pairs N] "
               "[--no-touch] [--exclude-group SEP] [--threads N] [--summary]",
           false;
  return true;
}

uint64_t PeakRss() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<uint64_t>(u.ru_maxrss) * 1024;
}

}  // namespace

int RunClash(int argc, char** argv, int rank, int ranks) {
  const auto start = std::chrono::steady_clock::now();
  ClashArgs a;
  std::string err;
  if (!ParseClash(argc, argv, &a, &err)) {
    if (rank == 0) std::fprintf(stderr, "error: %s\n", err.c_str());
    return 2;
  }
  auto fail = [&](const std::string& message) {
    std::fprintf(stderr, "error: rank %d: %s\n", rank, message.c_str());
    return false;
  };
  bool ok = true;
  auto m = ReadManifest(a.manifest);
  if (!m.ok()) ok = fail(m.status().message());
  if (!AllOk(ok)) return 1;
  const uint32_t k = static_cast<uint32_t>(m->shards.size());
  const double c = a.o.clearance;
  // The shards this rank reads: its own, and those above one of its own whose root box grown by C meets it.
  std::vector<uint8_t> open(k, 0);
  for (uint32_t i = 0; i < k; ++i) {
    if (RankOfShard(i, k, ranks) != rank) continue;
    open[i] = 1;
    for (uint32_t j = i + 1; j < k; ++j)
      if (clash::GrownMeet(clash::ToBox3d(m->shards[i].box), clash::ToBox3d(m->shards[j].box), c))
        open[j] = 1;
  }
  std::vector<OpenShard> shards;
  for (uint32_t s = 0; s < k && ok; ++s) {
    if (!open[s]) continue;
    auto o = OpenOneShard(a.manifest, *m, s);
    if (!o.ok())
      ok = fail(o.status().message());
    else
      shards.push_back(std::move(*o));
  }
  std::FILE* spill = std::tmpfile();
  if (ok && !spill) ok = fail("cannot make a temporary file for the pairs");
  ClashStats stats;
  if (ok) {
    std::vector<ClashPart> parts;
    for (const OpenShard& s : shards) parts.push_back(ClashPart{StoreClashView(*s.db), &s.ids});
    ClashOptions o = a.o;
    o.max_pairs = std::numeric_limits<uint64_t>::max();  // the cap is rank 0's, over every rank's pairs
    const Status st = RunMultiClash(
        parts, [&](uint32_t i, uint32_t) { return RankOfShard(shards[i].index, k, ranks) == rank; }, o,
        [&](const ClashPair& p) {
          if (std::fwrite(&p, sizeof p, 1, spill) != 1) ok = false;
        },
        &stats);
    if (!st.ok()) ok = fail(st.message());
    // The store's pages are counted by the shards' owners (a shard read for its pairs with a lower one
    // is read here too: its reads count, its size does not).
    stats.store_pages = 0;
    for (const OpenShard& s : shards)
      if (RankOfShard(s.index, k, ranks) == rank)
        for (const LeafInfo& l : StoreClashView(*s.db).reader.tree().leaves)
          stats.store_pages += l.page_count;
    if (ok && (std::fflush(spill) != 0 || std::ferror(spill)))
      ok = fail("cannot write the temporary pair file");
  }
  if (!AllOk(ok)) {
    if (spill) std::fclose(spill);
    return 1;
  }

  // Statistics: every rank's, summed on rank 0.
  std::vector<uint8_t> mine(sizeof(ClashStats) + sizeof(uint64_t));
  std::memcpy(mine.data(), &stats, sizeof stats);
  const uint64_t rss = PeakRss();
  std::memcpy(mine.data() + sizeof stats, &rss, sizeof rss);
  const auto all = Gather(mine, rank, ranks);

  // Pairs: rank 0's, then each other rank's in turn, in messages of at most kMessageBytes (an empty one
  // ends a rank's), so rank 0 holds one message of pairs at a time.
  std::rewind(spill);
  std::vector<uint8_t> buf(kMessageBytes / sizeof(ClashPair) * sizeof(ClashPair));
  uint64_t reported = 0, capped = 0;
  bool write_failed = false;
  auto deliver = [&](const uint8_t* bytes, size_t n) {
    for (size_t at = 0; at + sizeof(ClashPair) <= n; at += sizeof(ClashPair)) {
      ClashPair p;
      std::memcpy(&p, bytes + at, sizeof p);
      if (reported >= a.o.max_pairs) {
        ++capped;
        continue;
      }
      ++reported;
      const std::string line = tools::PairLine(p);
      if (std::fwrite(line.data(), 1, line.size(), stdout) != line.size()) write_failed = true;
    }
  };
  if (rank == 0) {
    for (size_t n; (n = std::fread(buf.data(), 1, buf.size(), spill)) > 0;) deliver(buf.data(), n);
    for (int r = 1; r < ranks; ++r) {
      for (;;) {
        MPI_Status status;
        MPI_Probe(r, kPairsTag, MPI_COMM_WORLD, &status);
        int n = 0;
        MPI_Get_count(&status, MPI_BYTE, &n);
        MPI_Recv(buf.data(), n, MPI_BYTE, r, kPairsTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (n == 0) break;
        deliver(buf.data(), static_cast<size_t>(n));
      }
    }
  } else {
    for (size_t n; (n = std::fread(buf.data(), 1, buf.size(), spill)) > 0;)
      MPI_Send(buf.data(), static_cast<int>(n), MPI_BYTE, 0, kPairsTag, MPI_COMM_WORLD);
    MPI_Send(buf.data(), 0, MPI_BYTE, 0, kPairsTag, MPI_COMM_WORLD);
  }
  std::fclose(spill);
  if (rank != 0) return 0;

  ClashStats total;
  uint64_t peak_rss = 0;
  for (const auto& b : all) {
    ClashStats s;
    std::memcpy(&s, b.data(), sizeof s);
    uint64_t r = 0;
    std::memcpy(&r, b.data() + sizeof s, sizeof r);
    AddClashStats(&total, s);
    peak_rss = std::max(peak_rss, r);
  }
  total.reported_pairs = reported;
  total.capped_pairs = capped;
  total.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (a.summary) {
    const std::string line = tools::SummaryLine(total, peak_rss);
    if (std::fwrite(line.data(), 1, line.size(), stdout) != line.size()) write_failed = true;
  }
  if (std::fflush(stdout) != 0 || write_failed) {
    std::fprintf(stderr, "error: cannot write the pairs to standard output\n");
    return 1;
  }
  std::fprintf(stderr, "clash of %u shards over %d ranks: %llu pairs, %llu pages read of %llu\n", k, ranks,
               static_cast<unsigned long long>(total.hard + total.touch + total.clearance),
               static_cast<unsigned long long>(total.pages_read),
               static_cast<unsigned long long>(total.store_pages));
  return 0;
}

}  // namespace mktree
