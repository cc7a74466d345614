// tree_build_bench: MKtree construction from in-RAM records, and the routing quality of the result.
//
// Workloads (each runs in its own forked process, so that its peak RSS is its own):
//   tanker_100k      100,000 objects (for instruction-level profiles: valgrind --tool=callgrind)
//   tanker_1m        1,000,000 objects of MakeTankerSource(1e6, seed 1), BuildTuning defaults
//                    (SplitPolicy::kCompact) on 1 thread
//   tanker_1m_2t     the same, two threads
//   tanker_1m_soafill  the same, SplitPolicy::kSoa with the page-fill-aware ranking near the leaves
//   tanker_1m_soa    the same, plain SOA (docs/design.md §3.5, exactly): the fill baseline
//   tanker_10m       10,000,000 objects of MakeTankerSource(1e7, seed 1)
//   tanker_10m_2t    the same, two threads
//   synthetic_1m     1,000,000 synthetic records (pipes / plates / equipment boxes; no generator)
//   tanker_1m_packing  (only when named) the MKtree's leaves against Morton and STR packings of the same
//                    records into pages of the same budget: leaves holding an answer per point / box query
//                    against the floor ceil(hits / B)
//   random_tunings   (only when named) one hash over 400 small builds (seed 11): random scenes of 1 to 6000
//                    objects (uniform, gridded with many ties, clustered with long objects, all identical at
//                    +-0) under random BuildParams / BuildTuning (r, page size, fill slack, fill pages, kSoa,
//                    axis ratio 0), so that a change meant to keep the tree (a speed-up) is checked beyond
//                    the default tuning of the workloads above (its hash: bench/README.md, tree_build_bench)
//   random_tunings_spilled  (only when named) the same 400 builds with the out-of-core top levels forced
//                    (BuildTuning::ram_node_objects 1 to 400): the same hash as random_tunings
// Usage: tree_build_bench [workload...]   (default: all of them)
//
// Records: id, Aabb() and encoded_bytes = 64 + mesh.RawGeometryBytes() / 2, a stand-in for the compressed
// size that ingest will measure. Generating them is not timed.
// Measured: build wall time and objects/s; peak RSS (getrusage, the process's whole life: records 32 B/object
// plus everything the builder holds) in B/object; RAM of internal nodes + SplitTrees in B/object; the tree's
// shape (TreeStats). Routing quality on 10,000 random points (seed 99) uniform in the scene box:
// "extra leaves" = mean over points of (leaves reached - distinct leaves holding an object whose AABB
// contains the point), and the share of points reaching more than one leaf. Box quality: cubes of side 2 m
// and 8 m centred uniformly in the scene box (seed 7), distinct leaves holding an answer (= leaves read
// with the leaf filter) against the floor ceil(hits / objects per page).
// Targets: >= 2M objects/s at 1M, <= 60 B/object peak while building (issue 21; bench/README.md says where
// it stands), <= 16 B/object for the index.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/tree/leaf_filter.h"
#include "engine/tree/mktree_builder.h"
#include "engine/tree/page_budget.h"

namespace mktree {
namespace {

double PeakRssBytes() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_maxrss) * 1024.0;  // Linux: kilobytes
}

std::vector<BuildObject> TankerRecords(uint64_t n, uint64_t seed) {
  std::vector<BuildObject> recs;
  recs.reserve(n);
  auto src = MakeTankerSource(n, seed);
  SceneObject obj;
  for (;;) {
    auto more = src->Next(&obj);
    if (!more.ok()) {
      std::fprintf(stderr, "error: %s\n", more.status().ToString().c_str());
      std::exit(1);
    }
    if (!*more) break;
    BuildObject r;
    r.id = obj.id;
    r.box = obj.Aabb();
    r.encoded_bytes = static_cast<uint32_t>(64 + obj.mesh.RawGeometryBytes() / 2);
    recs.push_back(r);
  }
  return recs;
}

// Realistic sizes without the generator: a 300 x 50 x 30 m box of pipes (long, thin, axis-aligned),
// plates (thin) and equipment (chunky), encoded 400-3000 bytes.
std::vector<BuildObject> SyntheticRecords(uint64_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  auto uni = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  const double ext[3] = {300, 50, 30};
  std::vector<BuildObject> recs(n);
  for (uint64_t i = 0; i < n; ++i) {
    BuildObject& r = recs[i];
    r.id = static_cast<ObjectId>(i);
    const int cls = static_cast<int>(rng() % 10), along = static_cast<int>(rng() % 3);
    double size[3];
    for (int a = 0; a < 3; ++a) {
      if (cls < 6)
        size[a] = a == along ? std::exp(uni(std::log(0.3), std::log(40.0))) : uni(0.05, 0.5);
      else if (cls < 9)
        size[a] = a == along ? 0.01 : uni(0.5, 4);
      else
        size[a] = uni(0.5, 3);
      const double lo = uni(0, std::max(0.0, ext[a] - size[a]));
      r.box.min[a] = static_cast<float>(lo);
      r.box.max[a] = static_cast<float>(lo + size[a]);
    }
    r.encoded_bytes = static_cast<uint32_t>(cls < 6   ? uni(400, 1600)
                                            : cls < 9 ? uni(400, 900)
                                                      : uni(1000, 3000));
  }
  return recs;
}

struct Quality {
  double extra_leaves = 0;
  double multi_leaf_share = 0;
  double mean_leaves = 0;
  double mean_answer_leaves = 0;
  double mean_split_nodes = 0;
  double mean_leaf_boxes =
      0;  // leaves whose box contains the point (first 1,000 points): routing by boxes only
  double filtered_leaves = 0;  // leaves the leaf filter lets through (what a query reads)
  double filtered_extra = 0;   // of those, the ones without an answer (the target: <= 0.2)
  double filtered_multi_share = 0;
};

Quality RoutingQuality(const BuildResult& r, const std::vector<BuildObject>& recs, int points,
                       uint64_t seed) {
  Quality q;
  if (r.tree.empty()) return q;
  std::mt19937_64 rng(seed);
  const Box3f& root = r.tree.nodes[0].box;
  std::vector<uint32_t> leaves;
  uint64_t reached = 0, answer = 0, multi = 0, stabbed = 0, passed = 0, passed_multi = 0;
  // The tree with its leaf filter, as the store builder fills it (each leaf's objects quantized inside its
  // box): its RoutePoint drops the leaves the filter rules out, as a point query does.
  MKTree filtered = r.tree;
  filtered.leaf_filter.resize(uint64_t{kLeafFilterBytesPerObject} * r.leaf_objects.size());
  for (size_t l = 0; l < r.tree.leaves.size(); ++l)
    for (uint64_t k = r.leaf_offsets[l]; k < r.leaf_offsets[l + 1]; ++k)
      QuantizeBox(r.tree.leaves[l].box, recs[r.leaf_objects[k]].box,
                  &filtered.leaf_filter[k * kLeafFilterBytesPerObject]);
  if (!filtered.IndexLeafFilter()) std::abort();
  std::vector<uint32_t> passed_leaves;
  const int box_points = std::min(points, 1000);
  QueryStats st;
  for (int i = 0; i < points; ++i) {
    Vec3d p;
    for (int a = 0; a < 3; ++a) p[a] = std::uniform_real_distribution<double>(root.min[a], root.max[a])(rng);
    leaves.clear();
    r.tree.RoutePoint(p, &leaves, &st);
    if (i < box_points)
      for (const LeafInfo& lf : r.tree.leaves) stabbed += lf.box.Contains(p);
    reached += leaves.size();
    multi += leaves.size() > 1;
    for (uint32_t l : leaves) {
      for (uint64_t k = r.leaf_offsets[l]; k < r.leaf_offsets[l + 1]; ++k) {
        if (recs[r.leaf_objects[k]].box.Contains(p)) {  // ids are record indices here
          ++answer;
          break;
        }
      }
    }
    passed_leaves.clear();
    filtered.RoutePoint(p, &passed_leaves, nullptr);
    passed += passed_leaves.size();
    passed_multi += passed_leaves.size() > 1;
  }
  q.mean_leaves = double(reached) / points;
  q.mean_answer_leaves = double(answer) / points;
  q.extra_leaves = double(reached - answer) / points;
  q.multi_leaf_share = double(multi) / points;
  q.mean_split_nodes = double(st.split_nodes_visited) / points;
  q.mean_leaf_boxes = double(stabbed) / box_points;
  q.filtered_leaves = double(passed) / points;
  q.filtered_extra = double(passed - answer) / points;  // a leaf with an answer always passes
  q.filtered_multi_share = double(passed_multi) / points;
  return q;
}

// Box queries: mean over cubes of side `side` centred uniformly in the scene box of the distinct leaves
// holding an object whose AABB meets the cube (what a query reads once the leaf filter has dropped the
// leaves without an answer), and of the I/O floor ceil(hits / B), B = objects per page.
struct BoxQuality {
  double leaves = 0;
  double floor = 0;
};

// leaf_of[k]: the leaf (page group) of record k, of `leaves`; B = records / pages.
BoxQuality BoxLeaves(const std::vector<uint32_t>& leaf_of, size_t leaves, double per_page, const Box3f& scene,
                     const std::vector<BuildObject>& recs, double side, int count, uint64_t seed) {
  BoxQuality q;
  std::mt19937_64 rng(seed);
  std::vector<uint32_t> seen(leaves, 0);
  for (int i = 1; i <= count; ++i) {
    Box3f b;
    for (int a = 0; a < 3; ++a) {
      const double c = std::uniform_real_distribution<double>(scene.min[a], scene.max[a])(rng);
      b.min[a] = static_cast<float>(c - side / 2);
      b.max[a] = static_cast<float>(c + side / 2);
    }
    uint64_t hits = 0;
    for (size_t k = 0; k < recs.size(); ++k) {
      if (!recs[k].box.Intersects(b)) continue;
      ++hits;
      if (seen[leaf_of[k]] != static_cast<uint32_t>(i)) {
        seen[leaf_of[k]] = static_cast<uint32_t>(i);
        q.leaves += 1;
      }
    }
    q.floor += std::ceil(double(hits) / per_page);
  }
  q.leaves /= count;
  q.floor /= count;
  return q;
}

std::vector<uint32_t> LeafOf(const BuildResult& r, size_t objects) {
  std::vector<uint32_t> leaf_of(objects);
  for (uint32_t l = 0; l < r.tree.leaves.size(); ++l)
    for (uint64_t k = r.leaf_offsets[l]; k < r.leaf_offsets[l + 1]; ++k) leaf_of[r.leaf_objects[k]] = l;
  return leaf_of;
}

BoxQuality BoxLeaves(const BuildResult& r, const std::vector<BuildObject>& recs, double side, int count,
                     uint64_t seed) {
  if (r.tree.empty()) return BoxQuality{};
  return BoxLeaves(LeafOf(r, recs.size()), r.tree.leaves.size(), double(recs.size()) / double(r.stats.pages),
                   r.tree.nodes[0].box, recs, side, count, seed);
}

// Packing baselines: the records cut into one-page leaves in a given order, greedily by encoded bytes
// (the page budget the MKtree uses). Returns leaf_of and sets *leaves.
std::vector<uint32_t> PackInOrder(const std::vector<BuildObject>& recs, const std::vector<uint32_t>& order,
                                  uint64_t mem_page, size_t* leaves) {
  std::vector<uint32_t> leaf_of(recs.size());
  uint64_t bytes = 0;
  uint32_t leaf = 0;
  bool empty = true;
  for (uint32_t k : order) {
    const uint64_t b = recs[k].encoded_bytes;
    if (!empty && !FitsInOnePage(bytes + b, mem_page)) {
      ++leaf;
      bytes = 0;
    }
    bytes += b;
    empty = false;
    leaf_of[k] = leaf;
  }
  *leaves = recs.empty() ? 0 : leaf + 1;
  return leaf_of;
}

float Centre(const BuildObject& r, int a) { return 0.5f * (r.box.min[a] + r.box.max[a]); }

// Z-order (Morton) of the box centres, 21 bits per axis.
std::vector<uint32_t> MortonOrder(const std::vector<BuildObject>& recs, const Box3f& scene) {
  auto spread = [](uint64_t v) {
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffull;
    v = (v | v << 16) & 0x1f0000ff0000ffull;
    v = (v | v << 8) & 0x100f00f00f00f00full;
    v = (v | v << 4) & 0x10c30c30c30c30c3ull;
    v = (v | v << 2) & 0x1249249249249249ull;
    return v;
  };
  std::vector<std::pair<uint64_t, uint32_t>> keyed(recs.size());
  for (uint32_t k = 0; k < recs.size(); ++k) {
    uint64_t code = 0;
    for (int a = 0; a < 3; ++a) {
      const double ext = double{scene.max[a]} - scene.min[a];
      const double f = ext > 0 ? (Centre(recs[k], a) - scene.min[a]) / ext : 0;
      code |= spread(static_cast<uint64_t>(std::clamp(f, 0.0, 1.0) * 2097151.0)) << a;
    }
    keyed[k] = {code, k};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<uint32_t> order(recs.size());
  for (size_t i = 0; i < keyed.size(); ++i) order[i] = keyed[i].second;
  return order;
}

// Sort-Tile-Recursive on the box centres (what R-tree bulk loaders such as libspatialindex's use): S slabs
// along x, S strips along y in each, then z order, S = cbrt(expected pages).
std::vector<uint32_t> StrOrder(const std::vector<BuildObject>& recs, uint64_t mem_page) {
  uint64_t total = 0;
  for (const BuildObject& r : recs) total += r.encoded_bytes;
  const double pages = std::max(1.0, double(total) / double(PagePayloadCapacity(mem_page)));
  const size_t s = std::max<size_t>(1, static_cast<size_t>(std::ceil(std::cbrt(pages))));
  std::vector<uint32_t> order(recs.size());
  for (uint32_t k = 0; k < recs.size(); ++k) order[k] = k;
  auto by = [&](int a) {
    return [&recs, a](uint32_t x, uint32_t y) { return Centre(recs[x], a) < Centre(recs[y], a); };
  };
  std::sort(order.begin(), order.end(), by(0));
  const size_t slab = (order.size() + s - 1) / s;
  for (size_t i = 0; i < order.size(); i += slab) {
    const auto first = order.begin() + i, last = order.begin() + std::min(order.size(), i + slab);
    std::sort(first, last, by(1));
    const size_t strip = (size_t(last - first) + s - 1) / s;
    for (auto j = first; j < last; j += std::min<ptrdiff_t>(strip, last - j))
      std::sort(j, std::min(last, j + strip), by(2));
  }
  return order;
}

// FNV-1a over every field of the built tree (nodes, split nodes, leaves, leaf_objects, leaf_offsets), field
// by field so that struct padding does not count: equal hashes = the same tree (TREE_BENCH_HASH=1 prints it).
struct Fnv {
  uint64_t h = 1469598103934665603ull;
  template <typename T>
  void Add(const T& v) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, &v, sizeof(T));
    for (unsigned char c : bytes) h = (h ^ c) * 1099511628211ull;
  }
  void AddBox(const Box3f& b) {
    for (int a = 0; a < 3; ++a) Add(b.min[a]), Add(b.max[a]);
  }
};

uint64_t TreeHash(const BuildResult& r) {
  Fnv f;
  for (const TreeNode& n : r.tree.nodes) {
    f.AddBox(n.box);
    f.Add(n.a), f.Add(n.b), f.Add(n.child[0]), f.Add(n.child[1]), f.Add(n.leaf), f.Add(n.split_root);
    f.Add(n.axis), f.Add(n.depth);
  }
  for (const SplitNode& n : r.tree.split_nodes)
    f.Add(n.cut), f.Add(n.child[0]), f.Add(n.child[1]), f.Add(n.axis), f.Add(n.label);
  for (const LeafInfo& l : r.tree.leaves) {
    f.AddBox(l.box);
    f.Add(l.node), f.Add(l.object_count), f.Add(l.payload_bytes), f.Add(l.first_page), f.Add(l.page_count);
  }
  for (ObjectId o : r.leaf_objects) f.Add(o);
  for (uint64_t o : r.leaf_offsets) f.Add(o);
  return f.h;
}

struct Workload {
  const char* name;
  uint64_t objects;
  bool tanker;
  int threads;
  bool fill_aware;
  SplitPolicy policy;
};

void Run(const Workload& w) {
  std::vector<BuildObject> recs = w.tanker ? TankerRecords(w.objects, 1) : SyntheticRecords(w.objects, 1);
  const double rss_records = PeakRssBytes();
  BuildTuning tune;
  tune.threads = w.threads;
  tune.fill_aware = w.fill_aware;
  tune.split_policy = w.policy;
  // TREE_BENCH_RAM_NODES=k: BuildTuning::ram_node_objects (nodes of more objects keep their lists on disk).
  if (const char* ram = std::getenv("TREE_BENCH_RAM_NODES")) tune.ram_node_objects = std::atoi(ram);
  // TREE_BENCH_REPEAT=k: k more builds of copies of the same records first, timed alone (for A/B runs on a
  // noisy machine; the peak RSS of the main build then includes the copy).
  if (const char* rep = std::getenv("TREE_BENCH_REPEAT")) {
    for (int i = 0, k = std::atoi(rep); i < k; ++i) {
      std::vector<BuildObject> copy = recs;
      const auto r0 = std::chrono::steady_clock::now();
      auto b = BuildMKTree(std::move(copy), BuildParams(), tune);
      const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - r0).count();
      if (!b.ok()) std::exit(1);
      const BuildTimings& tm = b->timings;
      std::printf("%-14s repeat %6.3f s  (layout %.3f sorts %.3f nodes %.3f finish %.3f s; stitch %.3f)\n",
                  w.name, sec, tm.layout, tm.sorts, tm.nodes, tm.finish, tm.stitch);
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  auto built = BuildMKTree(std::move(recs), BuildParams(), tune);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double peak = PeakRssBytes();
  if (!built.ok()) {
    std::fprintf(stderr, "error: %s\n", built.status().ToString().c_str());
    std::exit(1);
  }
  const TreeStats& s = built->stats;
  const double n = double(w.objects);
  if (std::getenv("TREE_BENCH_HASH")) {
    const BuildTimings& tm = built->timings;
    std::printf(
        "%-14s %6.2f s  %6.2f Mobj/s  peak %6.1f B/obj  tree hash %016llx  nodes %zu  split nodes %zu"
        "  leaves %zu  (layout %.3f sorts %.3f nodes %.3f finish %.3f s; stitch %.3f of nodes;"
        " peak B/obj at the end of layout %.1f sorts %.1f nodes %.1f finish %.1f)\n",
        w.name, secs, n / secs / 1e6, peak / n, (unsigned long long)TreeHash(*built),
        built->tree.nodes.size(), built->tree.split_nodes.size(), built->tree.leaves.size(), tm.layout,
        tm.sorts, tm.nodes, tm.finish, tm.stitch, tm.peak_layout / n, tm.peak_sorts / n, tm.peak_nodes / n,
        tm.peak_finish / n);
    std::fflush(stdout);
    if (std::getenv("TREE_BENCH_HASH_ONLY")) return;
  }
  // The records went into the builder; make them again (deterministic) for the brute-force check.
  recs = w.tanker ? TankerRecords(w.objects, 1) : SyntheticRecords(w.objects, 1);
  const Quality q = RoutingQuality(*built, recs, 10000, 99);
  std::printf(
      "%-14s %9llu obj  %6.2f s  %6.2f Mobj/s  peak %6.1f B/obj (records phase %5.1f)  index %5.2f B/obj"
      "  tree %5.2f B/obj\n",
      w.name, (unsigned long long)w.objects, secs, n / secs / 1e6, peak / n, rss_records / n,
      s.index_bytes_per_object, s.tree_bytes_per_object);
  std::printf(
      "%-14s phases: layout %.3f s  sorts %.3f s  nodes %.3f s (of which stitch %.3f s)  finish %.3f s"
      "  (peak B/obj at their ends %.1f %.1f %.1f %.1f)\n",
      "", built->timings.layout, built->timings.sorts, built->timings.nodes, built->timings.stitch,
      built->timings.finish, built->timings.peak_layout / n, built->timings.peak_sorts / n,
      built->timings.peak_nodes / n, built->timings.peak_finish / n);
  std::printf(
      "%-14s height %u  leaves %llu  obj/leaf %.2f  fill mean %.1f%% min %.1f%%  multi-page %llu"
      "  |Sm| %llu  SplitTree nodes %llu (max %u)  BOTH cells %llu/%llu\n",
      "", s.height, (unsigned long long)s.leaves, s.mean_objects_per_leaf, 100 * s.mean_page_fill,
      100 * s.min_page_fill, (unsigned long long)s.multi_page_leaves, (unsigned long long)s.overlap_objects,
      (unsigned long long)s.split_tree_nodes, s.max_split_tree_nodes, (unsigned long long)s.both_cells,
      (unsigned long long)s.split_tree_cells);
  std::printf(
      "%-14s routing: leaves/point %.3f  answer leaves/point %.3f  extra %.3f  >1 leaf %.1f%%"
      "  split nodes/point %.2f  (leaf boxes containing the point %.3f)\n",
      "", q.mean_leaves, q.mean_answer_leaves, q.extra_leaves, 100 * q.multi_leaf_share, q.mean_split_nodes,
      q.mean_leaf_boxes);
  std::printf(
      "%-14s with the leaf filter (what a query reads): leaves/point %.3f  extra %.3f (target <= 0.2)"
      "  >1 leaf %.1f%%\n",
      "", q.filtered_leaves, q.filtered_extra, 100 * q.filtered_multi_share);
  const int box_count = static_cast<int>(std::clamp<uint64_t>(300000000 / w.objects, 30, 300));
  std::printf("%-14s boxes (%d, seed 7): leaves with an answer", "", box_count);
  for (double side : {2.0, 8.0}) {
    const BoxQuality b = BoxLeaves(*built, recs, side, box_count, 7);
    std::printf("  side %.0f m: %.2f (floor %.2f)", side, b.leaves, b.floor);
  }
  std::printf("\n");
  if (std::getenv("TREE_BENCH_VERBOSE")) std::printf("%s", s.ToString().c_str());
  std::fflush(stdout);
}

// The MKtree's leaves against packing baselines over the same records and page budget: how far any
// partition of the objects into pages is from the floor ceil(hits / B) on the same queries.
void RunPacking(uint64_t objects) {
  std::vector<BuildObject> recs = TankerRecords(objects, 1);
  const BuildParams params;
  auto built = BuildMKTree(recs, params, BuildTuning());
  if (!built.ok()) {
    std::fprintf(stderr, "error: %s\n", built.status().ToString().c_str());
    std::exit(1);
  }
  const Box3f scene = built->tree.nodes[0].box;
  struct Partition {
    const char* name;
    std::vector<uint32_t> leaf_of;
    size_t leaves = 0;
    double pages = 0;
  };
  std::vector<Partition> parts;
  parts.push_back(
      {"mktree", LeafOf(*built, recs.size()), built->tree.leaves.size(), double(built->stats.pages)});
  for (const char* name : {"morton", "str"}) {
    Partition p{name, {}, 0, 0};
    const std::vector<uint32_t> order =
        std::strcmp(name, "morton") == 0 ? MortonOrder(recs, scene) : StrOrder(recs, params.mem_page());
    p.leaf_of = PackInOrder(recs, order, params.mem_page(), &p.leaves);
    p.pages = double(p.leaves);
    parts.push_back(std::move(p));
  }
  std::printf(
      "tanker_%llu_packing: leaves holding an answer per query / floor ceil(hits/B), same records and page "
      "budget; query centres uniform in the scene box (seed 7): 1000 points, 300 boxes per side\n",
      (unsigned long long)objects);
  std::printf("%-8s %8s %7s %16s %16s %16s %16s\n", "leaves", "count", "B", "point", "box 0.5 m", "box 2 m",
              "box 8 m");
  for (const Partition& p : parts) {
    const double per_page = double(recs.size()) / p.pages;
    std::printf("%-8s %8zu %7.2f", p.name, p.leaves, per_page);
    for (const auto& [side, count] : {std::pair{0.0, 1000}, {0.5, 300}, {2.0, 300}, {8.0, 300}}) {
      const BoxQuality b = BoxLeaves(p.leaf_of, p.leaves, per_page, scene, recs, side, count, 7);
      char cell[32];
      std::snprintf(cell, sizeof cell, "%.2f/%.2f=%.1fx", b.leaves, b.floor,
                    b.floor > 0 ? b.leaves / b.floor : 0);
      std::printf(" %16s", cell);
    }
    std::printf("\n");
    std::fflush(stdout);
  }
}

// See random_tunings in the header.
void RunRandomTunings(bool spilled) {
  std::mt19937_64 rng(11);
  std::mt19937_64 budgets(12);  // (its own stream: the scenes and tunings stay those of random_tunings)
  Fnv all;
  constexpr int kBuilds = 400;
  for (int t = 0; t < kBuilds; ++t) {
    const int n = 1 + static_cast<int>(rng() % 6000);
    const int kind = static_cast<int>(rng() % 4);
    std::vector<BuildObject> recs(n);
    for (int i = 0; i < n; ++i) {
      BuildObject& r = recs[i];
      r.id = static_cast<ObjectId>(i);
      for (int u = 0; u < 3; ++u) {
        float c, e;
        switch (kind) {
          case 0:
            c = std::uniform_real_distribution<float>(-50, 50)(rng),
            e = std::uniform_real_distribution<float>(0, 3)(rng);
            break;
          case 1:
            c = static_cast<float>(rng() % 20), e = static_cast<float>(rng() % 3);
            break;
          case 2:
            c = std::normal_distribution<float>(0, 5)(rng), e = rng() % 10 == 0 ? 40.0f : 0.2f;
            break;
          default:
            c = rng() % 2 ? 0.0f : -0.0f, e = 0;
        }
        r.box.min[u] = c;
        r.box.max[u] = c + e;
      }
      r.encoded_bytes = static_cast<uint32_t>(64 + rng() % 3000);
    }
    BuildParams params;
    params.balance_r = rng() % 3 == 0 ? 0.0 : (rng() % 2 ? 0.3 : 0.45);
    params.blocks_per_page = static_cast<uint32_t>(1 + rng() % 3);
    BuildTuning tuning;
    tuning.threads = 1;
    if (rng() % 2) tuning.fill_sm_slack = static_cast<uint32_t>(rng() % 8);
    if (rng() % 3 == 0) tuning.fill_sm_slack_rel = 0.05;
    if (rng() % 4 == 0) tuning.fill_aware_pages = static_cast<uint32_t>(2 + rng() % 30);
    if (rng() % 5 == 0) tuning.split_policy = SplitPolicy::kSoa;
    if (rng() % 5 == 0) tuning.compact_axis_ratio = 0.0;
    if (spilled) tuning.ram_node_objects = static_cast<uint32_t>(1 + budgets() % 400);
    auto built = BuildMKTree(std::move(recs), params, tuning);
    if (!built.ok()) {
      std::fprintf(stderr, "error: random_tunings build %d: %s\n", t, built.status().ToString().c_str());
      std::exit(1);
    }
    all.Add(TreeHash(*built));
  }
  std::printf("random_tunings%s: %d builds, hash %016llx\n", spilled ? "_spilled" : "", kBuilds,
              static_cast<unsigned long long>(all.h));
  std::fflush(stdout);
}

}  // namespace
}  // namespace mktree

int main(int argc, char** argv) {
  using mktree::Workload;
  constexpr mktree::SplitPolicy kSoa = mktree::SplitPolicy::kSoa, kCompact = mktree::SplitPolicy::kCompact;
  const Workload all[] = {
      {"tanker_100k", 100000, true, 1, true, kCompact},
      {"tanker_1m", 1000000, true, 1, true, kCompact},
      {"tanker_1m_2t", 1000000, true, 2, true, kCompact},
      {"tanker_1m_soafill", 1000000, true, 1, true, kSoa},
      {"tanker_1m_soa", 1000000, true, 1, false, kSoa},
      {"tanker_10m", 10000000, true, 1, true, kCompact},
      {"tanker_10m_2t", 10000000, true, 2, true, kCompact},
      {"synthetic_1m", 1000000, false, 1, true, kCompact},
  };
#ifndef NDEBUG
  std::printf("WARNING: built without optimisation (NDEBUG not defined); timings are not meaningful\n");
#endif
  std::printf(
      "tree_build_bench: MKtree construction from in-RAM records (BuildParams defaults: MemPage 12288 B,"
      " r 0.3, SplitTree budget 64)\n");
  std::printf(
      "records: tanker generator seed 1, encoded_bytes = 64 + RawGeometryBytes/2; 10,000 query points seed "
      "99\n");
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "tanker_1m_packing") == 0) mktree::RunPacking(1000000);
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "random_tunings") == 0) mktree::RunRandomTunings(false);
    if (std::strcmp(argv[i], "random_tunings_spilled") == 0) mktree::RunRandomTunings(true);
  }
  for (const Workload& w : all) {
    bool wanted = argc == 1;
    for (int i = 1; i < argc; ++i) wanted |= std::strcmp(argv[i], w.name) == 0;
    if (!wanted) continue;
    std::fflush(stdout);
    const pid_t pid = fork();
    if (pid == 0) {
      mktree::Run(w);
      std::_Exit(0);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      std::fprintf(stderr, "error: workload %s failed\n", w.name);
      return 1;
    }
  }
  return 0;
}
