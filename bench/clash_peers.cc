// In-RAM clash peers for scripts/bench_clash.py (bench/README.md, "Clash"): FCL 0.7 and CGAL 5.5 find
// the pairs of objects that meet (and, with a clearance C > 0, come closer than C) in a scene loaded
// whole into RAM, the way a user of those libraries would. Never linked into the engine.
//
//   clash_peers --engine fcl|cgal --scene tanker:N[:SEED]|FILE [--clearance C] [--object MESH]
//               [--pairs FILE] [--summary] [--world]
//
// Pair lines follow docs/clash.md's JSON contract as far as the peer knows: {"a", "b", "meeting",
// "class"?, "distance"?}; collide (--object) lines name the scene object as "b" and the object as a = -1.
// The last line is a summary: objects, triangles, pairs, load and clash seconds (clash = find + write:
// finding the pairs, then sorting and writing their lines, as mktree's clash time includes its visitor), peak
// RSS.
//
// Geometry: by default every object goes through the store's encoding (engine/store_format/object_codec.h)
// and back, so the peers test the very float32-local vertices mktree decodes; --world keeps the input's
// doubles.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>
#include <CGAL/squared_distance_3.h>
#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/distance.h>
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/geometry/mesh_edges.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/scene_source.h"
#include "engine/store_format/object_codec.h"

namespace mktree::bench {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Obj {
  ObjectId id = 0;
  Mesh mesh;  // store frame (world - origin) unless --world
  Box3d box;
  bool closed = false;
};

struct Options {
  std::string engine, scene, object, pairs_path;
  double clearance = 0;
  bool summary = false, world = false;
};

[[noreturn]] void Die(const std::string& msg) {
  std::fprintf(stderr, "clash_peers: %s\n", msg.c_str());
  std::exit(1);
}

Result<std::unique_ptr<SceneSource>> OpenSpec(const std::string& spec) {
  if (spec.rfind("tanker:", 0) == 0) {
    unsigned long long n = 0, seed = 1;
    if (std::sscanf(spec.c_str(), "tanker:%llu:%llu", &n, &seed) < 1 || n == 0)
      return Status::InvalidArgument("scene '" + spec + "': expected tanker:N[:SEED]");
    return MakeTankerSource(n, seed);
  }
  return OpenSceneFile(spec);
}

// Reads every object of `spec`; `origin` is set from the first object as ingest chooses it, unless given.
std::vector<Obj> Load(const std::string& spec, bool world, std::optional<Vec3d>* origin) {
  auto src = OpenSpec(spec);
  if (!src.ok()) Die(src.status().ToString());
  std::vector<Obj> objs;
  SceneObject so;
  std::vector<uint8_t> entry;
  CodecOptions raw;
  raw.codec = Codec::kNone;
  for (;;) {
    auto more = (*src)->Next(&so);
    if (!more.ok()) Die(more.status().ToString());
    if (!*more) break;
    if (so.mesh.triangle_count() == 0) continue;
    Obj o;
    o.id = so.id;
    if (world) {
      if (!origin->has_value()) *origin = Vec3d{0, 0, 0};
      o.mesh = std::move(so.mesh);
    } else {
      if (!origin->has_value()) *origin = ChooseStoreOrigin(so.mesh.Bounds());
      entry.clear();
      auto n = EncodeObjectEntry(so, **origin, raw, &entry);
      if (!n.ok()) Die(spec + ": " + n.status().ToString());
      auto view = ParseObjectEntry(entry.data(), entry.size());
      if (!view.ok()) Die(view.status().ToString());
      Status st = DecodeObjectMesh(*view, &o.mesh);
      if (!st.ok()) Die(st.ToString());
    }
    o.box = o.mesh.Bounds();
    o.closed = CheckEdges(o.mesh).closed;
    objs.push_back(std::move(o));
  }
  return objs;
}

enum class Meet { kApart, kCross, kAInB, kBInA };
const char* MeetName(Meet m) {
  switch (m) {
    case Meet::kCross:
      return "cross";
    case Meet::kAInB:
      return "a_inside_b";
    case Meet::kBInA:
      return "b_inside_a";
    default:
      return "apart";
  }
}

struct Pair {
  long long a, b;  // a = -1: the --object
  Meet meet;
  double distance;  // clearance pairs: the gap; meeting pairs: 0 (the peers do not measure depth)
  std::optional<std::array<double, 3>> point;
};

class Output {
 public:
  Output(const Options& opt) : summary_(opt.summary) {
    if (!opt.pairs_path.empty()) {
      f_ = std::fopen(opt.pairs_path.c_str(), "w");
      if (!f_) Die(opt.pairs_path + ": cannot write");
    } else {
      f_ = stdout;
    }
  }
  ~Output() {
    if (f_ != stdout) std::fclose(f_);
  }
  void Add(const Pair& p) {
    if (p.meet == Meet::kApart)
      ++clearance;
    else
      ++meeting;
    if (summary_) return;
    std::fprintf(f_, "{\"a\": %lld, \"b\": %lld, ", p.a, p.b);
    if (p.meet == Meet::kApart)
      std::fprintf(f_, "\"class\": \"clearance\", \"distance\": %.17g, ", p.distance);
    if (p.point)
      std::fprintf(f_, "\"point_a\": [%.17g, %.17g, %.17g], ", (*p.point)[0], (*p.point)[1], (*p.point)[2]);
    std::fprintf(f_, "\"meeting\": \"%s\"}\n", MeetName(p.meet));
  }
  uint64_t meeting = 0, clearance = 0;

 private:
  bool summary_;
  FILE* f_;
};

// ---- FCL: BVHModel<OBBRSS> per object, a dynamic AABB tree over them ----

using FclModel = fcl::BVHModel<fcl::OBBRSSd>;

std::shared_ptr<FclModel> FclMesh(const Mesh& m) {
  std::vector<fcl::Vector3d> pts(m.vertex_count());
  for (size_t i = 0; i < pts.size(); ++i)
    pts[i] = fcl::Vector3d(m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]);
  std::vector<fcl::Triangle> tris(m.triangle_count());
  for (size_t i = 0; i < tris.size(); ++i)
    tris[i] = fcl::Triangle(m.triangles[3 * i], m.triangles[3 * i + 1], m.triangles[3 * i + 2]);
  auto model = std::make_shared<FclModel>();
  model->beginModel(static_cast<int>(tris.size()), static_cast<int>(pts.size()));
  model->addSubModel(pts, tris);
  model->endModel();
  return model;
}

std::unique_ptr<fcl::CollisionObjectd> FclObject(const Mesh& m, double grow, intptr_t tag) {
  auto o = std::make_unique<fcl::CollisionObjectd>(FclMesh(m));
  o->computeAABB();
  if (grow > 0) {
    // The manager pairs objects by these boxes: grown by C, it yields the clearance candidates too.
    auto& box = const_cast<fcl::AABBd&>(o->getAABB());
    box.min_ -= fcl::Vector3d::Constant(grow);
    box.max_ += fcl::Vector3d::Constant(grow);
  }
  o->setUserData(reinterpret_cast<void*>(tag));
  return o;
}

struct FclRun {
  double clearance;
  Vec3d origin;
  std::vector<Pair> found;
  uint64_t candidates = 0;
};

bool FclPair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto* run = static_cast<FclRun*>(data);
  ++run->candidates;
  long long a = reinterpret_cast<intptr_t>(o1->getUserData());
  long long b = reinterpret_cast<intptr_t>(o2->getUserData());
  if (a > b) std::swap(a, b), std::swap(o1, o2);
  fcl::CollisionRequestd req(1, true);
  fcl::CollisionResultd res;
  fcl::collide(o1, o2, req, res);
  if (res.isCollision()) {
    const auto& c = res.getContact(0);
    run->found.push_back({a, b, Meet::kCross, 0,
                          std::array<double, 3>{c.pos[0] + run->origin.x, c.pos[1] + run->origin.y,
                                                c.pos[2] + run->origin.z}});
  } else if (run->clearance > 0) {
    fcl::DistanceRequestd dreq(true);
    fcl::DistanceResultd dres;
    fcl::distance(o1, o2, dreq, dres);
    if (dres.min_distance < run->clearance) run->found.push_back({a, b, Meet::kApart, dres.min_distance, {}});
  }
  return false;  // never stop early
}

// ---- CGAL: box_intersection_d on object boxes, exact triangle predicates on Epick ----

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using P3 = K::Point_3;
using Tri = K::Triangle_3;
using SMesh = CGAL::Surface_mesh<P3>;
using ObjBox = CGAL::Box_intersection_d::Box_with_info_d<double, 3, size_t>;

CGAL::Bbox_3 Grown(const Box3d& b, double c) {
  return CGAL::Bbox_3(b.min[0] - c, b.min[1] - c, b.min[2] - c, b.max[0] + c, b.max[1] + c, b.max[2] + c);
}

P3 Vertex(const Mesh& m, uint32_t v) {
  return P3(m.vertices[3 * v], m.vertices[3 * v + 1], m.vertices[3 * v + 2]);
}
Tri Triangle(const Mesh& m, size_t t) {
  return Tri(Vertex(m, m.triangles[3 * t]), Vertex(m, m.triangles[3 * t + 1]),
             Vertex(m, m.triangles[3 * t + 2]));
}

// A degenerate triangle (collinear corners) is its longest edge, or a point: CGAL's Triangle_3 predicates
// require non-degenerate triangles.
struct Prim {
  Tri t;
  int kind;  // 0 triangle, 1 segment, 2 point
  K::Segment_3 s;
};
Prim MakePrim(const Tri& t) {
  if (!t.is_degenerate()) return {t, 0, {}};
  const P3 &p = t[0], &q = t[1], &r = t[2];
  if (p == q && q == r) return {t, 2, K::Segment_3(p, p)};
  K::Segment_3 e[3] = {{p, q}, {q, r}, {r, p}};
  int best = 0;
  for (int i = 1; i < 3; ++i)
    if (e[i].squared_length() > e[best].squared_length()) best = i;
  return {t, 1, e[best]};
}
bool Meets(const Prim& x, const Prim& y) {
  if (x.kind == 2 && y.kind == 2) return x.s.source() == y.s.source();
  if (x.kind == 2) return y.kind == 0 ? y.t.has_on(x.s.source()) : y.s.has_on(x.s.source());
  if (y.kind == 2) return Meets(y, x);
  if (x.kind == 0 && y.kind == 0) return CGAL::do_intersect(x.t, y.t);
  if (x.kind == 0) return CGAL::do_intersect(x.t, y.s);
  if (y.kind == 0) return CGAL::do_intersect(x.s, y.t);
  return CGAL::do_intersect(x.s, y.s);
}
// Squared gap of two primitives that do not meet (CGAL 5.5 has no triangle-segment distance: the gap of
// a triangle and a segment that do not cross is the least of the segment's ends against the triangle
// and the segment against the triangle's edges).
double SqDist(const Prim& x, const Prim& y) {
  if (x.kind == 0 && y.kind == 0) return CGAL::to_double(CGAL::squared_distance(x.t, y.t));
  if (x.kind != 0 && y.kind == 0) return SqDist(y, x);
  if (x.kind == 0) {
    if (y.kind == 2) return CGAL::to_double(CGAL::squared_distance(x.t, y.s.source()));
    double d = std::min(CGAL::to_double(CGAL::squared_distance(x.t, y.s.source())),
                        CGAL::to_double(CGAL::squared_distance(x.t, y.s.target())));
    for (int i = 0; i < 3; ++i)
      d = std::min(d, CGAL::to_double(CGAL::squared_distance(K::Segment_3(x.t[i], x.t[(i + 1) % 3]), y.s)));
    return d;
  }
  if (x.kind == 2 && y.kind == 2) return CGAL::to_double(CGAL::squared_distance(x.s.source(), y.s.source()));
  if (x.kind == 2) return CGAL::to_double(CGAL::squared_distance(x.s.source(), y.s));
  if (y.kind == 2) return CGAL::to_double(CGAL::squared_distance(x.s, y.s.source()));
  return CGAL::to_double(CGAL::squared_distance(x.s, y.s));
}

class CgalRun {
 public:
  // side_ has one slot more than objs: the collide query object's (index objs.size()).
  CgalRun(const std::vector<Obj>& objs, double clearance)
      : objs_(objs), c_(clearance), side_(objs.size() + 1) {}

  // Objects i and j (indexes into objs, or the --object as `query`) given their boxes met grown by C.
  void Test(const Obj& A, const Obj& B, size_t ia, size_t ib, long long a, long long b,
            std::vector<Pair>* out) {
    ++candidates;
    std::vector<ObjBox> ta, tb;
    CollectTriangles(A, B.box, &ta);
    CollectTriangles(B, A.box, &tb);
    bool meet = false;
    double best = std::numeric_limits<double>::infinity();
    auto visit = [&](const ObjBox& x, const ObjBox& y) {
      if (meet) return;
      Prim px = MakePrim(Triangle(A.mesh, x.info())), py = MakePrim(Triangle(B.mesh, y.info()));
      ++triangle_tests;
      if (Meets(px, py)) {
        meet = true;
      } else if (c_ > 0) {
        best = std::min(best, SqDist(px, py));
      }
    };
    if (!ta.empty() && !tb.empty())
      CGAL::box_intersection_d(ta.begin(), ta.end(), tb.begin(), tb.end(), visit);
    if (meet) return out->push_back({a, b, Meet::kCross, 0, {}});
    if (Inside(A, B, ib)) return out->push_back({a, b, Meet::kAInB, 0, {}});
    if (Inside(B, A, ia)) return out->push_back({a, b, Meet::kBInA, 0, {}});
    if (c_ > 0 && best < c_ * c_) out->push_back({a, b, Meet::kApart, std::sqrt(best), {}});
  }

  uint64_t candidates = 0, triangle_tests = 0, containment_tests = 0, side_meshes = 0, side_failures = 0;

 private:
  struct Side {
    SMesh mesh;
    bool ok = false;
    std::unique_ptr<CGAL::Side_of_triangle_mesh<SMesh, K>> tester;
  };

  void CollectTriangles(const Obj& o, const Box3d& other, std::vector<ObjBox>* out) {
    CGAL::Bbox_3 region = Grown(other, c_);
    for (size_t t = 0; t < o.mesh.triangle_count(); ++t) {
      CGAL::Bbox_3 b = Triangle(o.mesh, t).bbox();
      double h = c_ / 2;
      CGAL::Bbox_3 tb(b.xmin() - h, b.ymin() - h, b.zmin() - h, b.xmax() + h, b.ymax() + h, b.zmax() + h);
      if (CGAL::do_overlap(tb, region)) out->push_back(ObjBox(tb, t));
    }
  }

  // Does a part of solid A lie inside solid B, given that no triangles meet? Both must be closed: an open
  // mesh is a surface, nothing is inside it and it is inside nothing (docs/clash.md, section 1). With no
  // triangles meeting, each connected component of A lies wholly inside or wholly outside B, so A meets B
  // this way iff some vertex of A is strictly inside B. Every vertex is tested (one per component would
  // do, but finding components is what mktree does; the peer stays naive). A vertex on B's boundary would
  // mean the triangles meet; it decides nothing.
  bool Inside(const Obj& A, const Obj& B, size_t ib) {
    if (ib == SIZE_MAX || !A.closed || !B.closed) return false;
    auto in_box = [&](size_t v) {
      for (int k = 0; k < 3; ++k) {
        const double x = A.mesh.vertices[3 * v + k];
        if (x < B.box.min[k] || x > B.box.max[k]) return false;
      }
      return true;
    };
    size_t first = 0;
    while (first < A.mesh.vertex_count() && !in_box(first)) ++first;
    if (first == A.mesh.vertex_count()) return false;  // no vertex of A in B's box
    auto& side = side_[ib];
    if (!side) side = MakeSide(B);
    if (!side->ok) return false;
    ++containment_tests;
    for (size_t v = first; v < A.mesh.vertex_count(); ++v)
      if (in_box(v) && (*side->tester)(Vertex(A.mesh, v)) == CGAL::ON_BOUNDED_SIDE) return true;
    return false;
  }

  // B as a CGAL Surface_mesh for Side_of_triangle_mesh, which needs a closed triangle mesh. The stored
  // mesh may repeat a point under several vertex indexes (the real scenes do: a steel plate has 32
  // vertices for its 12 triangles), so the soup is repaired first (equal points merged, triangles with
  // two equal corners dropped), as CheckEdges judges closedness on positions too.
  std::unique_ptr<Side> MakeSide(const Obj& B) {
    ++side_meshes;
    auto entry = std::make_unique<Side>();
    std::vector<P3> pts;
    for (size_t v = 0; v < B.mesh.vertex_count(); ++v) pts.push_back(Vertex(B.mesh, v));
    std::vector<std::vector<size_t>> faces;
    for (size_t t = 0; t < B.mesh.triangle_count(); ++t)
      faces.push_back({B.mesh.triangles[3 * t], B.mesh.triangles[3 * t + 1], B.mesh.triangles[3 * t + 2]});
    namespace PMP = CGAL::Polygon_mesh_processing;
    PMP::repair_polygon_soup(pts, faces);
    PMP::orient_polygon_soup(pts, faces);
    PMP::polygon_soup_to_polygon_mesh(pts, faces, entry->mesh);
    entry->ok =
        !CGAL::is_empty(entry->mesh) && CGAL::is_closed(entry->mesh) && CGAL::is_triangle_mesh(entry->mesh);
    if (entry->ok)
      entry->tester = std::make_unique<CGAL::Side_of_triangle_mesh<SMesh, K>>(entry->mesh);
    else
      ++side_failures;  // closed by CheckEdges, not by CGAL: no containment for this B (counted, reported)
    return entry;
  }

  const std::vector<Obj>& objs_;
  double c_;
  std::vector<std::unique_ptr<Side>> side_;
};

long PeakRssKib() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss;
}

int Main(int argc, char** argv) {
  Options opt;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) Die(a + " needs a value");
      return argv[++i];
    };
    if (a == "--engine")
      opt.engine = next();
    else if (a == "--scene")
      opt.scene = next();
    else if (a == "--object")
      opt.object = next();
    else if (a == "--pairs")
      opt.pairs_path = next();
    else if (a == "--clearance")
      opt.clearance = std::strtod(next().c_str(), nullptr);
    else if (a == "--summary")
      opt.summary = true;
    else if (a == "--world")
      opt.world = true;
    else if (a == "--versions") {
      std::printf("FCL %s, CGAL %s\n", FCL_VERSION, CGAL_VERSION_STR);
      return 0;
    } else
      Die("unknown argument " + a + " (see bench/clash_peers.cc)");
  }
  if ((opt.engine != "fcl" && opt.engine != "cgal") || opt.scene.empty())
    Die("usage: clash_peers --engine fcl|cgal --scene SPEC [--clearance C] [--object MESH] [--pairs FILE] "
        "[--summary] [--world]");
  if (!(opt.clearance >= 0) || !std::isfinite(opt.clearance)) Die("--clearance must be finite and >= 0");

  auto t0 = Clock::now();
  std::optional<Vec3d> origin;
  std::vector<Obj> objs = Load(opt.scene, opt.world, &origin);
  if (objs.empty()) Die(opt.scene + ": no object with geometry");
  std::vector<Obj> query;
  if (!opt.object.empty()) {
    query = Load(opt.object, opt.world, &origin);  // in the scene's frame
    if (query.empty()) Die(opt.object + ": no object with geometry");
    // The collide query is one object: every mesh of the file, merged.
    for (size_t i = 1; i < query.size(); ++i) {
      uint32_t base = static_cast<uint32_t>(query[0].mesh.vertex_count());
      auto& m = query[0].mesh;
      m.vertices.insert(m.vertices.end(), query[i].mesh.vertices.begin(), query[i].mesh.vertices.end());
      for (uint32_t v : query[i].mesh.triangles) m.triangles.push_back(v + base);
    }
    query.resize(1);
    query[0].box = query[0].mesh.Bounds();
    query[0].closed = CheckEdges(query[0].mesh).closed;
  }
  uint64_t triangles = 0;
  Box3d bounds;
  for (const Obj& o : objs) {
    triangles += o.mesh.triangle_count();
    for (int k = 0; k < 3; ++k) {
      double shift = k == 0 ? origin->x : k == 1 ? origin->y : origin->z;
      bounds.min[k] = std::min(bounds.min[k], o.box.min[k] + shift);
      bounds.max[k] = std::max(bounds.max[k], o.box.max[k] + shift);
    }
  }
  char bounds_json[256];
  std::snprintf(bounds_json, sizeof bounds_json, ", \"bounds\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g]",
                bounds.min[0], bounds.min[1], bounds.min[2], bounds.max[0], bounds.max[1], bounds.max[2]);

  Output out(opt);
  std::vector<Pair> found;
  double load_s = 0, clash_s = 0;
  uint64_t candidates = 0;
  std::string extra;
  if (opt.engine == "fcl") {
    FclRun run{opt.clearance, *origin, {}};
    std::vector<std::unique_ptr<fcl::CollisionObjectd>> owned;
    std::vector<fcl::CollisionObjectd*> ptrs;
    for (size_t i = 0; i < objs.size(); ++i) {
      owned.push_back(FclObject(objs[i].mesh, opt.clearance, objs[i].id));
      ptrs.push_back(owned.back().get());
      Mesh().vertices.swap(objs[i].mesh.vertices);  // FCL keeps its own copy
      Mesh().triangles.swap(objs[i].mesh.triangles);
    }
    fcl::DynamicAABBTreeCollisionManagerd manager;
    manager.registerObjects(ptrs);
    manager.setup();
    load_s = Since(t0);
    auto t1 = Clock::now();
    if (query.empty()) {
      manager.collide(&run, FclPair);
    } else {
      auto q = FclObject(query[0].mesh, opt.clearance, -1);
      manager.collide(q.get(), &run, FclPair);
    }
    clash_s = Since(t1);
    found = std::move(run.found);
    candidates = run.candidates;
  } else {
    load_s = Since(t0);
    auto t1 = Clock::now();
    CgalRun run(objs, opt.clearance);
    std::vector<ObjBox> boxes;
    boxes.reserve(objs.size());
    for (size_t i = 0; i < objs.size(); ++i) boxes.emplace_back(Grown(objs[i].box, opt.clearance / 2), i);
    if (query.empty()) {
      CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const ObjBox& x, const ObjBox& y) {
        size_t i = x.info(), j = y.info();
        if (objs[i].id > objs[j].id) std::swap(i, j);
        run.Test(objs[i], objs[j], i, j, objs[i].id, objs[j].id, &found);
      });
    } else {
      std::vector<ObjBox> qb{ObjBox(Grown(query[0].box, opt.clearance / 2), 0)};
      CGAL::box_intersection_d(qb.begin(), qb.end(), boxes.begin(), boxes.end(),
                               [&](const ObjBox&, const ObjBox& y) {
                                 size_t j = y.info();
                                 run.Test(query[0], objs[j], objs.size(), j, -1, objs[j].id, &found);
                               });
    }
    clash_s = Since(t1);
    candidates = run.candidates;
    extra = ", \"triangle_tests\": " + std::to_string(run.triangle_tests) +
            ", \"containment_tests\": " + std::to_string(run.containment_tests) +
            ", \"side_meshes\": " + std::to_string(run.side_meshes) +
            ", \"side_mesh_failures\": " + std::to_string(run.side_failures);
  }
  // Writing the pairs is timed too: mktree's clash time includes its visitor writing every pair's line.
  const auto t2 = Clock::now();
  std::sort(found.begin(), found.end(),
            [](const Pair& x, const Pair& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
  for (const Pair& p : found) out.Add(p);
  const double write_s = Since(t2);
  std::fflush(stdout);
  std::printf(
      "{\"engine\": \"%s\", \"objects\": %zu, \"triangles\": %llu, \"clearance\": %.17g, \"candidates\": "
      "%llu, "
      "\"pairs\": %zu, \"meeting\": %llu, \"clearance_pairs\": %llu, \"load_seconds\": %.3f, "
      "\"clash_seconds\": %.4f, \"find_seconds\": %.4f, \"write_seconds\": %.4f, \"peak_rss_kib\": "
      "%ld%s%s}\n",
      opt.engine.c_str(), objs.size(), static_cast<unsigned long long>(triangles), opt.clearance,
      static_cast<unsigned long long>(candidates), found.size(), static_cast<unsigned long long>(out.meeting),
      static_cast<unsigned long long>(out.clearance), load_s, clash_s + write_s, clash_s, write_s,
      PeakRssKib(), extra.c_str(), bounds_json);
  return 0;
}

}  // namespace
}  // namespace mktree::bench

int main(int argc, char** argv) { return mktree::bench::Main(argc, argv); }
