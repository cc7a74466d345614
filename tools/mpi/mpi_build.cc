// mktree-mpi: the sharded build (docs/shards.md) spread over MPI ranks (CMake option MKTREE_MPI).
//   mpirun -n R mktree-mpi SCENE... -o MANIFEST --shards K [--backend hdf5|pagefile] [--threads N]
//                          [--round-bytes B] [-q]
// The build's steps are engine/ingest/distributed_build.h's; here the command line, the ranks' exchange
// over MPI (tools/mpi/mpi_exchange.h) and rank 0's report.
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "engine/ingest/distributed_build.h"
#include "tools/mpi/mpi_cli.h"
#include "tools/mpi/mpi_exchange.h"
#include "tools/mpi/mpi_util.h"

namespace mktree {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

constexpr char kUsage[] =
    "usage: mktree-mpi SCENE... -o MANIFEST --shards K [--backend hdf5|pagefile] [--threads N] "
    "[--round-bytes B] [-q]";

// The command line into the build's options; -1 to go on, else the exit status.
int ParseBuild(int argc, char** argv, int rank, DistributedBuildOptions* o, bool* quiet) {
  CLI::App app{"mktree-mpi: the sharded build over MPI ranks (docs/shards.md)", "mktree-mpi"};
  std::string shards, threads, round_bytes, backend = "hdf5";
  app.add_option("scenes", o->inputs, "Scene files or tanker:N[:SEED]");
  app.add_option("-o,--output", o->manifest_path, "The sharded store's manifest to write");
  app.add_option("--shards", shards, "Shards K, 1 to 65536");
  app.add_option("--backend", backend, "hdf5 or pagefile");
  app.add_option("--threads", threads, "Each rank's build threads (0: one per core)");
  app.add_option("--round-bytes", round_bytes, "Bytes a rank sends in one exchange round at most");
  app.add_flag("-q,--quiet", *quiet, "No report");
  if (const int code = ParseMpiCommandLine(&app, argc, argv, rank); code >= 0) return code;
  if (!shards.empty()) {
    const auto k = CountOption(shards, 65536, true);
    if (!k) return UsageError(rank, "--shards must be 1 to 65536");
    o->shards = static_cast<uint32_t>(*k);
  }
  if (!threads.empty()) {
    const auto n = CountOption(threads, 65536);
    if (!n) return UsageError(rank, "--threads must be 0 to 65536");
    o->ingest.threads = static_cast<uint32_t>(*n);
    o->ingest.tuning.threads = static_cast<int>(*n);
  }
  if (!round_bytes.empty()) {  // tests: many exchange rounds on a small scene
    const auto n = CountOption(round_bytes, UINT64_MAX, true);
    if (!n) return UsageError(rank, "--round-bytes must be positive");
    o->round_bytes = *n;
  }
  if (backend != "hdf5" && backend != "pagefile")
    return UsageError(rank, "--backend must be hdf5 or pagefile");
  o->ingest.store.backend = backend == "pagefile" ? Backend::kPagedFile : Backend::kHdf5;
  if (o->inputs.empty() || o->manifest_path.empty() || o->shards == 0) return UsageError(rank, kUsage);
  return -1;
}

// Tests (tests/mpi/ranks.sh): MKTREE_MPI_TEST_KILL="RANK:POINT" kills that rank with SIGKILL at that point of
// the build, "exchanged" (the spills received) or "staged" (its first shard built under its staging names).
void KillForTest(int rank, const char* point) {
  const char* k = std::getenv("MKTREE_MPI_TEST_KILL");
  if (k && std::to_string(rank) + ":" + point == k) std::raise(SIGKILL);
}

// Bytes this process has read through read(2) and pread(2) (/proc/self/io rchar), or 0.
uint64_t BytesRead() {
  std::FILE* f = std::fopen("/proc/self/io", "r");
  if (!f) return 0;
  unsigned long long v = 0;
  const bool got = std::fscanf(f, "rchar: %llu", &v) == 1;
  std::fclose(f);
  return got ? v : 0;
}

// Rank 0's report of a finished build; every rank gives its bytes read.
void PrintReport(const DistributedBuildOptions& o, const DistributedBuildReport& r, RankExchange* x,
                 Clock::time_point start) {
  std::vector<uint8_t> mine(sizeof(uint64_t));
  const uint64_t my_reads = BytesRead();
  std::memcpy(mine.data(), &my_reads, sizeof my_reads);
  const std::vector<std::vector<uint8_t>> reads = x->Gather(mine);
  if (x->rank() != 0) return;
  const Manifest& m = r.manifest;
  std::printf("built %s: %llu objects in %u shards on %d ranks (%s)\n", o.manifest_path.c_str(),
              static_cast<unsigned long long>(m.objects), o.shards, x->ranks(), PartModeName(r.mode));
  std::printf(
      "exchange: %llu objects (%.1f %%) moved, %llu bytes, %.1f bytes an object of the scene, "
      "%.1f a moved object, %llu rounds\n",
      static_cast<unsigned long long>(r.moved_objects),
      100.0 * static_cast<double>(r.moved_objects) / static_cast<double>(m.objects),
      static_cast<unsigned long long>(r.moved_bytes),
      static_cast<double>(r.moved_bytes) / static_cast<double>(m.objects),
      r.moved_objects ? static_cast<double>(r.moved_bytes) / static_cast<double>(r.moved_objects) : 0.0,
      static_cast<unsigned long long>(r.rounds));
  std::printf("seconds: scan %.2f, exchange %.2f, shards %.2f, total %.2f\n", r.scan_seconds,
              r.exchange_seconds, r.shard_seconds, Since(start));
  std::printf("bytes read per rank (rchar: input, spills, store checks):");
  for (const std::vector<uint8_t>& b : reads) {
    uint64_t v = 0;
    std::memcpy(&v, b.data(), sizeof v);
    std::printf(" %llu", static_cast<unsigned long long>(v));
  }
  std::printf("\n");
}

}  // namespace

int RunBuild(int argc, char** argv, int rank, int ranks) {
  const auto start = Clock::now();
  DistributedBuildOptions o;
  bool quiet = false;
  if (const int code = ParseBuild(argc, argv, rank, &o, &quiet); code >= 0) return code;
  o.error = [rank](const std::string& m) { std::fprintf(stderr, "error: rank %d: %s\n", rank, m.c_str()); };
  o.warning = [](const std::string& m) { std::fprintf(stderr, "warning: %s\n", m.c_str()); };
  o.note = [quiet](const std::string& m) {
    if (!quiet) std::printf("note: %s\n", m.c_str());
  };
  o.checkpoint = [rank](const char* point) { KillForTest(rank, point); };
  MpiExchange exchange(rank, ranks);
  const auto report = BuildShardedOnRanks(o, &exchange);
  if (!report.ok()) return 1;
  if (!quiet) PrintReport(o, *report, &exchange, start);
  return 0;
}

}  // namespace mktree
