// query_bench: point and box queries on the synthetic tanker, cold and warm, against the I/O floor and
// against Boost.Geometry's packed R-tree in RAM on the same boxes (measured in the same run).
//
// Workloads (fixed seeds):
//   build        mktree build of tanker:N (both backends unless --backend), objects/s, peak RSS, size
//   point        --queries seeded random points in the scene box
//   box0.5/2/8   boxes of side 0.5 m, 2 m and 8 m centred on seeded random points
// For each: mean/p50/p99 pages read with a cold cache, the I/O floor ceil(T/B), mean leaves reached minus
// leaves holding an answer, queries/s cold (engine cache emptied before each query; add --direct-io
// for the OS cache too) and warm (64 MiB cache unless --warm-cache-mib, second pass; its misses read
// through the OS page cache),
// the warm pass's cache hit rate, AABB and exact mode. Every AABB answer is cross-checked against
// Boost.Geometry; a mismatch fails the run.
//
// Usage: query_bench [--objects N] [--seed S] [--queries Q] [--backend hdf5|pagefile] [--dir DIR]
//                    [--direct-io] [--keep] [--reuse] [--only WORKLOAD] [--mode aabb|exact] [--warm-passes K]
//                    [--warm-cache-mib M]
//   --keep     keep the store; --reuse opens a kept store instead of building it (no build line)
//   --only     run one workload (point, box0.5, box2, box8), --mode one mode: for perf record
//   --warm-passes K  time K warm passes, and K Boost.Geometry passes, and report the fastest of each (on a
//              machine shared with other jobs the fastest pass is the least disturbed one)
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/store_builder.h"
#include "mktree/database.h"

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;
using namespace mktree;

namespace {

using BPoint = bg::model::point<float, 3, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using BValue = std::pair<BBox, ObjectId>;
using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Args {
  uint64_t objects = 1000000;
  uint64_t seed = 1;
  size_t queries = 2000;
  std::string backend = "both";
  std::string dir = ".";
  bool direct_io = false;
  bool keep = false;
  bool reuse = false;
  std::string only;  // empty: every workload
  std::string mode;  // empty: both modes
  int warm_passes = 1;
  uint64_t warm_cache_mib = 64;
};

struct Workload {
  std::string name;
  std::vector<Query> queries;
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5))];
}

BBox ToB(const Box3d& b) {
  return BBox(
      BPoint(static_cast<float>(b.min[0]), static_cast<float>(b.min[1]), static_cast<float>(b.min[2])),
      BPoint(static_cast<float>(b.max[0]), static_cast<float>(b.max[1]), static_cast<float>(b.max[2])));
}

template <typename Rtree>
void BoostQuery(const Rtree& rtree, const Query& q, std::vector<BValue>* found) {
  found->clear();
  if (q.kind == Query::Kind::kPoint)
    rtree.query(bgi::intersects(BPoint(static_cast<float>(q.point.x), static_cast<float>(q.point.y),
                                       static_cast<float>(q.point.z))),
                std::back_inserter(*found));
  else
    rtree.query(bgi::intersects(ToB(q.box)), std::back_inserter(*found));
}

// Boost.Geometry compares in float; mktree's query boxes are double. To compare answers exactly, the
// workloads use query coordinates that are representable in float.
double F(double x) { return static_cast<double>(static_cast<float>(x)); }

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    std::string k = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (k == "--objects")
      a.objects = std::stoull(next());
    else if (k == "--seed")
      a.seed = std::stoull(next());
    else if (k == "--queries")
      a.queries = std::stoull(next());
    else if (k == "--backend")
      a.backend = next();
    else if (k == "--dir")
      a.dir = next();
    else if (k == "--direct-io")
      a.direct_io = true;
    else if (k == "--keep")
      a.keep = true;
    else if (k == "--reuse")
      a.reuse = a.keep = true;
    else if (k == "--only")
      a.only = next();
    else if (k == "--mode")
      a.mode = next();
    else if (k == "--warm-passes")
      a.warm_passes = std::max(1, std::stoi(next()));
    else if (k == "--warm-cache-mib")
      a.warm_cache_mib = std::stoull(next());
    else {
      std::fprintf(stderr, "unknown argument %s\n", k.c_str());
      return 2;
    }
  }
#ifndef NDEBUG
  std::printf("WARNING: built without optimisation; timings are meaningless\n");
#endif
  std::printf("# query_bench: tanker objects=%llu seed=%llu queries/workload=%zu page=12 KiB direct_io=%d\n",
              static_cast<unsigned long long>(a.objects), static_cast<unsigned long long>(a.seed), a.queries,
              a.direct_io);
  std::printf(
      "# cores=%ld, cold = engine cache emptied before each query%s; warm = %llu MiB cache, best of %d "
      "passes\n",
      sysconf(_SC_NPROCESSORS_ONLN), a.direct_io ? " and O_DIRECT reads" : " (OS page cache not bypassed)",
      static_cast<unsigned long long>(a.warm_cache_mib), a.warm_passes);

  // Object AABBs for the peer and for query placement, streamed from the generator.
  std::vector<BValue> values;
  values.reserve(a.objects);
  Box3f scene;
  {
    auto src = MakeTankerSource(a.objects, a.seed, 0);
    SceneObject o;
    for (;;) {
      auto more = src->Next(&o);
      if (!more.ok()) {
        std::fprintf(stderr, "generator: %s\n", more.status().ToString().c_str());
        return 1;
      }
      if (!*more) break;
      const Box3f b = o.Aabb();
      scene.Extend(b);
      values.emplace_back(BBox(BPoint(b.min[0], b.min[1], b.min[2]), BPoint(b.max[0], b.max[1], b.max[2])),
                          o.id);
    }
  }
  auto t0 = Clock::now();
  bgi::rtree<BValue, bgi::rstar<16>> rtree(values.begin(), values.end());
  const double rtree_build = Since(t0);
  std::printf("# boost.geometry rtree (rstar<16>, packing constructor): %.2fs to build in RAM\n",
              rtree_build);

  std::vector<Workload> workloads;
  {
    std::mt19937_64 rng(a.seed * 7919 + 17);
    std::uniform_real_distribution<double> u(0, 1);
    auto random_point = [&] {
      Vec3d p;
      for (int i = 0; i < 3; ++i) p[i] = F(scene.min[i] + u(rng) * (scene.max[i] - scene.min[i]));
      return p;
    };
    Workload points{"point", {}};
    for (size_t i = 0; i < a.queries; ++i) points.queries.push_back(Query::Point(random_point()));
    workloads.push_back(points);
    for (double side : {0.5, 2.0, 8.0}) {
      char name[32];
      std::snprintf(name, sizeof name, "box%g", side);
      Workload w{name, {}};
      for (size_t i = 0; i < a.queries; ++i) {
        Vec3d c = random_point();
        Box3d b;
        for (int k = 0; k < 3; ++k) {
          b.min[k] = F(c[k] - side / 2);
          b.max[k] = F(c[k] + side / 2);
        }
        w.queries.push_back(Query::Box(b));
      }
      workloads.push_back(w);
    }
  }

  std::vector<std::string> backends;
  if (a.backend == "both" || a.backend == "hdf5") backends.push_back("hdf5");
  if (a.backend == "both" || a.backend == "pagefile") backends.push_back("pagefile");
  bool mismatch = false;
  for (const std::string& backend : backends) {
    // The name carries the scene so that --reuse never opens a store of another scene.
    const std::string path = a.dir + "/query_bench_" + backend + "_" + std::to_string(a.objects) + "_" +
                             std::to_string(a.seed) + ".mkt";
    IngestOptions opts;
    opts.store.backend = backend == "hdf5" ? Backend::kHdf5 : Backend::kPagedFile;
    std::printf("\n## backend %s\n", backend.c_str());
    if (!a.reuse || !std::filesystem::exists(path)) {
      t0 = Clock::now();
      auto report = BuildStore({[&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
                                 return MakeTankerSource(a.objects, a.seed, first);
                               }},
                               path, opts);
      if (!report.ok()) {
        std::fprintf(stderr, "build: %s\n", report.status().ToString().c_str());
        return 1;
      }
      struct rusage ru {};
      getrusage(RUSAGE_SELF, &ru);
      std::printf(
          "build: %.2fs, %.0f objects/s, %.1f MB/s written, store %.1f MiB, raw geometry "
          "%.1f MiB (ratio %.2f), peak RSS so far %.0f MiB, %llu leaves, %llu pages\n",
          report->total_seconds, a.objects / report->total_seconds,
          report->store_bytes / 1e6 / report->write_seconds, report->store_bytes / 1048576.0,
          report->raw_geometry_bytes / 1048576.0,
          static_cast<double>(report->raw_geometry_bytes) / static_cast<double>(report->store_bytes),
          ru.ru_maxrss / 1024.0, static_cast<unsigned long long>(report->tree_stats.leaves),
          static_cast<unsigned long long>(report->pages));
    }

    OpenOptions cold_opts;
    cold_opts.cache_pages = 4096;
    cold_opts.direct_io = a.direct_io;
    auto db = Database::Open(path, cold_opts);
    OpenOptions warm_opts;
    warm_opts.cache_pages = (a.warm_cache_mib << 20) / opts.store.params.mem_page();
    auto warm = Database::Open(path, warm_opts);
    if (!db.ok() || !warm.ok()) {
      std::fprintf(stderr, "open: %s\n", (!db.ok() ? db.status() : warm.status()).ToString().c_str());
      return 1;
    }
    const double B = (*db)->objects_per_page();
    std::printf("B = %.2f objects per page\n", B);
    std::printf("%-8s %-5s %9s %9s %9s %9s %9s %10s %9s %11s %11s %11s %8s %8s\n", "workload", "mode", "hits",
                "pages", "p50", "p99", "floor", "pages/flr", "extra_lv", ">1leaf(%)", "cold q/s", "warm q/s",
                "vs boost", "warm hit");
    for (const Workload& w : workloads) {
      if (!a.only.empty() && w.name != a.only) continue;
      for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
        if (!a.mode.empty() && a.mode != (mode == QueryMode::kAabb ? "aabb" : "exact")) continue;
        std::vector<Query> queries = w.queries;
        for (Query& q : queries) q.mode = mode;
        std::vector<double> pages, floors;
        double hits = 0, extra = 0, multi = 0;
        QueryResult r;
        t0 = Clock::now();
        for (const Query& q : queries) {
          (*db)->ClearCache();
          if (!(*db)->Run(q, &r).ok()) return 1;
          pages.push_back(static_cast<double>(r.stats.pages_read));
          floors.push_back(std::ceil(static_cast<double>(r.hits.size()) / B));
          hits += static_cast<double>(r.hits.size());
          extra += static_cast<double>(r.stats.leaves_visited - r.stats.leaves_with_hits);
          multi += r.stats.leaves_visited > 1;
        }
        const double cold_qps = static_cast<double>(w.queries.size()) / Since(t0);
        for (const Query& q : queries)  // fill the warm cache
          if (!(*warm)->Run(q, &r).ok()) return 1;
        QueryStats warm_stats;
        double warm_qps = 0;
        for (int pass = 0; pass < a.warm_passes; ++pass) {
          t0 = Clock::now();
          for (const Query& q : queries) {
            if (!(*warm)->Run(q, &r).ok()) return 1;
            warm_stats += r.stats;
          }
          warm_qps = std::max(warm_qps, static_cast<double>(w.queries.size()) / Since(t0));
        }
        const double warm_hit_rate =
            warm_stats.pages_touched ? static_cast<double>(warm_stats.cache_hits) / warm_stats.pages_touched
                                     : 1.0;
        std::string vs = "-";
        if (mode == QueryMode::kAabb) {
          // Same queries against Boost.Geometry, and the answers cross-checked.
          std::vector<BValue> found;
          std::vector<ObjectId> ids;
          size_t total = 0;
          double boost_qps = 0;
          for (int pass = 0; pass < a.warm_passes; ++pass) {
            t0 = Clock::now();
            for (const Query& q : queries) {
              BoostQuery(rtree, q, &found);
              total += found.size();
            }
            boost_qps = std::max(boost_qps, static_cast<double>(w.queries.size()) / Since(t0));
          }
          char buf[32];
          std::snprintf(buf, sizeof buf, "%.2fx", warm_qps / boost_qps);
          vs = buf;
          for (const Query& q : queries) {
            BoostQuery(rtree, q, &found);
            ids.clear();
            for (const auto& v : found) ids.push_back(v.second);
            std::sort(ids.begin(), ids.end());
            if (!(*warm)->Run(q, &r).ok()) return 1;
            if (ids != r.hits) {
              std::fprintf(stderr, "MISMATCH %s: mktree %zu hits, boost %zu\n", w.name.c_str(), r.hits.size(),
                           ids.size());
              mismatch = true;
              break;
            }
          }
          (void)total;
        }
        double mean_pages = 0, mean_floor = 0;
        for (double p : pages) mean_pages += p;
        for (double f : floors) mean_floor += f;
        const double n = static_cast<double>(w.queries.size());
        mean_pages /= n;
        mean_floor /= n;
        std::printf("%-8s %-5s %9.2f %9.3f %9.0f %9.0f %9.3f %10.2f %9.3f %11.1f %11.0f %11.0f %8s %7.1f%%\n",
                    w.name.c_str(), mode == QueryMode::kAabb ? "aabb" : "exact", hits / n, mean_pages,
                    Percentile(pages, 0.5), Percentile(pages, 0.99), mean_floor,
                    mean_floor > 0 ? mean_pages / mean_floor : 0.0, extra / n, 100 * multi / n, cold_qps,
                    warm_qps, vs.c_str(), 100 * warm_hit_rate);
      }
    }
    if (!a.keep) std::filesystem::remove(path);
  }
  if (mismatch) {
    std::printf("FAILED: answers differ from Boost.Geometry\n");
    return 1;
  }
  return 0;
}
