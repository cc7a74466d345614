// warm_bench: warm AABB queries of one open Database against Boost.Geometry's packed rtree, many passes
// over the same queries (peers_bench times one pass of each engine, too short to profile or to compare
// small workloads on a shared machine).
//
// Workloads (seeded; `--seed`), those of peers_bench on the same scene and seed:
//   point          uniform random points in the scene box
//   box<f>%        cubes of side f % of the scene diagonal, centred on the AABB centre of a random object
// Each workload has `--queries` queries. The store (paged file, zstd, default build parameters) is built into
// `--dir` unless `--reuse` finds it there; it is opened with a cache of `--cache-mib` (64: peers_bench's
// warm cache) and one pass fills it. Then `--passes` rounds each time one mktree pass (Database::Run) and one
// Boost.Geometry pass (query, ids copied and sorted, as peers_bench's reference does), alternated; the best
// pass of each is reported. Every mktree answer is compared with Boost's (exit 1 on a difference).
//
// Usage: warm_bench --scene FILE|tanker:N[:SEED] [--dir DIR] [--reuse] [--queries Q] [--passes K]
//                   [--seed S] [--cache-mib M] [--only WORKLOAD] [--engine both|mktree|boost]
// `--only box1% --engine mktree --passes 2000` is the loop to run under perf record.
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
#include "engine/scene/scene_source.h"
#include "mktree/database.h"

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;

namespace mktree {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

using BPoint = bg::model::point<float, 3, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using BValue = std::pair<BBox, ObjectId>;
using BTree = bgi::rtree<BValue, bgi::rstar<16>>;

struct Args {
  std::string scene, dir = "/tmp", only, engine = "both";
  bool reuse = false;
  size_t queries = 200, passes = 20;
  uint64_t seed = 1, cache_mib = 64;
};

struct Workload {
  std::string name;
  std::vector<Query> queries;
};

Result<std::unique_ptr<SceneSource>> OpenScene(const std::string& spec, ObjectId first) {
  if (spec.rfind("tanker:", 0) == 0) {
    uint64_t n = 0, seed = 1;
    if (std::sscanf(spec.c_str(), "tanker:%lu:%lu", &n, &seed) < 1 || n == 0)
      return Status::InvalidArgument("scene '" + spec + "': expected tanker:N[:SEED]");
    return MakeTankerSource(n, seed, first);
  }
  return OpenSceneFile(spec, first);
}

double F(double x) { return static_cast<double>(static_cast<float>(x)); }

// peers_bench's MakeWorkloads, every workload with the full count.
std::vector<Workload> MakeWorkloads(const std::vector<Box3f>& boxes, const Box3f& bounds, const Args& a) {
  double d2 = 0;
  for (int i = 0; i < 3; ++i) d2 += std::pow(static_cast<double>(bounds.max[i]) - bounds.min[i], 2);
  const double diag = std::sqrt(d2);
  std::mt19937_64 rng(a.seed * 7919 + 17);
  std::uniform_real_distribution<double> u(0, 1);
  std::uniform_int_distribution<size_t> pick(0, boxes.size() - 1);
  std::vector<Workload> w;
  Workload points{"point", {}};
  for (size_t i = 0; i < a.queries; ++i) {
    Vec3d p;
    for (int k = 0; k < 3; ++k) p[k] = F(bounds.min[k] + u(rng) * (bounds.max[k] - bounds.min[k]));
    points.queries.push_back(Query::Point(p));
  }
  w.push_back(points);
  for (double f : {0.0002, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05}) {
    char name[32];
    std::snprintf(name, sizeof name, "box%g%%", f * 100);
    Workload x{name, {}};
    const double side = f * diag;
    for (size_t i = 0; i < a.queries; ++i) {
      const Box3f& b = boxes[pick(rng)];
      Box3d q;
      for (int k = 0; k < 3; ++k) {
        const double c = 0.5 * (static_cast<double>(b.min[k]) + b.max[k]);
        q.min[k] = F(c - side / 2);
        q.max[k] = F(c + side / 2);
      }
      x.queries.push_back(Query::Box(q));
    }
    w.push_back(std::move(x));
  }
  return w;
}

void BoostQuery(const BTree& t, const Query& q, std::vector<BValue>* found, std::vector<ObjectId>* hits) {
  found->clear();
  if (q.kind == Query::Kind::kPoint)
    t.query(bgi::intersects(BPoint(static_cast<float>(q.point.x), static_cast<float>(q.point.y),
                                   static_cast<float>(q.point.z))),
            std::back_inserter(*found));
  else
    t.query(bgi::intersects(BBox(BPoint(static_cast<float>(q.box.min[0]), static_cast<float>(q.box.min[1]),
                                        static_cast<float>(q.box.min[2])),
                                 BPoint(static_cast<float>(q.box.max[0]), static_cast<float>(q.box.max[1]),
                                        static_cast<float>(q.box.max[2])))),
            std::back_inserter(*found));
  hits->clear();
  for (const BValue& v : *found) hits->push_back(v.second);
  std::sort(hits->begin(), hits->end());
}

int Main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto val = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "error: %s needs a value\n", k.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (k == "--scene")
      a.scene = val();
    else if (k == "--dir")
      a.dir = val();
    else if (k == "--reuse")
      a.reuse = true;
    else if (k == "--queries")
      a.queries = std::stoul(val());
    else if (k == "--passes")
      a.passes = std::stoul(val());
    else if (k == "--seed")
      a.seed = std::stoul(val());
    else if (k == "--cache-mib")
      a.cache_mib = std::stoul(val());
    else if (k == "--only")
      a.only = val();
    else if (k == "--engine")
      a.engine = val();
    else {
      std::fprintf(
          stderr,
          "usage: warm_bench --scene FILE|tanker:N[:SEED] [--dir DIR] [--reuse] [--queries Q] "
          "[--passes K] [--seed S] [--cache-mib M] [--only WORKLOAD] [--engine both|mktree|boost]\n");
      return 2;
    }
  }
  if (a.scene.empty() || a.queries == 0 || a.passes == 0 ||
      (a.engine != "both" && a.engine != "mktree" && a.engine != "boost")) {
    std::fprintf(stderr,
                 "error: --scene is required; --queries and --passes > 0; --engine both|mktree|boost\n");
    return 2;
  }
  std::string stem = std::filesystem::path(a.scene).filename().string();
  std::replace(stem.begin(), stem.end(), ':', '_');
  const std::string path = a.dir + "/warm_bench_" + stem + ".mkt";

  std::vector<Box3f> boxes;
  Box3f bounds;
  {
    auto src = OpenScene(a.scene, 0);
    if (!src.ok()) {
      std::fprintf(stderr, "error: %s\n", src.status().ToString().c_str());
      return 1;
    }
    SceneObject o;
    for (;;) {
      auto more = (*src)->Next(&o);
      if (!more.ok()) {
        std::fprintf(stderr, "error: %s\n", more.status().ToString().c_str());
        return 1;
      }
      if (!*more) break;
      boxes.push_back(o.Aabb());
      bounds.Extend(boxes.back());
    }
  }
  if (boxes.empty()) {
    std::fprintf(stderr, "error: scene %s has no objects\n", a.scene.c_str());
    return 1;
  }
  if (!a.reuse || !std::filesystem::exists(path)) {
    IngestOptions opts;
    opts.store.backend = Backend::kPagedFile;
    opts.store.codec.codec = Codec::kZstd;
    opts.spill_dir = a.dir;
    auto built = BuildStore({[&](ObjectId first) { return OpenScene(a.scene, first); }}, path, opts);
    if (!built.ok()) {
      std::fprintf(stderr, "error: build %s: %s\n", path.c_str(), built.status().ToString().c_str());
      return 1;
    }
  }
  OpenOptions oo;
  oo.cache_pages = a.cache_mib * (uint64_t{1} << 20) / 12288;
  auto db = Database::Open(path, oo);
  if (!db.ok()) {
    std::fprintf(stderr, "error: %s\n", db.status().ToString().c_str());
    return 1;
  }
  std::vector<BValue> values;
  for (size_t i = 0; i < boxes.size(); ++i)
    values.emplace_back(BBox(BPoint(boxes[i].min[0], boxes[i].min[1], boxes[i].min[2]),
                             BPoint(boxes[i].max[0], boxes[i].max[1], boxes[i].max[2])),
                        static_cast<ObjectId>(i));
  const BTree boost(values.begin(), values.end());

  std::printf(
      "warm_bench: scene %s (%zu objects), store %s, seed %lu, %zu queries a workload, %zu passes, "
      "cache %lu MiB, one thread\n",
      a.scene.c_str(), boxes.size(), path.c_str(), a.seed, a.queries, a.passes, a.cache_mib);
  std::printf("%-9s %9s %12s %12s %7s %12s %12s\n", "workload", "hits/q", "mktree q/s", "boost q/s", "ratio",
              "mktree cpu/q", "boost cpu/q");
  std::vector<BValue> found;
  std::vector<ObjectId> expected;
  QueryResult r;
  for (const Workload& w : MakeWorkloads(boxes, bounds, a)) {
    if (!a.only.empty() && w.name != a.only) continue;
    double hits = 0;
    for (const Query& q : w.queries) {  // fills the cache; checks the answers
      BoostQuery(boost, q, &found, &expected);
      if (Status st = (*db)->Run(q, &r); !st.ok()) {
        std::fprintf(stderr, "error: %s\n", st.ToString().c_str());
        return 1;
      }
      if (r.hits != expected) {
        std::fprintf(stderr, "error: %s: mktree answered %zu ids, Boost.Geometry %zu\n", w.name.c_str(),
                     r.hits.size(), expected.size());
        return 1;
      }
      hits += static_cast<double>(expected.size());
    }
    double best_m = 1e30, best_b = 1e30, cpu_m = 1e30, cpu_b = 1e30;
    for (size_t pass = 0; pass < a.passes; ++pass) {
      if (a.engine != "boost") {
        const double c = CpuSeconds();
        const auto t = Clock::now();
        for (const Query& q : w.queries)
          if (!(*db)->Run(q, &r).ok()) return 1;
        best_m = std::min(best_m, Since(t));
        cpu_m = std::min(cpu_m, CpuSeconds() - c);
      }
      if (a.engine != "mktree") {
        const double c = CpuSeconds();
        const auto t = Clock::now();
        for (const Query& q : w.queries) BoostQuery(boost, q, &found, &expected);
        best_b = std::min(best_b, Since(t));
        cpu_b = std::min(cpu_b, CpuSeconds() - c);
      }
    }
    const double n = static_cast<double>(w.queries.size());
    auto qps = [n](double best) { return best < 1e30 ? n / best : 0.0; };
    auto cpu = [n](double best) { return best < 1e30 ? 1e6 * best / n : 0.0; };
    std::printf("%-9s %9.1f %12.0f %12.0f %7.2f %10.2fus %10.2fus\n", w.name.c_str(), hits / n, qps(best_m),
                qps(best_b), best_m < 1e30 && best_b < 1e30 ? best_b / best_m : 0.0, cpu(cpu_m), cpu(cpu_b));
  }
  return 0;
}

}  // namespace
}  // namespace mktree

int main(int argc, char** argv) { return mktree::Main(argc, argv); }
