// changes_bench: commit latency of change batches on the synthetic tanker (issue 38, "Performance"), mktree
// against its peers in one run.
//
// Workload (bench/change_workload.h; tanker seed `--seed`, change seed `--change-seed`): the tanker of N
// objects, then batches of each size in `--sizes` (default 1, 100, 10000, 100000), `--batches` of each
// (default 20, 20, 5, 2), applied in that order to the same evolving set; a third of each batch adds moved
// copies of tanker objects (new ids), a third removes live ids, a third replaces a live id's geometry by a
// moved copy. Every engine starts from the same N objects and applies the same batches.
// Engines (`--engines`, comma-separated, run one after another):
//   sqlite          SQLite R*Tree, WAL, synchronous=FULL, one transaction per batch
//   sqlite-normal   the same with synchronous=NORMAL
//   spatialindex    libspatialindex R*-tree, disk storage manager, flush + fdatasync per batch
//   bgi             Boost.Geometry rtree in RAM
//   mktree          mktree::ChangeWriter on a paged-file store, 12 KiB pages
//   rebuild         mktree: a full BuildFromObjects of the live set after the whole script (the "at least
//                   30x faster than rebuilding" reference)
// The peers store boxes only; mktree writes each object's geometry too. Timed: the engine's Commit() of
// each batch (the batch's inputs are prepared before, untimed). After its batches each engine's answers
// (the whole scene box, and `--checks` 2 m boxes around random live objects) are compared with a brute-force
// scan of the script's live set; a difference fails the run (exit 1).
//
// Usage: changes_bench [--objects N] [--seed S] [--change-seed S] [--sizes 1,100,...] [--batches 20,20,...]
//                      [--engines a,b,...] [--dir WORKDIR] [--compact-threshold T] [--checks Q] [--smoke]
// `--smoke`: 100k tanker, 5 batches each of 1 and 100 changes.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bench/change_engine.h"
#include "bench/change_workload.h"
#include "mktree/build.h"

namespace mktree::bench {

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Args {
  uint64_t objects = 1000000;
  uint64_t seed = 1;
  uint64_t change_seed = 1;
  std::vector<uint64_t> sizes = {1, 100, 10000, 100000};
  std::vector<uint64_t> batches = {20, 20, 5, 2};
  std::string engines = "sqlite,spatialindex,bgi,mktree,rebuild";
  std::string dir = "/work/tmp-bench";
  double compact_threshold = 0;
  size_t checks = 20;
};

// One engine on one batch size.
struct Row {
  std::string engine;
  uint64_t size = 0;
  size_t batches = 0;
  double p50 = 0, p95 = 0;  // seconds
  double changes_per_second = 0;
};

std::vector<uint64_t> ParseList(const std::string& s) {
  std::vector<uint64_t> v;
  std::stringstream ss(s);
  std::string x;
  while (std::getline(ss, x, ','))
    if (!x.empty()) v.push_back(std::stoull(x));
  return v;
}

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> v;
  std::stringstream ss(s);
  std::string x;
  while (std::getline(ss, x, ','))
    if (!x.empty()) v.push_back(x);
  return v;
}

// Nearest rank: the smallest value with at least q of the values at or below it.
double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const size_t rank = static_cast<size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::clamp<size_t>(rank, 1, v.size()) - 1];
}

bool ParseArgs(int argc, char** argv, Args* a) {
  for (int i = 1; i < argc; ++i) {
    std::string k = argv[i], v;
    const size_t eq = k.find('=');
    if (eq != std::string::npos) {
      v = k.substr(eq + 1);
      k = k.substr(0, eq);
    } else if (k != "--smoke") {
      v = i + 1 < argc ? argv[++i] : "";
    }
    if (k == "--objects")
      a->objects = std::stoull(v);
    else if (k == "--seed")
      a->seed = std::stoull(v);
    else if (k == "--change-seed")
      a->change_seed = std::stoull(v);
    else if (k == "--sizes")
      a->sizes = ParseList(v);
    else if (k == "--batches")
      a->batches = ParseList(v);
    else if (k == "--engines")
      a->engines = v;
    else if (k == "--dir")
      a->dir = v;
    else if (k == "--compact-threshold")
      a->compact_threshold = std::stod(v);
    else if (k == "--checks")
      a->checks = std::stoull(v);
    else if (k == "--smoke") {
      a->objects = 100000;
      a->sizes = {1, 100};
      a->batches = {5, 5};
    } else {
      std::fprintf(stderr, "error: unknown argument %s (see the top of bench/changes_bench.cc)\n", k.c_str());
      return false;
    }
  }
  return true;
}

std::unique_ptr<ChangeEngine> MakeEngine(const std::string& name, const Args& a) {
  if (name == "sqlite") return MakeSqliteChangeEngine(a.dir, SqliteSync::kFull);
  if (name == "sqlite-normal") return MakeSqliteChangeEngine(a.dir, SqliteSync::kNormal);
  if (name == "spatialindex") return MakeSpatialIndexChangeEngine(a.dir);
  if (name == "bgi") return MakeBoostChangeEngine();
  if (name == "mktree") return MakeMktreeChangeEngine(a.dir, a.compact_threshold);
  return nullptr;
}

// The engine's answers against a brute-force scan of the live set: a box holding the whole scene, then 2 m
// cubes centred on random live objects.
Status CheckAnswers(ChangeEngine* e, const ChangeWorkload& w, size_t checks) {
  std::vector<Box3f> queries = {RoundOutward(Box3d{{-1e6, -1e6, -1e6}, {1e6, 1e6, 1e6}})};
  std::mt19937_64 rng(w.change_seed + 99);
  std::uniform_int_distribution<size_t> pick(0, w.live.size() - 1);
  while (queries.size() <= checks) {
    const size_t id = pick(rng);
    if (!w.live[id]) continue;
    Box3f q;
    for (int i = 0; i < 3; ++i) {
      const float c = 0.5f * (w.boxes[id].min[i] + w.boxes[id].max[i]);
      q.min[i] = c - 1.0f;
      q.max[i] = c + 1.0f;
    }
    queries.push_back(q);
  }
  std::vector<ObjectId> got, want;
  for (size_t qi = 0; qi < queries.size(); ++qi) {
    want.clear();
    for (size_t id = 0; id < w.live.size(); ++id)
      if (w.live[id] && w.boxes[id].Intersects(queries[qi])) want.push_back(static_cast<ObjectId>(id));
    MKTREE_RETURN_IF_ERROR(e->Query(queries[qi], &got));
    if (got != want)
      return Status::Internal(e->name() + ": check query " + std::to_string(qi) + " gave " +
                              std::to_string(got.size()) + " ids, the live set " +
                              std::to_string(want.size()));
  }
  return Status::Ok();
}

// Loads the engine, runs every batch of the script, checks its answers; appends one row per batch size.
Status RunEngine(ChangeEngine* e, const ChangeWorkload& w, const Args& a, std::vector<Row>* rows) {
  auto t0 = Clock::now();
  MKTREE_RETURN_IF_ERROR(e->Load(w));
  std::printf("## %s: loaded %llu objects in %.2f s\n", e->name().c_str(),
              static_cast<unsigned long long>(w.objects), Since(t0));
  std::fflush(stdout);
  for (const BatchGroup& g : w.groups) {
    std::vector<double> seconds;
    double total = 0;
    uint64_t changes = 0;
    for (const ChangeBatchScript& b : g.batches) {
      MKTREE_RETURN_IF_ERROR(e->Stage(b));
      const auto t = Clock::now();
      MKTREE_RETURN_IF_ERROR(e->Commit());
      seconds.push_back(Since(t));
      total += seconds.back();
      changes += b.changes.size();
    }
    if (seconds.empty()) continue;
    Row r{e->name(),
          g.size,
          seconds.size(),
          Percentile(seconds, 0.5),
          Percentile(seconds, 0.95),
          static_cast<double>(changes) / total};
    std::printf("   batch %7llu x %3zu: p50 %10.3f ms  p95 %10.3f ms  %12.0f changes/s\n",
                static_cast<unsigned long long>(r.size), r.batches, r.p50 * 1e3, r.p95 * 1e3,
                r.changes_per_second);
    std::fflush(stdout);
    rows->push_back(r);
  }
  t0 = Clock::now();
  MKTREE_RETURN_IF_ERROR(CheckAnswers(e, w, a.checks));
  std::printf("   answers equal brute force over the live set (%zu queries, %.1f s)%s%s\n", a.checks + 1,
              Since(t0), e->summary().empty() ? "" : "; ", e->summary().c_str());
  return Status::Ok();
}

// A full rebuild of the live set after the script, as mktree has to without changes; returns seconds. For
// scale, also times BuildFromFiles of the tanker itself (the generator read by the ingest's own threads).
Result<double> RunRebuild(const ChangeWorkload& w, const Args& a) {
  auto t0 = Clock::now();
  MKTREE_ASSIGN_OR_RETURN(const SourceObjects sources, LoadSourceObjects(w));
  std::printf("## rebuild: %zu moved objects' sources read in %.2f s (untimed)\n", sources.size(), Since(t0));
  const std::string path = a.dir + "/changes_rebuild.mkt";
  std::filesystem::remove(path);
  t0 = Clock::now();
  auto built = BuildFromObjects(LiveSetSource(w, sources), path, ChangesBenchBuildOptions());
  const double seconds = Since(t0);
  std::filesystem::remove(path);
  if (!built.ok()) return built.status();
  if (built->objects != w.live_count())
    return Status::Internal("rebuild: built " + std::to_string(built->objects) +
                            " objects, the live set has " + std::to_string(w.live_count()));
  std::printf(
      "   BuildFromObjects of the %llu live objects: %.2f s (read %.2f, tree %.2f, write %.2f), %llu pages\n",
      static_cast<unsigned long long>(built->objects), seconds, built->read_seconds, built->build_seconds,
      built->write_seconds, static_cast<unsigned long long>(built->pages));
  t0 = Clock::now();
  auto tanker = BuildFromFiles({w.TankerInput()}, path, ChangesBenchBuildOptions());
  const double tanker_seconds = Since(t0);
  std::filesystem::remove(path);
  if (!tanker.ok()) return tanker.status();
  std::printf(
      "   for scale, BuildFromFiles(\"%s\") before any change: %.2f s (read %.2f, tree %.2f, write %.2f)\n",
      w.TankerInput().c_str(), tanker_seconds, tanker->read_seconds, tanker->build_seconds,
      tanker->write_seconds);
  return seconds;
}

void PrintTable(const std::vector<Row>& rows, double rebuild_seconds) {
  std::printf(
      "\n| engine | batch size | batches | p50 ms | p95 ms | changes/s | rebuild ÷ p50 |\n"
      "|---|---:|---:|---:|---:|---:|---:|\n");
  for (const Row& r : rows) {
    char ratio[32] = "-";
    if (r.engine == "mktree" && rebuild_seconds > 0)
      std::snprintf(ratio, sizeof ratio, "%.1f", rebuild_seconds / r.p50);
    std::printf("| %s | %llu | %zu | %.3f | %.3f | %.0f | %s |\n", r.engine.c_str(),
                static_cast<unsigned long long>(r.size), r.batches, r.p50 * 1e3, r.p95 * 1e3,
                r.changes_per_second, ratio);
  }
  if (rebuild_seconds > 0)
    std::printf("| mktree full rebuild of the live set | - | 1 | %.1f | %.1f | - | - |\n",
                rebuild_seconds * 1e3, rebuild_seconds * 1e3);
}

void PrintHeader(const Args& a, const ChangeWorkload& w, double seconds,
                 const std::vector<std::unique_ptr<ChangeEngine>>& engines, bool rebuild) {
  std::printf("# changes_bench: commit latency of change batches (issue 38)\n");
  std::printf(
      "# workload: %s (%llu objects, scene box (%.1f, %.1f, %.1f)-(%.1f, %.1f, %.1f)), change seed %llu,"
      " generated in %.1f s\n",
      w.TankerInput().c_str(), static_cast<unsigned long long>(w.objects), w.scene_bounds.min[0],
      w.scene_bounds.min[1], w.scene_bounds.min[2], w.scene_bounds.max[0], w.scene_bounds.max[1],
      w.scene_bounds.max[2], static_cast<unsigned long long>(w.change_seed), seconds);
  std::printf("# batches, in this order on one evolving set:");
  for (const BatchGroup& g : w.groups)
    std::printf(" %zu x %llu", g.batches.size(), static_cast<unsigned long long>(g.size));
  std::printf(
      "; a third each add (moved copies of random tanker objects, new ids), remove (random live ids),"
      " replace (a live id gets a moved copy's geometry); %llu live objects at the end\n",
      static_cast<unsigned long long>(w.live_count()));
  std::printf(
      "# timed: each batch's commit alone (inputs prepared before it); p50/p95 by nearest rank over the"
      " batches of a size; changes/s = changes / summed commit time\n");
  std::printf(
      "# the peers store boxes only (no geometry); mktree writes each added or replaced object's"
      " geometry too\n");
  for (const auto& e : engines) std::printf("#   %s: %s\n", e->name().c_str(), e->description().c_str());
  if (rebuild)
    std::printf(
        "#   rebuild: mktree BuildFromObjects of the live set after the script, paged file, 12 KiB pages"
        " (4096 x 3), zstd, threads = cores\n");
#ifndef NDEBUG
  std::printf("WARNING: built without optimisation; timings are meaningless\n");
#endif
  std::printf("# files in %s\n", a.dir.c_str());
  std::fflush(stdout);
}

int Main(int argc, char** argv) {
  Args a;
  if (!ParseArgs(argc, argv, &a)) return 2;
  std::vector<std::unique_ptr<ChangeEngine>> engines;
  bool rebuild = false;
  for (const std::string& name : Split(a.engines)) {
    if (name == "rebuild") {
      rebuild = true;
      continue;
    }
    auto e = MakeEngine(name, a);
    if (!e) {
      std::fprintf(stderr,
                   "error: unknown engine %s (sqlite, sqlite-normal, spatialindex, bgi, mktree, rebuild)\n",
                   name.c_str());
      return 2;
    }
    engines.push_back(std::move(e));
  }
  std::filesystem::create_directories(a.dir);
  const auto t0 = Clock::now();
  auto w = MakeChangeWorkload(a.objects, a.seed, a.change_seed, a.sizes, a.batches);
  if (!w.ok()) {
    std::fprintf(stderr, "error: %s\n", w.status().ToString().c_str());
    return 2;
  }
  PrintHeader(a, *w, Since(t0), engines, rebuild);
  std::vector<Row> rows;
  for (auto& e : engines) {
    if (Status st = RunEngine(e.get(), *w, a, &rows); !st.ok()) {
      std::fprintf(stderr, "error: %s: %s\n", e->name().c_str(), st.ToString().c_str());
      return 1;
    }
    e.reset();  // its files and memory go before the next engine runs
  }
  double rebuild_seconds = 0;
  if (rebuild) {
    auto r = RunRebuild(*w, a);
    if (!r.ok()) {
      std::fprintf(stderr, "error: rebuild: %s\n", r.status().ToString().c_str());
      return 1;
    }
    rebuild_seconds = *r;
  }
  PrintTable(rows, rebuild_seconds);
  return 0;
}

}  // namespace
}  // namespace mktree::bench

int main(int argc, char** argv) { return mktree::bench::Main(argc, argv); }
