// nearest_bench: k nearest (exact distance) and first-hit rays on the synthetic tanker, cold and warm,
// against the I/O floor of a best-first search and against in-RAM peers measured in the same run.
//
// Workloads (fixed seeds):
//   build        mktree build of tanker:N (paged file), seconds
//   nearest k    --queries seeded random points in the scene box, k = 1, 10, 100: exact distance
//   ray          --queries seeded rays from random points toward random objects' centres: first hit
// mktree: queries/s warm (a cache of --warm-cache-mib, fastest of 3 passes after a filling one) and cold
// (cache 0: every page looked up is read), pages read per query cold against the floor (NearestPageFloor /
// RayPageFloor: the pages of the leaves whose region is within the answer), RSS of the open Database. Peers,
// in RAM, on the same triangles in float32 world coordinates (mismatches: beyond kFloatTolerance):
//   boost        Boost.Geometry rtree (rstar<16>, packing) of the objects' boxes: the K = 4k nearest boxes
//                (4x more while the K-th box is nearer than the k-th exact distance), each refined by its
//                exact distance (0 inside a closed solid, else a scan of its triangles)
//   embree       Embree 3: one triangle geometry of all objects; rtcIntersect1 for rays, rtcPointQuery
//                with a closest-point callback for k = 1
//   cgal         CGAL's AABB_tree over every triangle (Simple_cartesian<double>): closest_point_and_primitive
//                for k = 1 (surfaces only), first_intersection for rays (--no-cgal skips it)
// Every peer answer is checked against mktree's (distances, t); a mismatch is counted and printed.
//
// Usage: nearest_bench [--objects N | --scene FILE] [--seed S] [--queries Q] [--dir DIR] [--keep] [--reuse]
//                      [--warm-cache-mib M] [--no-cgal] [--no-peers]
//   --scene FILE  a real scene (any format mktree build reads) instead of the tanker
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <embree3/rtcore.h>
#include <malloc.h>
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
#include <fstream>
#include <queue>
#include <random>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/geometry/closest_point.h"
#include "engine/geometry/mesh_edges.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/geometry/triangle_pair.h"
#include "engine/ingest/store_builder.h"
#include "engine/query/nearest_search.h"
#include "engine/query/ray_search.h"
#include "engine/query/store_database.h"
#include "engine/scene/scene_source.h"
#include "mktree/database.h"

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;
using namespace mktree;

namespace {

using BPoint = bg::model::point<float, 3, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using BValue = std::pair<BBox, ObjectId>;
using Clock = std::chrono::steady_clock;

// The peers hold float32 world coordinates (Embree must); the store keeps float32 offsets in each object's
// frame, finer by the ratio of the scene's size to the object's. Answers within this (m) count as equal.
constexpr double kFloatTolerance = 1e-4;

constexpr size_t kKs[3] = {1, 10, 100};  // the nearest workloads' k
constexpr int kPasses = 3;               // warm passes timed; the fastest is reported

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Heap bytes in use now, MiB (glibc's mallinfo2: unaffected by freed memory that RSS still counts).
double HeapMiB() {
  const struct mallinfo2 m = mallinfo2();
  return static_cast<double>(m.uordblks + m.hblkhd) / 1048576.0;  // in use, small blocks and mmapped ones
}

// Resident set size now, MiB (/proc/self/statm).
double RssMiB() {
  std::ifstream in("/proc/self/statm");
  uint64_t size = 0, resident = 0;
  in >> size >> resident;
  return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / 1048576.0;
}

struct Args {
  uint64_t objects = 1000000;
  uint64_t seed = 1;
  size_t queries = 300;
  std::string dir = ".";
  bool keep = false, reuse = false;
  uint64_t warm_cache_mib = 256;
  std::string scene;  // empty: the tanker
  bool cgal = true;
  bool peers = true;
  Result<std::unique_ptr<SceneSource>> Open(ObjectId first) const {
    return scene.empty() ? MakeTankerSource(objects, seed, first) : OpenSceneFile(scene, first);
  }
  std::string Name() const { return scene.empty() ? "tanker:" + std::to_string(objects) : scene; }
};

bool ParseArgs(int argc, char** argv, Args* a) {
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto next = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    const char* v = nullptr;
    if (s == "--objects" && (v = next())) {
      a->objects = std::stoull(v);
    } else if (s == "--seed" && (v = next())) {
      a->seed = std::stoull(v);
    } else if (s == "--queries" && (v = next())) {
      a->queries = std::stoull(v);
    } else if (s == "--dir" && (v = next())) {
      a->dir = v;
    } else if (s == "--warm-cache-mib" && (v = next())) {
      a->warm_cache_mib = std::stoull(v);
    } else if (s == "--scene" && (v = next())) {
      a->scene = v;
    } else if (s == "--no-peers") {
      a->peers = false;
    } else if (s == "--no-cgal") {
      a->cgal = false;
    } else if (s == "--keep") {
      a->keep = true;
    } else if (s == "--reuse") {
      a->reuse = a->keep = true;
    } else {
      std::fprintf(stderr,
                   "usage: nearest_bench [--objects N] [--seed S] [--queries Q] [--dir DIR] [--keep] "
                   "[--reuse] [--warm-cache-mib M]\n");
      return false;
    }
  }
  return true;
}

// The scene as the peers hold it: float32 vertices (as stored), triangles, each triangle's object.
struct Soup {
  std::vector<float> vertices;
  std::vector<uint32_t> triangles;
  std::vector<uint32_t> object_of;          // per triangle
  std::vector<uint64_t> first_triangle{0};  // per object, + 1
  std::vector<BValue> boxes;
  Box3f scene;
  uint64_t Bytes() const {
    return vertices.capacity() * 4 + triangles.capacity() * 4 + object_of.capacity() * 4 +
           first_triangle.capacity() * 8 + boxes.capacity() * sizeof(BValue);
  }
};

Soup ReadScene(const Args& a) {
  Soup s;
  auto src = a.Open(0);
  if (!src.ok()) {
    std::fprintf(stderr, "scene: %s\n", src.status().ToString().c_str());
    std::exit(1);
  }
  SceneObject o;
  while (true) {
    auto more = (*src)->Next(&o);
    if (!more.ok() || !*more) break;
    const uint32_t base = static_cast<uint32_t>(s.vertices.size() / 3);
    for (double v : o.mesh.vertices) s.vertices.push_back(static_cast<float>(v));
    for (uint32_t t : o.mesh.triangles) s.triangles.push_back(base + t);
    for (size_t t = 0; t < o.mesh.triangle_count(); ++t) s.object_of.push_back(o.id);
    s.first_triangle.push_back(s.triangles.size() / 3);
    const Box3f b = o.Aabb();
    s.scene.Extend(b);
    s.boxes.emplace_back(BBox(BPoint(b.min[0], b.min[1], b.min[2]), BPoint(b.max[0], b.max[1], b.max[2])),
                         o.id);
  }
  return s;
}

Vec3d Corner(const Soup& s, uint32_t v) {
  return {s.vertices[3 * v], s.vertices[3 * v + 1], s.vertices[3 * v + 2]};
}

// Exact distance of object id as mktree defines it: 0 inside its solid (a closed mesh whose box holds p:
// SolidClassifier, as mktree's), else a scan of its triangles.
double ExactDistance(const Soup& s, ObjectId id, const Vec3d& p, const BBox& box) {
  const uint64_t first = s.first_triangle[id], last = s.first_triangle[id + 1];
  if (bg::covered_by(BPoint(static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)),
                     box)) {
    Mesh m;
    for (uint64_t t = first; t < last; ++t)
      for (int c = 0; c < 3; ++c) {
        const Vec3d v = Corner(s, s.triangles[3 * t + c]);
        m.vertices.insert(m.vertices.end(), {v.x, v.y, v.z});
        m.triangles.push_back(static_cast<uint32_t>(m.triangles.size()));
      }
    if (IsClosedMesh(m) && PointInSolid(m, p)) return 0;
  }
  double best = INFINITY;
  for (uint64_t t = first; t < last; ++t) {
    const uint32_t* c = &s.triangles[3 * t];
    best = std::min(
        best, PointTriangleClosest(p, Corner(s, c[0]), Corner(s, c[1]), Corner(s, c[2])).distance_squared);
  }
  return std::sqrt(best);
}

// Boost's k nearest by exact distance: the K nearest boxes (K = 4k, then 4x more while the K-th box is
// nearer than the k-th exact distance found), each refined by its exact distance. Returns the k-th distance.
double BoostNearest(const bgi::rtree<BValue, bgi::rstar<16>>& rtree, const Soup& s, const Vec3d& p,
                    size_t k) {
  const BPoint q(static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z));
  std::vector<BValue> found;
  for (size_t want = 4 * k;; want *= 4) {
    found.clear();
    rtree.query(bgi::nearest(q, static_cast<unsigned>(std::min<size_t>(want, rtree.size()))),
                std::back_inserter(found));
    std::vector<double> exact;
    double farthest_box = 0;
    for (const BValue& v : found) {
      exact.push_back(ExactDistance(s, v.second, p, v.first));
      farthest_box = std::max(farthest_box, static_cast<double>(bg::distance(q, v.first)));
    }
    std::sort(exact.begin(), exact.end());
    const double kth = exact.size() >= k ? exact[k - 1] : INFINITY;
    if (found.size() == rtree.size() || kth <= farthest_box) return kth;
  }
}

struct EmbreeScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~EmbreeScene() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

struct ClosestQuery {
  const Soup* soup;
  double best2 = INFINITY;
};

bool EmbreeClosest(RTCPointQueryFunctionArguments* args) {
  auto* q = static_cast<ClosestQuery*>(args->userPtr);
  const Soup& s = *q->soup;
  const uint32_t* c = &s.triangles[3 * size_t{args->primID}];
  const Vec3d p{args->query->x, args->query->y, args->query->z};
  const double d2 =
      PointTriangleClosest(p, Corner(s, c[0]), Corner(s, c[1]), Corner(s, c[2])).distance_squared;
  if (d2 < q->best2) {
    q->best2 = d2;
    args->query->radius = static_cast<float>(std::sqrt(d2)) * (1 + 1e-6f);
    return true;
  }
  return false;
}

// CGAL's AABB_tree over every triangle: k = 1 closest point (surfaces) and first ray hits.
void CgalPeer(const Soup& soup, const std::vector<Vec3d>& points, const std::vector<RayQuery>& rays,
              const std::vector<double>& nearest1, const std::vector<double>& first_t) {
  using K = CGAL::Simple_cartesian<double>;
  using Tri = K::Triangle_3;
  using Iterator = std::vector<Tri>::const_iterator;
  using Primitive = CGAL::AABB_triangle_primitive<K, Iterator>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
  const double rss = RssMiB(), heap = HeapMiB();
  auto t0 = Clock::now();
  std::vector<Tri> tris;
  tris.reserve(soup.object_of.size());
  auto at = [&](uint32_t v) {
    return K::Point_3(soup.vertices[3 * v], soup.vertices[3 * v + 1], soup.vertices[3 * v + 2]);
  };
  for (size_t t = 0; t < soup.object_of.size(); ++t)
    tris.emplace_back(at(soup.triangles[3 * t]), at(soup.triangles[3 * t + 1]),
                      at(soup.triangles[3 * t + 2]));
  Tree tree(tris.begin(), tris.end());
  tree.accelerate_distance_queries();
  tree.closest_point(K::Point_3(0, 0, 0));  // builds the tree and its search structure (lazily built)
  std::printf(
      "cgal AABB_tree: %.2f s to build (distance queries accelerated), RSS +%.0f MiB, heap +%.0f MiB "
      "(its triangles included)\n",
      Since(t0), RssMiB() - rss, HeapMiB() - heap);
  uint64_t mismatches = 0;
  double best_s = INFINITY;  // the fastest of kPasses passes (a shared machine)
  for (int pass = 0; pass < kPasses; ++pass) {
    mismatches = 0;
    t0 = Clock::now();
    for (size_t i = 0; i < points.size(); ++i) {
      const K::Point_3 p(points[i].x, points[i].y, points[i].z);
      const auto cp = tree.closest_point_and_primitive(p);
      const double d = std::sqrt(CGAL::squared_distance(p, cp.first));
      if (nearest1[i] > 0) mismatches += std::fabs(d - nearest1[i]) > kFloatTolerance;
    }
    best_s = std::min(best_s, Since(t0));
  }
  std::printf("cgal closest_point k=1   %10.0f q/s, mismatches (outside solids) %llu\n",
              points.size() / best_s, static_cast<unsigned long long>(mismatches));
  mismatches = 0;
  best_s = INFINITY;
  for (int pass = 0; pass < kPasses; ++pass) {
    mismatches = 0;
    t0 = Clock::now();
    for (size_t i = 0; i < rays.size(); ++i) {
      const RayQuery& r = rays[i];
      const K::Ray_3 ray(K::Point_3(r.origin.x, r.origin.y, r.origin.z),
                         K::Vector_3(r.direction.x, r.direction.y, r.direction.z));
      const auto hit = tree.first_intersection(ray);
      double t = INFINITY;
      if (hit) {
        if (const K::Point_3* q = boost::get<K::Point_3>(&hit->first))
          t = std::sqrt(CGAL::squared_distance(ray.source(), *q));
        else
          t = 0;  // a segment: the ray runs in a triangle's plane
      }
      mismatches += !(t == first_t[i] || std::fabs(t - first_t[i]) <= kFloatTolerance);
    }
    best_s = std::min(best_s, Since(t0));
  }
  std::printf("cgal first_intersection  %10.0f q/s, first-hit t mismatches %llu\n", rays.size() / best_s,
              static_cast<unsigned long long>(mismatches));
}

void Header(const Args& a) {
  std::printf("# nearest_bench: scene %s seed=%llu queries/workload=%zu page=12 KiB, paged file\n",
              a.Name().c_str(), static_cast<unsigned long long>(a.seed), a.queries);
  std::printf(
      "# cores=%ld; cold = cache 0 (every page looked up is read; OS page cache not bypassed); warm = "
      "%llu MiB cache, fastest of 3 passes after a first; peers: fastest of 3; one thread%s\n",
      sysconf(_SC_NPROCESSORS_ONLN), static_cast<unsigned long long>(a.warm_cache_mib),
#ifdef NDEBUG
      ""
#else
      " -- WARNING: built without optimisation"
#endif
  );
}

// mktree on the store at `path`, cold then warm: fills each query's k-th distance (per k) and first hit.
int RunMktree(const Args& a, const std::string& path, const std::vector<Vec3d>& points,
              const std::vector<RayQuery>& rays, std::vector<std::vector<double>>* kth,
              std::vector<double>* first_t) {
  auto t0 = Clock::now();
  const double heap0 = HeapMiB(), rss_open0 = RssMiB();
  auto cold = Database::Open(path, {.cache_pages = 0});
  const double warm_pages = a.warm_cache_mib * 1048576.0 / 12288.0;
  auto warm = Database::Open(path, {.cache_pages = static_cast<uint64_t>(warm_pages)});
  if (!cold.ok() || !warm.ok()) {
    std::fprintf(stderr, "open failed\n");
    return 1;
  }
  const auto* store = dynamic_cast<const StoreDatabase*>(cold->get());
  std::printf("mktree open (two Databases: cache 0 and warm): heap +%.1f MiB, RSS +%.1f MiB\n",
              HeapMiB() - heap0, RssMiB() - rss_open0);
  std::printf("\n%-12s %10s %10s %12s %12s %10s\n", "workload", "cold q/s", "warm q/s", "pages/query",
              "floor/query", "ratio");
  for (int w = 0; w < 4; ++w) {
    const bool ray = w == 3;
    uint64_t pages = 0, floor = 0;
    t0 = Clock::now();
    for (size_t i = 0; i < a.queries; ++i) {
      QueryStats s;
      if (ray) {
        std::vector<RayHit> hits;
        if (!(*cold)->Ray(rays[i], &hits, &s).ok()) return 1;
        (*first_t)[i] = hits.empty() ? INFINITY : hits[0].t;
      } else {
        std::vector<NearestHit> hits;
        const DistanceQuery q = Query::Nearest(points[i], kKs[w]);
        if (!(*cold)->Nearest(q, &hits, &s).ok()) return 1;
        (*kth)[w].push_back(hits.empty() ? INFINITY : hits.back().distance);
      }
      pages += s.pages_read;
    }
    const double cold_s = Since(t0);
    for (size_t i = 0; i < a.queries; ++i)  // a scan of every leaf's filter: not timed
      floor += ray ? RayPageFloor({SearchPart{store}}, rays[i], (*first_t)[i])
                   : NearestPageFloor({SearchPart{store}}, Query::Nearest(points[i], kKs[w]), (*kth)[w][i]);
    double warm_s = INFINITY;  // the first pass fills the cache; the fastest of the next kPasses
    for (int pass = 0; pass <= kPasses; ++pass) {
      t0 = Clock::now();
      for (size_t i = 0; i < a.queries; ++i) {
        if (ray) {
          std::vector<RayHit> hits;
          if (!(*warm)->Ray(rays[i], &hits, nullptr).ok()) return 1;
        } else {
          std::vector<NearestHit> hits;
          if (!(*warm)->Nearest(Query::Nearest(points[i], kKs[w]), &hits, nullptr).ok()) return 1;
        }
      }
      if (pass > 0) warm_s = std::min(warm_s, Since(t0));
    }
    const std::string name = ray ? "ray" : "nearest k=" + std::to_string(kKs[w]);
    std::printf("%-12s %10.0f %10.0f %12.2f %12.2f %10.3f\n", name.c_str(), a.queries / cold_s,
                a.queries / warm_s, static_cast<double>(pages) / a.queries,
                static_cast<double>(floor) / a.queries,
                floor ? static_cast<double>(pages) / static_cast<double>(floor) : 0.0);
  }
  std::printf("mktree after the warm passes: heap +%.1f MiB, RSS +%.1f MiB (the warm cache included)\n",
              HeapMiB() - heap0, RssMiB() - rss_open0);
  return 0;
}

// Boost.Geometry's rtree of boxes with exact refinement, checked against mktree's k-th distances.
void BoostPeer(const Args& a, const Soup& soup, const std::vector<Vec3d>& points,
               const std::vector<std::vector<double>>& kth) {
  const double heap = HeapMiB();
  auto t0 = Clock::now();
  bgi::rtree<BValue, bgi::rstar<16>> rtree(soup.boxes.begin(), soup.boxes.end());
  std::printf(
      "\nboost rtree: %.2f s to build, heap +%.1f MiB (plus the triangle soup for refinement, %.0f MiB)\n",
      Since(t0), HeapMiB() - heap, soup.Bytes() / 1048576.0);
  for (int w = 0; w < 3; ++w) {
    uint64_t mismatches = 0;
    double best_s = INFINITY;  // the fastest of kPasses passes (a shared machine)
    for (int pass = 0; pass < kPasses; ++pass) {
      mismatches = 0;
      t0 = Clock::now();
      for (size_t i = 0; i < a.queries; ++i) {
        const double d = BoostNearest(rtree, soup, points[i], kKs[w]);
        const bool bad = std::fabs(d - kth[w][i]) > kFloatTolerance;
        if (bad && mismatches == 0)
          std::printf("  first mismatch: query %zu, boost %.9g, mktree %.9g\n", i, d, kth[w][i]);
        mismatches += bad;
      }
      best_s = std::min(best_s, Since(t0));
    }
    std::printf("boost nearest k=%-4zu %10.0f q/s, k-th distance mismatches %llu\n", kKs[w],
                a.queries / best_s, static_cast<unsigned long long>(mismatches));
  }
}

// Embree 3: closest points (k = 1) and first hits, checked against mktree's.
void EmbreePeer(const Args& a, const Soup& soup, const std::vector<Vec3d>& points,
                const std::vector<RayQuery>& rays, const std::vector<double>& nearest1,
                const std::vector<double>& first_t) {
  const double rss = RssMiB(), heap = HeapMiB();
  auto t0 = Clock::now();
  EmbreeScene e;
  e.device = rtcNewDevice("threads=1");
  e.scene = rtcNewScene(e.device);
  RTCGeometry g = rtcNewGeometry(e.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, soup.vertices.data(), 0,
                             3 * sizeof(float), soup.vertices.size() / 3);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, soup.triangles.data(), 0,
                             3 * sizeof(uint32_t), soup.triangles.size() / 3);
  rtcCommitGeometry(g);
  rtcAttachGeometry(e.scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(e.scene);
  std::printf("embree: %.2f s to build (one thread), RSS +%.0f MiB, heap +%.0f MiB (plus the shared soup)\n",
              Since(t0), RssMiB() - rss, HeapMiB() - heap);
  uint64_t mismatches = 0;
  double best_s = INFINITY;  // the fastest of kPasses passes (a shared machine)
  for (int pass = 0; pass < kPasses; ++pass) {
    mismatches = 0;
    t0 = Clock::now();
    for (size_t i = 0; i < a.queries; ++i) {
      RTCPointQuery q;
      q.x = static_cast<float>(points[i].x);
      q.y = static_cast<float>(points[i].y);
      q.z = static_cast<float>(points[i].z);
      q.radius = INFINITY;
      q.time = 0;
      RTCPointQueryContext ctx;
      rtcInitPointQueryContext(&ctx);
      ClosestQuery cq{&soup};
      rtcPointQuery(e.scene, &q, &ctx, EmbreeClosest, &cq);
      // Embree measures surfaces: a point inside a solid is 0 for mktree only.
      if (nearest1[i] > 0) mismatches += std::fabs(std::sqrt(cq.best2) - nearest1[i]) > kFloatTolerance;
    }
    best_s = std::min(best_s, Since(t0));
  }
  std::printf("embree rtcPointQuery k=1 %10.0f q/s, mismatches (outside solids) %llu\n", a.queries / best_s,
              static_cast<unsigned long long>(mismatches));
  mismatches = 0;
  best_s = INFINITY;
  for (int pass = 0; pass < kPasses; ++pass) {
    mismatches = 0;
    t0 = Clock::now();
    for (size_t i = 0; i < a.queries; ++i) {
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      RTCRayHit rh;
      const RayQuery& r = rays[i];
      const double len = std::sqrt(r.direction.x * r.direction.x + r.direction.y * r.direction.y +
                                   r.direction.z * r.direction.z);
      rh.ray.org_x = static_cast<float>(r.origin.x);
      rh.ray.org_y = static_cast<float>(r.origin.y);
      rh.ray.org_z = static_cast<float>(r.origin.z);
      rh.ray.dir_x = static_cast<float>(r.direction.x / len);
      rh.ray.dir_y = static_cast<float>(r.direction.y / len);
      rh.ray.dir_z = static_cast<float>(r.direction.z / len);
      rh.ray.tnear = 0;
      rh.ray.tfar = INFINITY;
      rh.ray.mask = 0xffffffffu;
      rh.ray.flags = 0;
      rh.ray.time = 0;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(e.scene, &ctx, &rh);
      const double t = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? INFINITY : rh.ray.tfar;
      mismatches += !(t == first_t[i] || std::fabs(t - first_t[i]) <= kFloatTolerance);
    }
    best_s = std::min(best_s, Since(t0));
  }
  std::printf("embree rtcIntersect1      %10.0f q/s, first-hit t mismatches (float32 rays) %llu\n",
              a.queries / best_s, static_cast<unsigned long long>(mismatches));
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  if (!ParseArgs(argc, argv, &a)) return 2;
  Header(a);
  auto t0 = Clock::now();
  Soup soup = ReadScene(a);
  std::printf("# scene: %zu triangles, %.1f s to generate, peers' triangle soup %.0f MiB\n",
              soup.object_of.size(), Since(t0), soup.Bytes() / 1048576.0);

  const std::string path =
      a.dir + "/nearest_bench_" + std::to_string(a.objects) + "_" + std::to_string(a.seed) + ".mkt";
  if (!a.reuse || !std::filesystem::exists(path)) {
    IngestOptions opts;
    opts.store.backend = Backend::kPagedFile;
    t0 = Clock::now();
    auto report = BuildStore(
        {[&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> { return a.Open(first); }}, path, opts);
    if (!report.ok()) {
      std::fprintf(stderr, "build: %s\n", report.status().ToString().c_str());
      return 1;
    }
    std::printf("build mktree: %.1f s, store %.0f MiB\n", Since(t0), report->store_bytes / 1048576.0);
  }

  std::mt19937_64 rng(a.seed * 7919 + 5);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3d> points;
  std::vector<RayQuery> rays;
  for (size_t i = 0; i < a.queries; ++i) {
    Vec3d p;
    for (int k = 0; k < 3; ++k) p[k] = soup.scene.min[k] + u(rng) * (soup.scene.max[k] - soup.scene.min[k]);
    points.push_back(p);
    Vec3d o;
    for (int k = 0; k < 3; ++k) o[k] = soup.scene.min[k] + u(rng) * (soup.scene.max[k] - soup.scene.min[k]);
    const BBox& b = soup.boxes[rng() % soup.boxes.size()].first;
    const Vec3d c{(b.min_corner().get<0>() + b.max_corner().get<0>()) / 2.0,
                  (b.min_corner().get<1>() + b.max_corner().get<1>()) / 2.0,
                  (b.min_corner().get<2>() + b.max_corner().get<2>()) / 2.0};
    rays.push_back(Query::Ray(o, {c.x - o.x, c.y - o.y, c.z - o.z}));
  }

  std::vector<std::vector<double>> kth(3);  // per k: mktree's k-th distance per query
  std::vector<double> first_t(a.queries, INFINITY);
  if (RunMktree(a, path, points, rays, &kth, &first_t) != 0) return 1;
  if (a.peers) {
    BoostPeer(a, soup, points, kth);
    EmbreePeer(a, soup, points, rays, kth[0], first_t);
    if (a.cgal) CgalPeer(soup, points, rays, kth[0], first_t);
  }
  if (!a.keep) std::filesystem::remove(path);
  return 0;
}
