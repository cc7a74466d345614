// peers_bench: mktree against libspatialindex (R*-tree, STR bulk load, disk storage), SQLite R*Tree
// (rtree virtual table + geometry table) and Boost.Geometry's rtree (in RAM), on one scene, in one run.
//
// Workloads (seeded; `--seed`):
//   point          uniform random points in the scene box
//   box<f>%        cubes of side f % of the scene diagonal, centred on the AABB centre of a random object
//                  (a sweep of sizes; 0.1 %, 1 % and 5 % are the headline ones)
//   box<s>m        tanker only: cubes of side 0.5, 2 and 8 m, centred the same way
// Engines: mktree-{pagefile,hdf5}-{zstd,none}, libspatialindex, sqlite-rtree, boost-rtree. Each file engine
// is built in a child process (build time, objects/s, its own peak RSS, file size), then queried cold
// (engine cache emptied and OS cache bypassed or dropped before each query: pages read mean/p50/p99 against
// the I/O floor ceil(T / B), KiB read, queries/s) and warm (64 MiB cache, second pass, queries/s).
// Every engine's AABB answers are checked against Boost.Geometry's (itself checked against a brute-force
// scan on the first queries of each workload); any mismatch fails the run (exit 1).
//
// Usage: peers_bench --scene tanker:N:SEED|FILE [--name NAME] [--queries Q] [--seed S] [--dir WORKDIR]
//                    [--out OUTDIR] [--engines a,b,...] [--smoke] [--keep]
//        peers_bench --versions
// Writes OUTDIR/NAME.md (tables) and OUTDIR/NAME.tsv (rows for scripts/plot_bench.py); prints progress.
#include <fcntl.h>
#include <hdf5.h>
#include <spatialindex/Version.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <boost/version.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bench/peak_rss.h"
#include "bench/peer_engine.h"
#include "engine/generator/tanker_generator.h"
#include "engine/ingest/store_builder.h"
#include "engine/store_format/store_file.h"
#include "mktree/database.h"

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;

namespace mktree::bench {

Result<std::unique_ptr<SceneSource>> SceneSpec::Open(ObjectId first_id) const {
  if (spec.rfind("tanker:", 0) == 0) {
    uint64_t n = 0, seed = 1;
    if (std::sscanf(spec.c_str(), "tanker:%lu:%lu", &n, &seed) < 1 || n == 0)
      return Status::InvalidArgument("scene '" + spec + "': expected tanker:N[:SEED]");
    return MakeTankerSource(n, seed, first_id);
  }
  return OpenSceneFile(spec, first_id);
}

void EncodePeerEntry(const SceneObject& obj, const CodecOptions& codec, std::vector<uint8_t>* out) {
  EncodeObjectEntry(obj, codec, out);
}

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

using BPoint = bg::model::point<float, 3, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using BValue = std::pair<BBox, ObjectId>;
using BTree = bgi::rtree<BValue, bgi::rstar<16>>;

// ---- mktree ----

class MktreeEngine : public Engine {
 public:
  MktreeEngine(const std::string& dir, Backend backend, Codec codec) : backend_(backend), codec_(codec) {
    path_ =
        dir + "/peer_mktree_" + BackendName(backend) + (codec == Codec::kZstd ? "_zstd" : "_none") + ".mkt";
  }
  std::string name() const override {
    return std::string("mktree-") + BackendName(backend_) + (codec_ == Codec::kZstd ? "-zstd" : "-none");
  }
  std::vector<std::string> files() const override { return {path_}; }
  std::string cold_method() const override {
    return backend_ == Backend::kPagedFile
               ? "ClearCache() and O_DIRECT page reads" + (notice_.empty() ? "" : " (" + notice_ + ")")
               : std::string(
                     "ClearCache() and posix_fadvise(DONTNEED) before each query (HDF5 reads are buffered)");
  }
  Status Build(const SceneSpec& scene, Facts* facts) override {
    IngestOptions opts;
    opts.store.backend = backend_;
    opts.store.codec.codec = codec_;
    opts.spill_dir = std::filesystem::path(path_).parent_path().string();
    MKTREE_ASSIGN_OR_RETURN(const IngestReport report,
                            BuildStore({[&](ObjectId first) { return scene.Open(first); }}, path_, opts));
    MKTREE_ASSIGN_OR_RETURN(auto db, Database::Open(path_));
    (*facts)["objects"] = static_cast<double>(report.objects);
    (*facts)["pages"] = static_cast<double>(report.pages);
    (*facts)["leaves"] = static_cast<double>(report.tree_stats.leaves);
    (*facts)["B"] = db->objects_per_page();
    return Status::Ok();
  }
  Status Open(bool warm, const Facts&) override {
    OpenOptions o;
    o.cache_pages = (warm ? kWarmCacheBytes : kColdCacheBytes) / kPageBytes;
    o.direct_io = !warm && backend_ == Backend::kPagedFile;
    if (o.direct_io) {
      ReadOptions ro;
      ro.direct_io = true;
      MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(path_, ro));
      notice_ = reader->notice();
    }
    MKTREE_ASSIGN_OR_RETURN(db_, Database::Open(path_, o));
    return Status::Ok();
  }
  void Close() override { db_.reset(); }
  void ClearCache() override { db_->ClearCache(); }
  Status Run(const Query& q, std::vector<ObjectId>* hits, Io* io) override {
    QueryResult r;  // in the caller's buffer; q is in AABB mode (Query's default), as the peers answer
    r.hits.swap(*hits);
    Status st = db_->Run(q, &r);
    hits->swap(r.hits);
    io->pages = r.stats.pages_read;
    io->inner_pages = 0;  // internal nodes and SplitTrees are in RAM
    io->bytes = r.stats.bytes_read;
    return st;
  }
  double objects_per_page(const Facts& f) const override { return f.at("B"); }

 private:
  Backend backend_;
  Codec codec_;
  std::string path_, notice_;
  std::unique_ptr<Database> db_;
};

// ---- Boost.Geometry (in RAM; no pages, no cold phase) ----

BBox ToBBox(const Box3f& b) {
  return BBox(BPoint(b.min[0], b.min[1], b.min[2]), BPoint(b.max[0], b.max[1], b.max[2]));
}

void BoostQuery(const BTree& t, const Query& q, std::vector<ObjectId>* hits) {
  static thread_local std::vector<BValue> found;
  found.clear();
  if (q.kind == Query::Kind::kPoint)
    t.query(bgi::intersects(BPoint(static_cast<float>(q.point.x), static_cast<float>(q.point.y),
                                   static_cast<float>(q.point.z))),
            std::back_inserter(found));
  else
    t.query(bgi::intersects(BBox(BPoint(static_cast<float>(q.box.min[0]), static_cast<float>(q.box.min[1]),
                                        static_cast<float>(q.box.min[2])),
                                 BPoint(static_cast<float>(q.box.max[0]), static_cast<float>(q.box.max[1]),
                                        static_cast<float>(q.box.max[2])))),
            std::back_inserter(found));
  hits->clear();
  for (const BValue& v : found) hits->push_back(v.second);
  std::sort(hits->begin(), hits->end());
}

class BoostEngine : public Engine {
 public:
  explicit BoostEngine(const std::vector<Box3f>* boxes) : boxes_(boxes) {}
  std::string name() const override { return "boost-rtree"; }
  std::vector<std::string> files() const override { return {}; }
  std::string cold_method() const override { return "in RAM (no cold phase)"; }
  Status Build(const SceneSpec& scene, Facts* facts) override {
    // Stream the scene as the others do, keep only AABBs, build with the packing constructor.
    MKTREE_ASSIGN_OR_RETURN(auto src, scene.Open(0));
    std::vector<BValue> values;
    SceneObject o;
    for (;;) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, src->Next(&o));
      if (!more) break;
      values.emplace_back(ToBBox(o.Aabb()), o.id);
    }
    BTree t(values.begin(), values.end());
    (*facts)["objects"] = static_cast<double>(t.size());
    return Status::Ok();
  }
  Status Open(bool, const Facts&) override {
    if (!tree_) {
      std::vector<BValue> values;
      values.reserve(boxes_->size());
      for (size_t i = 0; i < boxes_->size(); ++i)
        values.emplace_back(ToBBox((*boxes_)[i]), static_cast<ObjectId>(i));
      tree_ = std::make_unique<BTree>(values.begin(), values.end());
    }
    return Status::Ok();
  }
  void Close() override {}
  void ClearCache() override {}
  Status Run(const Query& q, std::vector<ObjectId>* hits, Io* io) override {
    BoostQuery(*tree_, q, hits);
    *io = Io();
    return Status::Ok();
  }
  double objects_per_page(const Facts&) const override { return 0; }

 private:
  const std::vector<Box3f>* boxes_;
  std::unique_ptr<BTree> tree_;
};

// ---- driver ----

struct Args {
  std::string scene;
  std::string name;
  size_t queries = 200;
  uint64_t seed = 1;
  std::string dir = "/work/tmp-bench";
  std::string out = ".";
  std::string engines =
      "mktree-pagefile-zstd,mktree-pagefile-none,mktree-hdf5-zstd,mktree-hdf5-none,"
      "libspatialindex,sqlite-rtree,boost-rtree";
  bool smoke = false;
  bool keep = false;
  // libspatialindex capacities (computed by the parent from the scene, passed to build children)
  uint32_t lsi_leaf = 0, lsi_index = 0;
  std::string child_engine;
};

struct Workload {
  std::string name;
  double frac = 0;    // box side / scene diagonal (0 for points and absolute sizes)
  double side_m = 0;  // box side in scene units (0 for points)
  std::vector<Query> queries;
};

struct SceneInfo {
  std::vector<Box3f> boxes;  // by id
  Box3f bounds;
  double diag = 0;
  double entry_mean = 0, entry_sd = 0;  // encoded entry bytes (zstd), sampled
  uint64_t entries_sampled = 0;
};

std::unique_ptr<Engine> MakeEngine(const std::string& name, const Args& a, const std::vector<Box3f>* boxes) {
  const CodecOptions zstd;  // the codec every peer stores its geometry with: mktree's default
  if (name == "mktree-pagefile-zstd")
    return std::make_unique<MktreeEngine>(a.dir, Backend::kPagedFile, Codec::kZstd);
  if (name == "mktree-pagefile-none")
    return std::make_unique<MktreeEngine>(a.dir, Backend::kPagedFile, Codec::kNone);
  if (name == "mktree-hdf5-zstd") return std::make_unique<MktreeEngine>(a.dir, Backend::kHdf5, Codec::kZstd);
  if (name == "mktree-hdf5-none") return std::make_unique<MktreeEngine>(a.dir, Backend::kHdf5, Codec::kNone);
  if (name == "libspatialindex") return MakeSpatialIndexEngine(a.dir, zstd, a.lsi_leaf, a.lsi_index);
  if (name == "sqlite-rtree") return MakeSqliteEngine(a.dir, zstd);
  if (name == "boost-rtree") return std::make_unique<BoostEngine>(boxes);
  return nullptr;
}

// Smallest libspatialindex capacity c with floor(c * 0.99) == fanout (its fill factor must be < 1).
uint32_t CapacityFor(uint32_t fanout) {
  uint32_t c = fanout;
  while (static_cast<uint32_t>(std::floor(c * 0.99)) < fanout) ++c;
  return c;
}

// libspatialindex node bytes: 12-byte header + 48-byte MBR, and per entry 48 (box) + 8 (id) + 4 (length)
// + data. Leaf fan-out: the largest k whose expected node, plus two standard deviations of the sum of k
// entry sizes, fits one 12 KiB page; internal fan-out: entries of 60 bytes in one page.
void ChooseSpatialIndexCapacities(const SceneInfo& s, Args* a) {
  uint32_t k = 1;
  while (60 + (k + 1) * (60 + s.entry_mean) + 2 * std::sqrt(k + 1.0) * s.entry_sd <= kPageBytes) ++k;
  // libspatialindex refuses leaf capacities below 4: scenes of big objects (truman.ac) then get leaves
  // that span several pages, as mktree's single-object leaves do.
  a->lsi_leaf = CapacityFor(std::max<uint32_t>(k, 4));
  a->lsi_index = CapacityFor((kPageBytes - 60) / 60);
}

double F(double x) { return static_cast<double>(static_cast<float>(x)); }

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size() - 1) + 0.5))];
}

Status ReadScene(const SceneSpec& spec, SceneInfo* s) {
  MKTREE_ASSIGN_OR_RETURN(auto src, spec.Open(0));
  SceneObject o;
  std::vector<uint8_t> entry;
  const CodecOptions zstd;
  double sum = 0, sum2 = 0;
  uint64_t stride = 1;
  uint64_t n = 0;
  if (spec.spec.rfind("tanker:", 0) == 0) {
    std::sscanf(spec.spec.c_str(), "tanker:%lu", &n);
    stride = std::max<uint64_t>(1, n / 50000);  // sample entry sizes: 50k objects are plenty
  }
  for (;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, src->Next(&o));
    if (!more) break;
    const Box3f b = o.Aabb();
    s->bounds.Extend(b);
    s->boxes.push_back(b);
    if (o.id % stride == 0) {
      entry.clear();
      EncodePeerEntry(o, zstd, &entry);
      const double e = static_cast<double>(entry.size());
      sum += e;
      sum2 += e * e;
      ++s->entries_sampled;
    }
  }
  if (s->boxes.empty()) return Status::InvalidArgument("scene " + spec.spec + " has no objects");
  const double m = static_cast<double>(s->entries_sampled);
  s->entry_mean = sum / m;
  s->entry_sd = std::sqrt(std::max(0.0, sum2 / m - s->entry_mean * s->entry_mean));
  double d2 = 0;
  for (int i = 0; i < 3; ++i) d2 += std::pow(static_cast<double>(s->bounds.max[i]) - s->bounds.min[i], 2);
  s->diag = std::sqrt(d2);
  return Status::Ok();
}

std::vector<Workload> MakeWorkloads(const SceneInfo& s, const Args& a, bool tanker) {
  std::mt19937_64 rng(a.seed * 7919 + 17);
  std::uniform_real_distribution<double> u(0, 1);
  std::uniform_int_distribution<size_t> pick(0, s.boxes.size() - 1);
  auto centre = [&] {
    const Box3f& b = s.boxes[pick(rng)];
    Vec3d c;
    for (int i = 0; i < 3; ++i) c[i] = 0.5 * (static_cast<double>(b.min[i]) + b.max[i]);
    return c;
  };
  auto cube = [&](double side) {
    const Vec3d c = centre();
    Box3d b;
    for (int k = 0; k < 3; ++k) {
      b.min[k] = F(c[k] - side / 2);
      b.max[k] = F(c[k] + side / 2);
    }
    return Query::Box(b);
  };
  std::vector<Workload> w;
  Workload points{"point", 0, 0, {}};
  for (size_t i = 0; i < a.queries; ++i) {
    Vec3d p;
    for (int k = 0; k < 3; ++k) p[k] = F(s.bounds.min[k] + u(rng) * (s.bounds.max[k] - s.bounds.min[k]));
    points.queries.push_back(Query::Point(p));
  }
  w.push_back(points);
  const std::vector<double> fracs =
      a.smoke ? std::vector<double>{0.001, 0.01}
              : std::vector<double>{0.0002, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05};
  for (double f : fracs) {
    char name[32];
    std::snprintf(name, sizeof name, "box%g%%", f * 100);
    // Big boxes read many pages per cold query: fewer of them keep each workload's time similar.
    const size_t n = f <= 0.002 ? a.queries : std::max<size_t>(10, a.queries / (f <= 0.01 ? 2 : 5));
    Workload x{name, f, f * s.diag, {}};
    for (size_t i = 0; i < n; ++i) x.queries.push_back(cube(x.side_m));
    w.push_back(std::move(x));
  }
  if (tanker) {
    for (double side : {0.5, 2.0, 8.0}) {
      char name[32];
      std::snprintf(name, sizeof name, "box%gm", side);
      Workload x{name, side / s.diag, side, {}};
      const size_t n = side < 8 ? a.queries : std::max<size_t>(10, a.queries / 2);
      for (size_t i = 0; i < n; ++i) x.queries.push_back(cube(side));
      w.push_back(std::move(x));
    }
  }
  return w;
}

// ---- child builds ----

int ChildBuild(const Args& a) {
  std::unique_ptr<Engine> e = MakeEngine(a.child_engine, a, nullptr);
  if (!e) {
    std::fprintf(stderr, "unknown engine %s\n", a.child_engine.c_str());
    return 2;
  }
  Facts facts;
  const auto t0 = Clock::now();
  Status st = e->Build(SceneSpec{a.scene}, &facts);
  facts["seconds"] = Since(t0);
  if (!st.ok()) {
    std::fprintf(stderr, "error: build %s: %s\n", a.child_engine.c_str(), st.ToString().c_str());
    return 1;
  }
  facts["peak_rss_mib"] = bench::PeakRssMiB();
  for (const auto& [k, v] : facts) std::printf("%s=%.17g\n", k.c_str(), v);
  return 0;
}

struct BuildResult {
  Facts facts;
  double peak_rss_mib = 0;
};

// Runs this program as `--child-build ENGINE` and reads its facts from a pipe, its peak RSS among them
// (bench/peak_rss.h: wait4's would count this process's pages, the scene and the reference index).
Result<BuildResult> SpawnBuild(const std::string& engine, const Args& a) {
  int fds[2];
  if (pipe(fds) != 0) return Status::IOError("pipe");
  std::vector<std::string> argv_s = {"peers_bench",
                                     "--child-build",
                                     engine,
                                     "--scene",
                                     a.scene,
                                     "--dir",
                                     a.dir,
                                     "--lsi-leaf",
                                     std::to_string(a.lsi_leaf),
                                     "--lsi-index",
                                     std::to_string(a.lsi_index)};
  std::fflush(stdout);
  const pid_t pid = fork();
  if (pid < 0) return Status::IOError("fork");
  if (pid == 0) {
    dup2(fds[1], 1);
    close(fds[0]);
    close(fds[1]);
    std::vector<char*> argv;
    for (std::string& s : argv_s) argv.push_back(s.data());
    argv.push_back(nullptr);
    execv("/proc/self/exe", argv.data());
    _exit(127);
  }
  close(fds[1]);
  std::string out;
  char buf[4096];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof buf)) > 0) out.append(buf, static_cast<size_t>(n));
  close(fds[0]);
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return Status::IOError("waitpid");
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    return Status::Internal("build of " + engine + " failed (child status " + std::to_string(status) + ")");
  BuildResult r;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    const size_t eq = line.find('=');
    if (eq != std::string::npos) r.facts[line.substr(0, eq)] = std::stod(line.substr(eq + 1));
  }
  r.peak_rss_mib = r.facts["peak_rss_mib"];
  r.facts.erase("peak_rss_mib");
  return r;
}

// ---- measuring ----

struct Row {  // one engine on one workload
  size_t queries = 0;
  double hits = 0, pages = 0, p50 = 0, p99 = 0, floor = 0, inner = 0, kib = 0, cold_qps = 0, warm_qps = 0;
  bool cold = false;
};

class OsCache {
 public:
  explicit OsCache(const std::vector<std::string>& files) {
    for (const std::string& f : files) {
      int fd = open(f.c_str(), O_RDONLY);
      if (fd >= 0) {
        fdatasync(fd);  // dirty pages cannot be dropped
        fds_.push_back(fd);
      }
    }
  }
  ~OsCache() {
    for (int fd : fds_) close(fd);
  }
  void Drop() {
    for (int fd : fds_) posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  }

 private:
  std::vector<int> fds_;
};

std::string Fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string Ratio(double a, double b) { return b > 0 && a >= 0 ? Fmt("%.2f", a / b) : "-"; }

std::string Versions() {
  unsigned maj, min, rel;
  H5get_libversion(&maj, &min, &rel);
  std::ostringstream s;
  s << "libspatialindex " << SIDX_RELEASE_NAME << ", SQLite " << sqlite3_libversion() << ", Boost "
    << BOOST_LIB_VERSION << ", HDF5 " << maj << "." << min << "." << rel << ", zstd " << ZSTD_versionString();
  return s.str();
}

int Main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    std::string k = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (k == "--scene")
      a.scene = next();
    else if (k == "--name")
      a.name = next();
    else if (k == "--queries")
      a.queries = std::stoull(next());
    else if (k == "--seed")
      a.seed = std::stoull(next());
    else if (k == "--dir")
      a.dir = next();
    else if (k == "--out")
      a.out = next();
    else if (k == "--engines")
      a.engines = next();
    else if (k == "--smoke")
      a.smoke = true;
    else if (k == "--keep")
      a.keep = true;
    else if (k == "--child-build")
      a.child_engine = next();
    else if (k == "--lsi-leaf")
      a.lsi_leaf = static_cast<uint32_t>(std::stoul(next()));
    else if (k == "--lsi-index")
      a.lsi_index = static_cast<uint32_t>(std::stoul(next()));
    else if (k == "--versions") {
      std::printf("%s\n", Versions().c_str());
      return 0;
    } else {
      std::fprintf(stderr,
                   "error: unknown argument %s (see the comment at the top of bench/peers_bench.cc)\n",
                   k.c_str());
      return 2;
    }
  }
  if (!a.child_engine.empty()) return ChildBuild(a);
  if (a.scene.empty()) {
    std::fprintf(stderr, "error: --scene tanker:N:SEED or --scene FILE is required\n");
    return 2;
  }
  if (a.name.empty()) a.name = std::filesystem::path(a.scene).stem().string();
#ifndef NDEBUG
  std::printf("WARNING: built without optimisation; timings are meaningless\n");
#endif
  std::filesystem::create_directories(a.dir);
  std::filesystem::create_directories(a.out);
  const bool tanker = a.scene.rfind("tanker:", 0) == 0;
  const SceneSpec spec{a.scene};

  SceneInfo scene;
  auto t0 = Clock::now();
  if (Status st = ReadScene(spec, &scene); !st.ok()) {
    std::fprintf(stderr, "error: %s\n", st.ToString().c_str());
    return 1;
  }
  const uint64_t n_objects = scene.boxes.size();
  ChooseSpatialIndexCapacities(scene, &a);
  std::printf(
      "# peers_bench %s: %llu objects, diagonal %.1f, entry %.0f +- %.0f B (zstd, %llu sampled), read in "
      "%.1fs\n",
      a.name.c_str(), static_cast<unsigned long long>(n_objects), scene.diag, scene.entry_mean,
      scene.entry_sd, static_cast<unsigned long long>(scene.entries_sampled), Since(t0));
  const std::vector<Workload> workloads = MakeWorkloads(scene, a, tanker);

  // Reference answers: Boost.Geometry, itself checked against a brute-force scan on each workload's first
  // queries.
  BoostEngine reference(&scene.boxes);
  if (!reference.Open(false, {}).ok()) return 1;
  std::vector<std::vector<std::vector<ObjectId>>> expected(workloads.size());
  bool mismatch = false;
  for (size_t w = 0; w < workloads.size(); ++w) {
    for (size_t i = 0; i < workloads[w].queries.size(); ++i) {
      const Query& q = workloads[w].queries[i];
      std::vector<ObjectId> hits;
      Io io;
      if (!reference.Run(q, &hits, &io).ok()) return 1;
      if (i < 5) {
        Box3d qb = q.box;
        if (q.kind == Query::Kind::kPoint)
          for (int k = 0; k < 3; ++k) qb.min[k] = qb.max[k] = q.point[k];
        std::vector<ObjectId> brute;
        for (size_t id = 0; id < scene.boxes.size(); ++id)
          if (scene.boxes[id].Intersects(qb)) brute.push_back(static_cast<ObjectId>(id));
        if (brute != hits) {
          std::fprintf(stderr, "MISMATCH %s query %zu: boost %zu hits, brute force %zu\n",
                       workloads[w].name.c_str(), i, hits.size(), brute.size());
          mismatch = true;
        }
      }
      expected[w].push_back(std::move(hits));
    }
  }

  std::vector<std::string> engines;
  {
    std::stringstream ss(a.engines);
    std::string e;
    while (std::getline(ss, e, ','))
      if (!e.empty()) engines.push_back(e);
  }
  std::map<std::string, BuildResult> builds;
  std::map<std::string, double> file_mib, B;
  std::map<std::string, std::string> cold_methods;
  std::map<std::string, std::vector<Row>> rows;
  for (const std::string& name : engines) {
    std::unique_ptr<Engine> e = MakeEngine(name, a, &scene.boxes);
    if (!e) {
      std::fprintf(stderr, "error: unknown engine %s\n", name.c_str());
      return 2;
    }
    std::printf("## %s: building...\n", name.c_str());
    auto built = SpawnBuild(name, a);
    if (!built.ok()) {
      std::fprintf(stderr, "error: %s\n", built.status().ToString().c_str());
      return 1;
    }
    if (built->facts["objects"] != static_cast<double>(n_objects)) {
      std::fprintf(stderr, "error: %s built %.0f objects, expected %llu\n", name.c_str(),
                   built->facts["objects"], static_cast<unsigned long long>(n_objects));
      return 1;
    }
    builds[name] = *built;
    double bytes = 0;
    for (const std::string& f : e->files()) bytes += static_cast<double>(std::filesystem::file_size(f));
    file_mib[name] = bytes / 1048576.0;
    B[name] = e->objects_per_page(built->facts);
    std::printf("   built in %.2fs (%.0f objects/s), peak RSS %.0f MiB, %.1f MiB on disk, B = %.2f\n",
                built->facts["seconds"], n_objects / built->facts["seconds"], built->peak_rss_mib,
                file_mib[name], B[name]);

    std::vector<Row>& r = rows[name];
    r.resize(workloads.size());
    std::vector<ObjectId> hits;
    Io io;
    auto check = [&](size_t w, size_t i, const char* phase) {
      if (hits == expected[w][i]) return;
      std::fprintf(stderr, "MISMATCH %s %s %s query %zu: %zu hits, boost %zu\n", name.c_str(), phase,
                   workloads[w].name.c_str(), i, hits.size(), expected[w][i].size());
      mismatch = true;
    };
    const bool has_files = !e->files().empty();
    if (has_files) {  // cold phase
      if (Status st = e->Open(false, built->facts); !st.ok()) {
        std::fprintf(stderr, "error: open %s: %s\n", name.c_str(), st.ToString().c_str());
        return 1;
      }
      cold_methods[name] = e->cold_method();
      OsCache os(e->files());
      for (size_t w = 0; w < workloads.size(); ++w) {
        std::vector<double> pages;
        double seconds = 0;
        Row& row = r[w];
        row.cold = true;
        row.queries = workloads[w].queries.size();
        for (size_t i = 0; i < workloads[w].queries.size(); ++i) {
          os.Drop();
          e->ClearCache();
          const auto t = Clock::now();
          Status st = e->Run(workloads[w].queries[i], &hits, &io);
          seconds += Since(t);
          if (!st.ok()) {
            std::fprintf(stderr, "error: %s query: %s\n", name.c_str(), st.ToString().c_str());
            return 1;
          }
          check(w, i, "cold");
          pages.push_back(static_cast<double>(io.pages));
          row.hits += static_cast<double>(hits.size());
          row.pages += static_cast<double>(io.pages);
          row.inner += static_cast<double>(io.inner_pages);
          row.kib += static_cast<double>(io.bytes) / 1024.0;
          row.floor += std::ceil(static_cast<double>(hits.size()) / B[name]);
        }
        const double q = static_cast<double>(row.queries);
        row.hits /= q;
        row.pages /= q;
        row.inner /= q;
        row.kib /= q;
        row.floor /= q;
        row.p50 = Percentile(pages, 0.5);
        row.p99 = Percentile(pages, 0.99);
        row.cold_qps = q / seconds;
      }
      e->Close();
    }
    // Warm phase: one pass fills the cache, the second is timed.
    if (Status st = e->Open(true, built->facts); !st.ok()) {
      std::fprintf(stderr, "error: open %s: %s\n", name.c_str(), st.ToString().c_str());
      return 1;
    }
    for (size_t w = 0; w < workloads.size(); ++w) {
      Row& row = r[w];
      row.queries = workloads[w].queries.size();
      for (size_t i = 0; i < workloads[w].queries.size(); ++i) {
        if (!e->Run(workloads[w].queries[i], &hits, &io).ok()) return 1;
        if (!has_files) {
          check(w, i, "warm");
          row.hits += static_cast<double>(hits.size()) / static_cast<double>(row.queries);
        }
      }
      const auto t = Clock::now();
      for (size_t i = 0; i < workloads[w].queries.size(); ++i) {
        if (!e->Run(workloads[w].queries[i], &hits, &io).ok()) return 1;
      }
      row.warm_qps = static_cast<double>(row.queries) / Since(t);
      for (size_t i = 0; i < workloads[w].queries.size(); ++i) {  // answers from the warm cache too
        if (!e->Run(workloads[w].queries[i], &hits, &io).ok()) return 1;
        check(w, i, "warm");
      }
      std::printf(
          "   %-9s %5zu q  hits %9.1f  pages %8.2f (p50 %5.0f p99 %5.0f, floor %7.2f)  cold %8.0f q/s  warm "
          "%9.0f q/s\n",
          workloads[w].name.c_str(), row.queries, row.hits, row.pages, row.p50, row.p99, row.floor,
          row.cold_qps, row.warm_qps);
    }
    e->Close();
    if (!a.keep)
      for (const std::string& f : e->files()) std::filesystem::remove(f);
    std::fflush(stdout);
  }

  // ---- report ----
  std::ofstream tsv(a.out + "/" + a.name + ".tsv");
  for (const std::string& name : engines) {
    const BuildResult& b = builds[name];
    tsv << "build\t" << a.name << '\t' << n_objects << '\t' << name << '\t' << b.facts.at("seconds") << '\t'
        << n_objects / b.facts.at("seconds") << '\t' << b.peak_rss_mib << '\t' << file_mib[name] << '\t'
        << B[name] << '\n';
    for (size_t w = 0; w < workloads.size(); ++w) {
      const Row& r = rows[name][w];
      tsv << "query\t" << a.name << '\t' << n_objects << '\t' << name << '\t' << workloads[w].name << '\t'
          << workloads[w].frac << '\t' << workloads[w].side_m << '\t' << r.queries << '\t' << r.hits << '\t'
          << r.pages << '\t' << r.p50 << '\t' << r.p99 << '\t' << r.floor << '\t' << r.inner << '\t' << r.kib
          << '\t' << r.cold_qps << '\t' << r.warm_qps << '\n';
    }
  }

  std::ofstream md(a.out + "/" + a.name + ".md");
  md << "## " << a.name << ": " << n_objects << " objects (`" << a.scene << "`)\n\n";
  md << "Scene box (" << scene.bounds.min[0] << ", " << scene.bounds.min[1] << ", " << scene.bounds.min[2]
     << ") – (" << scene.bounds.max[0] << ", " << scene.bounds.max[1] << ", " << scene.bounds.max[2]
     << "), diagonal " << Fmt("%.1f", scene.diag) << ". Query seed " << a.seed
     << ". Encoded entry (mktree zstd, the peers' blob): " << Fmt("%.0f", scene.entry_mean) << " ± "
     << Fmt("%.0f", scene.entry_sd) << " bytes. libspatialindex leaf "
     << "capacity " << a.lsi_leaf << ", index capacity " << a.lsi_index << " (fill factor 0.99).\n\n";
  md << "### Build\n\n| engine | build s | objects/s | peak RSS MiB | file MiB | B objects/leaf page | cold "
        "reads |\n"
        "|---|---:|---:|---:|---:|---:|---|\n";
  for (const std::string& name : engines) {
    const BuildResult& b = builds[name];
    md << "| " << name << " | " << Fmt("%.2f", b.facts.at("seconds")) << " | "
       << Fmt("%.0f", n_objects / b.facts.at("seconds")) << " | " << Fmt("%.0f", b.peak_rss_mib) << " | "
       << Fmt("%.1f", file_mib[name]) << " | " << (B[name] > 0 ? Fmt("%.2f", B[name]) : "-") << " | "
       << (cold_methods.count(name) ? cold_methods[name] : "in RAM") << " |\n";
  }
  md << "\n### Queries (AABB answers; pages = disk accesses per query with a cold cache)\n\n"
        "`inner` = pages of internal nodes among them (libspatialindex reads its internal nodes from disk; "
        "mktree "
        "keeps them in RAM); floor = ceil(T/B) with the engine's own B; SQLite pages are 16 KiB, the others "
        "12 KiB."
        "\n\n";
  for (size_t w = 0; w < workloads.size(); ++w) {
    md << "#### " << workloads[w].name;
    if (workloads[w].side_m > 0) md << " (side " << Fmt("%.3g", workloads[w].side_m) << ")";
    md << ", " << workloads[w].queries.size() << " queries, mean " << Fmt("%.1f", rows[engines[0]][w].hits)
       << " hits\n\n| engine | pages | p50 | p99 | floor | pages/floor | inner | KiB read | cold q/s | warm "
          "q/s |\n"
          "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const std::string& name : engines) {
      const Row& r = rows[name][w];
      if (!r.cold) {
        md << "| " << name << " | - | - | - | - | - | - | - | - | " << Fmt("%.0f", r.warm_qps) << " |\n";
        continue;
      }
      md << "| " << name << " | " << Fmt("%.2f", r.pages) << " | " << Fmt("%.0f", r.p50) << " | "
         << Fmt("%.0f", r.p99) << " | " << Fmt("%.2f", r.floor) << " | " << Ratio(r.pages, r.floor) << " | "
         << Fmt("%.2f", r.inner) << " | " << Fmt("%.1f", r.kib) << " | " << Fmt("%.0f", r.cold_qps) << " | "
         << Fmt("%.0f", r.warm_qps) << " |\n";
    }
    md << "\n";
  }
  const std::string m = "mktree-pagefile-zstd";
  if (rows.count(m)) {
    md << "### Ratios " << m
       << " ÷ peer (pages, KiB: below 1 is better for mktree; q/s: above 1 is better)\n\n"
          "| workload | pages ÷ lsi | pages ÷ lsi leaf pages | pages ÷ sqlite | KiB ÷ lsi | KiB ÷ sqlite | "
          "cold q/s ÷ lsi "
          "| cold q/s ÷ sqlite | warm q/s ÷ lsi | warm q/s ÷ sqlite | warm q/s ÷ boost |\n"
          "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    auto get = [&](const std::string& e, size_t w) -> const Row* {
      return rows.count(e) ? &rows[e][w] : nullptr;
    };
    for (size_t w = 0; w < workloads.size(); ++w) {
      const Row& k = rows[m][w];
      const Row* l = get("libspatialindex", w);
      const Row* s = get("sqlite-rtree", w);
      const Row* b = get("boost-rtree", w);
      md << "| " << workloads[w].name << " | " << (l ? Ratio(k.pages, l->pages) : "-") << " | "
         << (l ? Ratio(k.pages, l->pages - l->inner) : "-") << " | " << (s ? Ratio(k.pages, s->pages) : "-")
         << " | " << (l ? Ratio(k.kib, l->kib) : "-") << " | " << (s ? Ratio(k.kib, s->kib) : "-") << " | "
         << (l ? Ratio(k.cold_qps, l->cold_qps) : "-") << " | " << (s ? Ratio(k.cold_qps, s->cold_qps) : "-")
         << " | " << (l ? Ratio(k.warm_qps, l->warm_qps) : "-") << " | "
         << (s ? Ratio(k.warm_qps, s->warm_qps) : "-") << " | " << (b ? Ratio(k.warm_qps, b->warm_qps) : "-")
         << " |\n";
    }
    md << "\n";
  }
  md << (mismatch ? "**ANSWER MISMATCH: see the run's stderr.**\n\n"
                  : "All engines' AABB answers agreed on every query.\n\n");
  if (mismatch) {
    std::printf("FAILED: answers differ between engines\n");
    return 1;
  }
  std::printf("ok: %s, all answers agree; wrote %s/%s.md and .tsv\n", a.name.c_str(), a.out.c_str(),
              a.name.c_str());
  return 0;
}

}  // namespace
}  // namespace mktree::bench

int main(int argc, char** argv) { return mktree::bench::Main(argc, argv); }
