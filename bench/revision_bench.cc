// revision_bench: what changes cost a store's readers, and what compaction and incremental clash cost
// (docs/changes.md), on the synthetic tanker in a paged-file store of 12 KiB pages.
//
// Workloads (fixed seeds; a change is a third each add, remove, replace; an added or replacing object is a
// copy of a random live object moved by up to 2 m on each axis):
//   pages     changes committed in batches of --batch until 1 %, 10 % and 30 % of the objects changed;
//             at each: cold pages per query (engine cache emptied before each query) of --queries points
//             and 0.5 / 2 / 8 m boxes on the revision, against the same queries on a compaction of a copy
//             of the store (= a fresh build of the live objects in id order), answers cross-checked;
//             compaction time and its process's peak RSS against a fresh build of the same live objects
//             read from an .mks file (written from the compacted copy, untimed) and against the tanker's
//             build (the generator: no input to read)
//   clash     a --clash-batch change batch: ClashSince (incremental) against the full self-clash of the new
//             revision and against collide of each added or replacing object: time and pages read
//   reader    one thread running box2 queries warm for --seconds, with the writer idle, then with the
//             writer committing batches of --clash-batch on the other thread: reader queries/s
//
// With --shards K, every store (the tanker's, the fresh build's) is a sharded store of K shards, and a
// compaction is a sharded build of the live objects (docs/changes.md, "Sharded stores").
//
// Usage: revision_bench [--objects N] [--seed S] [--queries Q] [--batch B] [--clash-batch K]
//                       [--seconds T] [--dir DIR] [--only pages|clash|reader] [--fractions 0.01,0.1,0.3]
//                       [--shards K]
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "bench/peak_rss.h"
#include "engine/generator/tanker_generator.h"
#include "engine/ingest/shard_build.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/mkscene_format.h"
#include "mktree/build.h"
#include "mktree/changes.h"
#include "mktree/database.h"

using namespace mktree;
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Args {
  uint64_t objects = 1000000;
  uint64_t seed = 1;
  size_t queries = 500;
  size_t batch = 10000;
  size_t clash_batch = 1000;
  double seconds = 5;
  std::string dir = ".";
  std::string only;
  std::vector<double> fractions{0.01, 0.10, 0.30};
  uint32_t shards = 0;
};

// The store at `path` built from `inputs` with the bench's options: one store, or `shards` shards.
Status BuildBenchStore(const std::vector<SceneOpener>& inputs, const std::string& path, uint32_t shards) {
  IngestOptions o;
  o.store.backend = Backend::kPagedFile;
  if (shards > 0) return BuildShardedStore(inputs, path, o, shards).status();
  return BuildStore(inputs, path, o).status();
}

[[noreturn]] void Die(const std::string& what, const Status& st) {
  std::fprintf(stderr, "revision_bench: %s: %s\n", what.c_str(), st.ToString().c_str());
  std::exit(1);
}
template <typename T>
T Must(Result<T> r, const std::string& what) {
  if (!r.ok()) Die(what, r.status());
  return std::move(*r);
}

// Runs this program with `args` and the path of a file for its peak RSS (which it writes last, from
// bench::PeakRssMiB, not this process's rusage of it) in a process of its own; returns its exit status and
// that peak in MiB.
std::pair<int, double> Spawn(std::vector<std::string> args, const std::string& dir) {
  std::fflush(stdout);
  const std::string peak = dir + "/revision_bench.peak";
  fs::remove(peak);
  args.push_back(peak);
  std::vector<char*> argv{const_cast<char*>("revision_bench")};
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, "/proc/self/exe", nullptr, nullptr, argv.data(), environ) != 0) return {127, 0};
  int status = 0;
  waitpid(pid, &status, 0);
  double mib = 0;
  if (std::FILE* f = std::fopen(peak.c_str(), "r")) {
    if (std::fscanf(f, "%lf", &mib) != 1) mib = 0;
    std::fclose(f);
  }
  fs::remove(peak);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128, mib};
}

// A child's last step: its peak RSS to `path`; its exit status.
int ReportPeak(const std::string& path, bool ok) {
  if (std::FILE* f = std::fopen(path.c_str(), "w")) {
    std::fprintf(f, "%.1f\n", bench::PeakRssMiB());
    std::fclose(f);
  }
  return ok ? 0 : 1;
}

struct Workload {
  std::string name;
  std::vector<Query> queries;
};

std::vector<Workload> MakeWorkloads(const Box3d& scene, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed * 7919 + 17);
  std::uniform_real_distribution<double> u(0, 1);
  auto point = [&] {
    Vec3d p;
    for (int i = 0; i < 3; ++i) p[i] = scene.min[i] + u(rng) * (scene.max[i] - scene.min[i]);
    return p;
  };
  std::vector<Workload> out{{"point", {}}};
  for (size_t i = 0; i < n; ++i) out[0].queries.push_back(Query::Point(point()));
  for (double side : {0.5, 2.0, 8.0}) {
    Workload w{"box" + std::string(side == 0.5 ? "0.5" : side == 2 ? "2" : "8"), {}};
    for (size_t i = 0; i < n; ++i) {
      const Vec3d c = point();
      Box3d b;
      for (int k = 0; k < 3; ++k) {
        b.min[k] = c[k] - side / 2;
        b.max[k] = c[k] + side / 2;
      }
      w.queries.push_back(Query::Box(b));
    }
    out.push_back(std::move(w));
  }
  return out;
}

// Cold pages per query of each workload, and every answer (for the cross-check).
std::vector<double> ColdPages(const Database& db, const std::vector<Workload>& ws,
                              std::vector<std::vector<ObjectId>>* answers) {
  std::vector<double> out;
  answers->clear();
  for (const Workload& w : ws) {
    BatchOptions bo;
    bo.threads = 1;
    bo.cold = true;
    uint64_t pages = 0;
    const Status st = db.RunBatchStreamed(w.queries, bo, [&](uint64_t, const QueryResult& r) {
      pages += r.stats.pages_read;
      answers->push_back(r.hits);
      return Status::Ok();
    });
    if (!st.ok()) Die("queries", st);
    out.push_back(static_cast<double>(pages) / static_cast<double>(w.queries.size()));
  }
  return out;
}

// The ids live now, kept beside the writer to draw changes from.
class Changes {
 public:
  Changes(uint64_t objects, uint64_t seed) : rng_(seed) {
    live_.resize(objects);
    for (uint64_t i = 0; i < objects; ++i) live_[i] = static_cast<ObjectId>(i);
  }
  // A batch of n changes drawn against `db` (the newest revision).
  ChangeBatch Next(const Database& db, size_t n) {
    ChangeBatch b;
    std::uniform_real_distribution<double> move(-2, 2);
    for (size_t i = 0; i < n && live_.size() > 1; ++i) {
      const size_t at = rng_() % live_.size();
      const ObjectId id = live_[at];
      const int kind = static_cast<int>(i % 3);
      if (kind == 1) {
        b.remove.push_back(id);
        live_[at] = live_.back();
        live_.pop_back();
        continue;
      }
      SceneObject o;
      o.mesh = Must(db.ObjectGeometry(id), "geometry");
      const ObjectRecord rec = Must(db.Object(id), "record");
      o.name = rec.name;
      o.attributes = rec.attributes;
      const double dx = move(rng_), dy = move(rng_), dz = move(rng_);
      for (size_t v = 0; v < o.mesh.vertex_count(); ++v) {
        o.mesh.vertices[3 * v] += dx;
        o.mesh.vertices[3 * v + 1] += dy;
        o.mesh.vertices[3 * v + 2] += dz;
      }
      if (kind == 0) {
        b.add.push_back(std::move(o));
      } else {
        o.id = id;
        b.replace.push_back(std::move(o));
        live_[at] = live_.back();  // a replaced object is not changed twice in one batch
        live_.pop_back();
        replaced_.push_back(id);
      }
    }
    return b;
  }
  void Committed(const CommitReport& r) {
    live_.insert(live_.end(), r.added_ids.begin(), r.added_ids.end());
    live_.insert(live_.end(), replaced_.begin(), replaced_.end());
    replaced_.clear();
  }

 private:
  std::mt19937_64 rng_;
  std::vector<ObjectId> live_, replaced_;
};

// The store, its changes folder and a sharded store's shard files beside it, removed.
void RemoveStore(const std::string& path) {
  fs::remove(path);
  fs::remove_all(path + ".changes");
  const std::string stem = fs::path(path).filename().string() + ".shard-";
  std::vector<fs::path> shards;
  for (const auto& e : fs::directory_iterator(fs::path(path).parent_path()))
    if (e.path().filename().string().rfind(stem, 0) == 0) shards.push_back(e.path());
  for (const fs::path& p : shards) fs::remove(p);
}

// The store, its changes folder and a sharded store's shard files beside it ("<store>.shard-N...").
void CopyStore(const std::string& from, const std::string& to) {
  RemoveStore(to);
  fs::copy_file(from, to);
  fs::copy(from + ".changes", to + ".changes", fs::copy_options::recursive);
  const std::string stem = fs::path(from).filename().string() + ".shard-";
  for (const auto& e : fs::directory_iterator(fs::path(from).parent_path()))
    if (e.path().filename().string().rfind(stem, 0) == 0)
      fs::copy_file(e.path(), to + e.path().filename().string().substr(stem.size() - 7),
                    fs::copy_options::overwrite_existing);
}

void RunPages(const Args& a, const std::string& store, double build_seconds, double build_rss) {
  auto db0 = Must(Database::Open(store), "open");
  const std::vector<Workload> ws = MakeWorkloads(db0->bounds(), a.queries, a.seed);
  std::printf("\n## pages: cold pages per query, revision with changes vs its compaction (fresh build)\n");
  std::printf("%-8s %6s %7s", "changed", "parts", "commits");
  for (const Workload& w : ws)
    std::printf(" %8s %8s %6s", (w.name + ".r").c_str(), (w.name + ".c").c_str(), "ratio");
  std::printf(" %9s %8s %8s %9s %9s\n", "compact_s", "rss_MiB", "fresh_s", "fresh_MiB", "answers");
  auto w = Must(ChangeWriter::Open(store, {.compact_threshold = 0}), "writer");
  Changes changes(a.objects, a.seed + 1);
  uint64_t changed = 0, commits = 0;
  std::vector<double> latencies;
  std::vector<std::string> fresh_rows;
  for (double f : a.fractions) {
    const uint64_t target = static_cast<uint64_t>(f * static_cast<double>(a.objects));
    while (changed < target) {
      auto db = Must(Database::Open(store), "open");
      const ChangeBatch b = changes.Next(*db, std::min<uint64_t>(a.batch, target - changed));
      const CommitReport r = Must(w->Commit(b), "commit");
      changes.Committed(r);
      latencies.push_back(r.seconds);
      changed += r.added + r.removed + r.replaced;
      ++commits;
    }
    auto db = Must(Database::Open(store), "open");
    std::vector<std::vector<ObjectId>> got, want;
    const std::vector<double> rev = ColdPages(*db, ws, &got);
    const std::string copy = a.dir + "/revision_bench_compacted.mkt";
    CopyStore(store, copy);
    const auto t = Clock::now();
    // A process of its own (spawned), so that its peak RSS is the compaction's, not this one's too.
    const auto [rc, rss] = Spawn({"--compact-only", copy}, a.dir);
    const double compact_s = Since(t);
    if (rc != 0) Die("compaction", Status::Internal("child failed"));
    auto cdb = Must(Database::Open(copy), "open compacted");
    const std::vector<double> fresh = ColdPages(*cdb, ws, &want);
    // The same live objects as a scene file, built afresh (as a user rebuilding would, from a file).
    const std::string mks = a.dir + "/revision_bench_live.mks";
    std::vector<ObjectId> live_ids;  // the fresh build numbers the live objects 0, 1, 2, ... in id order
    {
      auto out = Must(MkSceneWriter::Create(mks), "live scene");
      SceneObject o;
      for (ObjectId id = 0; id < cdb->id_limit(); ++id) {
        auto r = cdb->Object(id);
        if (!r.ok()) continue;  // removed
        live_ids.push_back(id);
        o.id = id;
        o.name = r->name;
        o.source = r->source;
        o.attributes = r->attributes;
        o.mesh = Must(cdb->ObjectGeometry(id), "geometry");
        if (Status st = out->Write(o); !st.ok()) Die("live scene", st);
      }
      if (Status st = out->Finish(); !st.ok()) Die("live scene", st);
    }
    const std::string rebuilt = a.dir + "/revision_bench_fresh.mkt";
    RemoveStore(rebuilt);
    const auto tf = Clock::now();
    const auto [frc, fresh_rss] = Spawn({"--build-only", mks, rebuilt, std::to_string(a.shards)}, a.dir);
    const double fresh_s = Since(tf);
    if (frc != 0) Die("fresh build", Status::Internal("child failed"));
    {
      // The compaction must read as the fresh build does (the issue: pages per query within 2 %).
      auto fdb = Must(Database::Open(rebuilt), "open fresh build");
      std::vector<std::vector<ObjectId>> fresh_got;
      const std::vector<double> rebuilt_pages = ColdPages(*fdb, ws, &fresh_got);
      bool same = fresh_got.size() == want.size();
      for (size_t q = 0; same && q < want.size(); ++q) {
        for (ObjectId& id : fresh_got[q]) id = live_ids[id];
        std::vector<ObjectId> w = want[q];
        std::sort(w.begin(), w.end());
        std::sort(fresh_got[q].begin(), fresh_got[q].end());
        same = w == fresh_got[q];
      }
      char row[512];
      int n = std::snprintf(row, sizeof row, "%-7.0f%%", f * 100);
      for (size_t i = 0; i < ws.size(); ++i)
        n += std::snprintf(row + n, sizeof row - n, " %8.2f %8.2f %6.3f", fresh[i], rebuilt_pages[i],
                           fresh[i] / rebuilt_pages[i]);
      std::snprintf(row + n, sizeof row - n, " %9s", same ? "same" : "DIFFER");
      fresh_rows.push_back(row);
      if (!same) {
        std::printf("%s\n", row);
        std::exit(2);
      }
    }
    RemoveStore(rebuilt);
    if (!std::getenv("REVISION_BENCH_KEEP_MKS")) fs::remove(mks);
    const std::string& js = db->stats_json();
    int parts = 0;  // the stores the revision answers from: a part per shard of a sharded base, then deltas
    for (size_t at = js.find("\"leaves\": "); at != std::string::npos; at = js.find("\"leaves\": ", at + 1))
      ++parts;
    std::printf("%-7.0f%% %6d %7llu", f * 100, parts, static_cast<unsigned long long>(commits));
    for (size_t i = 0; i < ws.size(); ++i)
      std::printf(" %8.2f %8.2f %6.3f", rev[i], fresh[i], rev[i] / fresh[i]);
    std::printf(" %9.2f %8.0f %8.2f %9.0f %9s\n", compact_s, rss, fresh_s, fresh_rss,
                got == want ? "same" : "DIFFER");
    if (got != want) std::exit(2);
  }
  std::printf(
      "\n## pages: cold pages per query, the compaction vs a fresh build of the same live objects (.mks)\n");
  std::printf("%-8s", "changed");
  for (const Workload& w : ws)
    std::printf(" %8s %8s %6s", (w.name + ".c").c_str(), (w.name + ".f").c_str(), "ratio");
  std::printf(" %9s\n", "answers");
  for (const std::string& row : fresh_rows) std::printf("%s\n", row.c_str());
  std::sort(latencies.begin(), latencies.end());
  std::printf("commits of %zu changes: p50 %.3f s, p95 %.3f s; tanker build: %.2f s, peak RSS %.0f MiB\n",
              a.batch, latencies[latencies.size() / 2], latencies[latencies.size() * 95 / 100], build_seconds,
              build_rss);
}

void RunClash(const Args& a, const std::string& store) {
  std::printf("\n## clash: a %zu-change batch, incremental against full and against collide\n",
              a.clash_batch);
  auto then = Must(Database::Open(store), "open");
  auto w = Must(ChangeWriter::Open(store, {.compact_threshold = 0}), "writer");
  Changes changes(then->id_limit(), a.seed + 2);
  // Ids drawn below id_limit may be dead after the pages workload: draw against the live store only.
  ChangeBatch b;
  {
    std::mt19937_64 rng(a.seed + 3);
    Changes c(0, a.seed + 2);
    (void)c;
    std::vector<ObjectId> live;
    for (ObjectId id = 0; id < then->id_limit() && live.size() < 4 * a.clash_batch; id += 1 + rng() % 97)
      if (then->Object(id).ok()) live.push_back(id);
    std::uniform_real_distribution<double> move(-2, 2);
    for (size_t i = 0; i < a.clash_batch && i < live.size(); ++i) {
      const ObjectId id = live[i];
      if (i % 3 == 1) {
        b.remove.push_back(id);
        continue;
      }
      SceneObject o;
      o.mesh = Must(then->ObjectGeometry(id), "geometry");
      o.name = Must(then->Object(id), "record").name;
      const double dx = move(rng), dy = move(rng), dz = move(rng);
      for (size_t v = 0; v < o.mesh.vertex_count(); ++v) {
        o.mesh.vertices[3 * v] += dx;
        o.mesh.vertices[3 * v + 1] += dy;
        o.mesh.vertices[3 * v + 2] += dz;
      }
      if (i % 3 == 0) {
        b.add.push_back(std::move(o));
      } else {
        o.id = id;
        b.replace.push_back(std::move(o));
      }
    }
  }
  const CommitReport r = Must(w->Commit(b), "commit");
  auto now = Must(Database::Open(store), "open");
  ClashOptions o;
  o.threads = 1;
  ClashStats inc, full;
  uint64_t added = 0, resolved = 0;
  now->ClearCache();
  then->ClearCache();
  auto t = Clock::now();
  Status st = ClashSince(
      *now, *then, o, [&](const ClashPair&, ClashChange c) { (c == ClashChange::kNew ? added : resolved)++; },
      &inc);
  const double inc_s = Since(t);
  if (!st.ok()) Die("clash since", st);
  now->ClearCache();
  t = Clock::now();
  uint64_t pairs = 0;
  st = now->SelfClash(
      o, [&](const ClashPair&) { ++pairs; }, &full);
  const double full_s = Since(t);
  if (!st.ok()) Die("self-clash", st);
  now->ClearCache();
  ClashStats col_total;
  t = Clock::now();
  std::vector<ObjectId> written = r.added_ids;
  for (const SceneObject& x : b.replace) written.push_back(x.id);
  for (ObjectId id : written) {
    const Mesh m = Must(now->ObjectGeometry(id), "geometry");
    ClashStats cs;
    st = now->Collide(m, std::nullopt, o, nullptr, &cs);
    if (!st.ok()) Die("collide", st);
    col_total.pages_read += cs.pages_read;
  }
  const double col_s = Since(t);
  std::printf("incremental: %.2f s, %llu pages, %llu new, %llu resolved (both revisions' focused clashes)\n",
              inc_s, static_cast<unsigned long long>(inc.pages_read), static_cast<unsigned long long>(added),
              static_cast<unsigned long long>(resolved));
  std::printf("full self-clash: %.2f s, %llu pages, %llu pairs; incremental/full time %.3f, pages %.3f\n",
              full_s, static_cast<unsigned long long>(full.pages_read),
              static_cast<unsigned long long>(pairs), inc_s / full_s,
              static_cast<double>(inc.pages_read) / static_cast<double>(full.pages_read));
  std::printf("collide of the %zu written objects at the new revision: %.2f s, %llu pages\n", written.size(),
              col_s, static_cast<unsigned long long>(col_total.pages_read));
}

void RunReader(const Args& a, const std::string& store) {
  std::printf("\n## reader: box2 queries warm on one thread, writer idle vs committing\n");
  auto db = Must(Database::Open(store), "open");
  const std::vector<Workload> ws = MakeWorkloads(db->bounds(), 20000, a.seed + 5);
  auto rate = [&](std::atomic<bool>& stop) {
    uint64_t n = 0;
    const auto t = Clock::now();
    while (Since(t) < a.seconds) {
      QueryResult r;
      if (!db->Run(ws[2].queries[n % ws[2].queries.size()], &r).ok()) std::exit(3);
      ++n;
    }
    stop = true;
    return static_cast<double>(n) / Since(t);
  };
  std::atomic<bool> stop{false};
  const double idle = rate(stop);
  stop = false;
  uint64_t commits = 0;
  std::thread writer([&] {
    auto w = Must(ChangeWriter::Open(store, {.compact_threshold = 0}), "writer");
    auto wdb = Must(Database::Open(store), "open");
    Changes changes(0, a.seed + 6);
    std::mt19937_64 rng(a.seed + 7);
    while (!stop) {
      ChangeBatch b;
      for (size_t i = 0; i < a.clash_batch / 3; ++i) {
        const ObjectId id = static_cast<ObjectId>(rng() % wdb->id_limit());
        auto m = wdb->ObjectGeometry(id);
        if (!m.ok()) continue;
        SceneObject o;
        o.mesh = std::move(*m);
        o.name = "reader_bench_add";
        b.add.push_back(std::move(o));
      }
      if (!w->Commit(b).ok()) std::exit(4);
      ++commits;
    }
  });
  const double busy = rate(stop);
  writer.join();
  std::printf("reader q/s: idle writer %.0f, writer committing %.0f (%llu commits meanwhile): ratio %.3f\n",
              idle, busy, static_cast<unsigned long long>(commits), busy / idle);
}

}  // namespace

int main(int argc, char** argv) {
  // The children Spawn runs (their last argument: the file for their peak RSS).
  if (argc == 4 && std::strcmp(argv[1], "--compact-only") == 0) {  // STORE
    auto cw = ChangeWriter::Open(argv[2]);
    return ReportPeak(argv[3], cw.ok() && (*cw)->Compact().ok());
  }
  if (argc == 6 && std::strcmp(argv[1], "--build-only") == 0) {  // MKS STORE SHARDS: as `mktree build`
    BuildOptions o;
    o.backend = BuildOptions::Backend::kPagedFile;
    o.shards = static_cast<uint32_t>(std::stoul(argv[4]));
    auto built = BuildFromFiles({argv[2]}, argv[3], o);
    if (!built.ok())
      std::fprintf(stderr, "revision_bench: fresh build: %s\n", built.status().ToString().c_str());
    return ReportPeak(argv[5], built.ok());
  }
  if (argc == 7 && std::strcmp(argv[1], "--tanker-only") == 0) {  // N SEED STORE SHARDS
    const uint64_t n = std::stoull(argv[2]), seed = std::stoull(argv[3]);
    const Status st = BuildBenchStore({[&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
                                        return MakeTankerSource(n, seed, first);
                                      }},
                                      argv[4], static_cast<uint32_t>(std::stoul(argv[5])));
    if (!st.ok()) std::fprintf(stderr, "revision_bench: build: %s\n", st.ToString().c_str());
    return ReportPeak(argv[6], st.ok());
  }
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", k.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (k == "--objects")
      a.objects = std::stoull(next());
    else if (k == "--seed")
      a.seed = std::stoull(next());
    else if (k == "--queries")
      a.queries = std::stoull(next());
    else if (k == "--batch")
      a.batch = std::stoull(next());
    else if (k == "--clash-batch")
      a.clash_batch = std::stoull(next());
    else if (k == "--seconds")
      a.seconds = std::stod(next());
    else if (k == "--dir")
      a.dir = next();
    else if (k == "--shards")
      a.shards = static_cast<uint32_t>(std::stoul(next()));
    else if (k == "--only")
      a.only = next();
    else if (k == "--fractions") {
      a.fractions.clear();
      const std::string list = next();
      for (size_t at = 0; at < list.size();) {
        const size_t comma = std::min(list.find(',', at), list.size());
        a.fractions.push_back(std::stod(list.substr(at, comma - at)));
        at = comma + 1;
      }
    } else {
      std::fprintf(stderr, "unknown argument %s\n", k.c_str());
      return 2;
    }
  }
  std::printf(
      "# revision_bench: tanker objects=%llu seed=%llu queries/workload=%zu batch=%zu clash-batch=%zu "
      "page=12 KiB pagefile shards=%u cores=%ld\n",
      static_cast<unsigned long long>(a.objects), static_cast<unsigned long long>(a.seed), a.queries, a.batch,
      a.clash_batch, a.shards, sysconf(_SC_NPROCESSORS_ONLN));
  const std::string store = a.dir + "/revision_bench.mkt";
  RemoveStore(store);
  const auto t = Clock::now();
  const auto [rc, rss] = Spawn(
      {"--tanker-only", std::to_string(a.objects), std::to_string(a.seed), store, std::to_string(a.shards)},
      a.dir);
  const double build_s = Since(t);
  if (rc != 0) Die("build", Status::Internal("child failed"));
  std::printf("build: %.2f s, peak RSS %.0f MiB\n", build_s, rss);
  if (a.only.empty() || a.only == "pages") RunPages(a, store, build_s, rss);
  if (a.only.empty() || a.only == "clash") RunClash(a, store);
  if (a.only.empty() || a.only == "reader") RunReader(a, store);
  return 0;
}
