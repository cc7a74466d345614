#include "engine/clash/clash_engine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <queue>
#include <thread>
#include <utility>
#include <vector>

#include "engine/clash/leaf_pairs.h"
#include "engine/clash/pair_rules.h"
#include "engine/clash/sweep_schedule.h"
#include "engine/clash/work_pool.h"
#include "engine/geometry/mesh_separation.h"
#include "engine/store/leaf_reader.h"
#include "engine/tree/leaf_filter.h"

namespace mktree {

namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

unsigned ThreadCount(unsigned t) { return t ? t : std::max(1u, std::thread::hardware_concurrency()); }

// Pairs found in one batch, in the leaf pairs' order per pair.
constexpr size_t kBatchPairs = 1024;
// Collide tests candidates in chunks of about this many objects, with at most this many leaves pinned
// in the cache meanwhile (their entries are decoded on the worker threads).
constexpr size_t kCollideChunk = 256;
constexpr size_t kCollidePinnedLeaves = 16;

// The edge check ingest stored with the entry (computed by ClashShape when absent).
std::optional<EdgeCheck> StoredEdges(const ObjectEntryView& e) {
  if (!(e.shape_flags & kShapeKnown)) return std::nullopt;
  EdgeCheck edges;
  edges.even = (e.shape_flags & kShapeEvenEdges) != 0;
  edges.closed = (e.shape_flags & kShapeClosed) != 0;
  return edges;
}

// One object of a decoded leaf: its float32 box, and its mesh and shape when some candidate pair may
// need them (NeededObjects).
struct LoadedObject {
  ObjectId id = 0;
  Box3d box;
  double resolution = 0;  // CoordinateResolution of its entry (with the shape: only candidates need it)
  std::unique_ptr<Mesh> mesh;
  std::unique_ptr<ClashShape> shape;
};
struct LoadedLeaf {
  std::vector<LoadedObject> objects;
  uint64_t bytes = 0;  // heap held by its meshes and shapes (about)
};

constexpr size_t kKeptFoundCapacity = 16;
// Leaf pairs tested between two hand-overs of found pairs to the visitor.
constexpr size_t kNarrowChunk = 128;

// What the tests of one leaf pair (or one collide chunk) found.
struct PairWork {
  std::vector<ClashPair> found;
  uint64_t candidates = 0, excluded = 0;
  NarrowStats narrow;
  void Clear() {
    // A slot keeps no more than a typical leaf pair's pairs: each of a batch's slots would otherwise keep
    // the most it ever held, and two batches of slots are alive (megabytes on the 100k tanker).
    if (found.capacity() > kKeptFoundCapacity) {
      std::vector<ClashPair>().swap(found);
    } else {
      found.clear();
    }
    candidates = excluded = 0;
    narrow = {};
  }
};

// Hands pairs to the visitor in order: the cap, unreported touches and the class counts.
struct Emitter {
  const ClashOptions& o;
  const ClashVisitor& visit;
  ClashStats& s;
  void Add(const PairWork& w) {
    s.candidate_pairs += w.candidates;
    s.excluded_pairs += w.excluded;
    s.bound_rejects += w.narrow.bound_rejects;
    s.triangle_tests += w.narrow.triangle_tests;
    s.containment_tests += w.narrow.containment_tests;
    s.hierarchies_built += w.narrow.hierarchies_built;
    s.classifiers_built += w.narrow.classifiers_built;
    for (const ClashPair& p : w.found) {
      clash::CountClass(p, &s);
      if (p.cls == ClashClass::kTouch && !o.report_touch) {
        ++s.unreported_touches;
      } else if (s.reported_pairs >= o.max_pairs) {
        ++s.capped_pairs;
      } else {
        ++s.reported_pairs;
        if (visit) visit(p);
      }
    }
  }
};

// The I/O counts of a call: the cache's, and which pages were looked up.
struct IoCount {
  QueryStats q;
  std::vector<uint8_t> touched;
  void Mark(const LeafInfo& info, uint64_t base = 0) {
    for (uint64_t p = base + info.first_page; p < base + info.first_page + info.page_count; ++p) {
      if (p >= touched.size()) touched.resize(p + 1, 0);
      touched[p] = 1;
    }
  }
  void Fill(ClashStats* s) const {
    s->pages_read = q.pages_read;
    s->pages_touched = q.pages_touched;
    s->distinct_pages = static_cast<uint64_t>(std::count(touched.begin(), touched.end(), 1));
  }
};

// What a leaf takes decoded, estimated before it is read from its encoded size (the entry headers with
// the vertex and triangle counts are in its pages): per object its box and the fixed part of a shape,
// per payload byte the double mesh and the parts its pairs build (hierarchy, classifier). A stored byte
// decodes to 12 (tanker) to 18 (steel) bytes on average (zstd), no measured leaf above its estimate;
// other scenes may exceed it, and the window its budget by that error (docs/clash.md section 3).
constexpr uint64_t kDecodedBytesPerObject = 512;
constexpr uint64_t kDecodedBytesPerPayloadByte = 24;
uint64_t DecodedLeafEstimate(const LeafInfo& info) {
  return info.object_count * kDecodedBytesPerObject + kDecodedBytesPerPayloadByte * info.payload_bytes;
}

// The heap a decoded leaf holds (about).
uint64_t DecodedLeafBytes(const LoadedLeaf& l) {
  uint64_t bytes = l.objects.capacity() * sizeof(LoadedObject);
  for (const LoadedObject& obj : l.objects) {
    if (obj.mesh)
      bytes += sizeof(Mesh) + obj.mesh->vertices.capacity() * sizeof(double) +
               obj.mesh->triangles.capacity() * sizeof(uint32_t);
    if (obj.shape) bytes += obj.shape->MemoryBytes();
  }
  return bytes;
}

// LeafSource::Read with one duplicate-id scratch for every pinned leaf: a read leaves it all zero, and
// each PinnedLeaf's own would keep a bit per object of the store (a batch pins up to hundreds of leaves).
Status ReadPinned(const LeafSource& st, uint32_t leaf, IoCount* io, std::vector<uint64_t>* seen,
                  PinnedLeaf* out, uint64_t page_base = 0) {
  const LeafInfo& info = st.reader().tree().leaves[leaf];
  out->seen.swap(*seen);
  const Status s = st.Read(leaf, &io->q, out);
  out->seen.swap(*seen);
  if (s.ok()) io->Mark(info, page_base);
  return s;
}

uint64_t StorePages(const MKTree& tree) {
  uint64_t n = 0;
  for (const LeafInfo& l : tree.leaves) n += l.page_count;
  return n;
}

// Tests the candidate pairs of leaves p and q (the same leaf: its pairs i < j).
Status TestLeafPair(const std::string& store, const LoadedLeaf& lp, const LoadedLeaf& lq, bool same,
                    const ClashOptions& o, const clash::Exclusions& ex, const Vec3d& origin, PairWork* w) {
  const double c = o.clearance;
  const auto& A = lp.objects;
  const auto& B = lq.objects;
  for (size_t i = 0; i < A.size(); ++i) {
    for (size_t j = same ? i + 1 : 0; j < B.size(); ++j) {
      if (!clash::GrownMeet(A[i].box, B[j].box, c)) continue;
      ++w->candidates;
      const LoadedObject* a = &A[i];
      const LoadedObject* b = &B[j];
      if (a->id > b->id) std::swap(a, b);
      // Ids never repeat within a leaf; across two only if their id digests were made to collide.
      if (a->id == b->id)
        return Status::Corruption(store + ": object " + std::to_string(a->id) +
                                  " is in two leaves (their id digests were made to collide)");
      if (ex.Excluded(a->id, b->id)) {
        ++w->excluded;
        continue;
      }
      if (!a->shape || !b->shape)
        return Status::Internal("clash: objects " + std::to_string(a->id) + " and " + std::to_string(b->id) +
                                " are a candidate pair the leaf filter did not admit");
      const double r = a->resolution + b->resolution;
      const Separation sep = Separate(*a->shape, *b->shape, clash::NarrowMaxDistance(o, r), &w->narrow,
                                      clash::NarrowOptions(o, r));
      ClashPair pair;
      if (clash::Classify(sep, o, r, a->id, b->id, origin, &pair)) w->found.push_back(pair);
    }
  }
  return Status::Ok();
}

// The first error of `errors` (in order), or Ok.
Status FirstError(const std::vector<Status>& errors) {
  for (const Status& e : errors)
    if (!e.ok()) return e;
  return Status::Ok();
}

}  // namespace

Status RunSelfClash(const LeafSource& st, const ClashOptions& o, const ClashVisitor& visit,
                    ClashStats* stats) {
  return RunMultiClash({ClashPart{&st, nullptr}}, nullptr, o, visit, stats);
}

Status RunMultiClash(const std::vector<ClashPart>& parts, const ClashPartPairs& want, const ClashOptions& o,
                     const ClashVisitor& visit, ClashStats* stats) {
  ClashStats local;
  ClashStats& s = stats ? *stats : local;
  s = ClashStats();
  MKTREE_RETURN_IF_ERROR(clash::CheckOptions(o));
  const Clock::time_point start = Clock::now();
  const size_t np = parts.size();
  if (np == 0) return Status::Ok();
  // Leaves of all parts numbered one after the other (part k's from leaf_base[k]); pages likewise.
  std::vector<uint32_t> leaf_base(np + 1, 0), part_of;
  std::vector<uint64_t> page_base(np + 1, 0);
  uint64_t global_count = 0, cache_bytes = 0;
  for (size_t k = 0; k < np; ++k) {
    const StoreReader& r = parts[k].leaves->reader();
    const MKTree& t = r.tree();
    leaf_base[k + 1] = leaf_base[k] + static_cast<uint32_t>(t.leaves.size());
    part_of.resize(leaf_base[k + 1], static_cast<uint32_t>(k));
    page_base[k + 1] = page_base[k] + r.pages().page_count();
    s.store_pages += StorePages(t);
    const std::vector<ObjectId>* ids = parts[k].ids;
    if (ids && ids->size() != r.object_count())
      return Status::Internal(r.path() + ": the part's id map does not match its objects");
    global_count = std::max<uint64_t>(
        global_count, ids ? (ids->empty() ? 0 : ids->back() + uint64_t{1}) : r.object_count());
    cache_bytes += parts[k].leaves->cache().capacity() * t.params.mem_page();
  }
  auto global_id = [&](size_t k, ObjectId id) { return parts[k].ids ? (*parts[k].ids)[id] : id; };
  auto wanted = [&](uint32_t i, uint32_t j) { return !want || want(i, j); };
  clash::WorkPool pool(ThreadCount(o.threads));
  // Group names from the record pages, read in id order (each page once) straight from the stores, so
  // that the clash's own page counts stay its leaves'; a damaged record page fails the run. Global ids
  // come in increasing order: the parts' next ids in a heap (ids increase within a part).
  Status names_status;
  std::vector<std::unique_ptr<RecordReader>> names;
  for (const ClashPart& part : parts)
    names.push_back(std::make_unique<RecordReader>(part.leaves->reader().record_layout(), nullptr,
                                                   part.leaves->verify_checksums()));
  std::vector<uint64_t> cursor(np, 0);
  using Head = std::pair<uint64_t, size_t>;  // (global id, part)
  std::priority_queue<Head, std::vector<Head>, std::greater<Head>> heads;
  if (!o.exclude_group_separator.empty())
    for (size_t k = 0; k < np; ++k)
      if (parts[k].leaves->reader().object_count() > 0) heads.push({global_id(k, 0), k});
  const clash::Exclusions ex(o, global_count, [&](uint64_t g) -> std::string_view {
    if (!names_status.ok() || heads.empty() || heads.top().first != g) return {};
    const size_t k = heads.top().second;
    heads.pop();
    const uint64_t at = cursor[k]++;
    if (cursor[k] < parts[k].leaves->reader().object_count())
      heads.push({global_id(k, static_cast<ObjectId>(cursor[k])), k});
    auto r = names[k]->Get(static_cast<uint32_t>(at), nullptr);
    if (!r.ok()) names_status = r.status();
    return r.ok() ? std::string_view((*r)->name) : std::string_view();
  });
  MKTREE_RETURN_IF_ERROR(names_status);
  names.clear();

  // Broad phase: leaf pairs through each tree and between the trees of parts whose roots grown by C meet,
  // the leaf filter, the plan.
  std::vector<clash::LeafPair> pairs;
  std::vector<clash::NeededObjects> needed(np);
  std::vector<uint8_t> filtered(np, 0);
  for (uint32_t k = 0; k < np; ++k) {
    const MKTree& t = parts[k].leaves->reader().tree();
    filtered[k] = clash::InitNeeded(t, &needed[k]);
    if (!wanted(k, k)) continue;
    std::vector<clash::LeafPair> own = clash::TreeLeafPairs(t, o.clearance);
    s.leaf_pairs_tree += own.size();
    clash::FilterLeafPairs(t, o.clearance, pool, &own, &needed[k]);
    for (const clash::LeafPair& lp : own) pairs.push_back({lp.p + leaf_base[k], lp.q + leaf_base[k]});
  }
  for (uint32_t i = 0; i < np; ++i) {
    const MKTree& ti = parts[i].leaves->reader().tree();
    for (uint32_t j = i + 1; j < np; ++j) {
      const MKTree& tj = parts[j].leaves->reader().tree();
      if (!wanted(i, j) || ti.empty() || tj.empty() ||
          !clash::GrownMeet(clash::ToBox3d(ti.nodes[0].box), clash::ToBox3d(tj.nodes[0].box), o.clearance))
        continue;
      std::vector<clash::LeafPair> cross = clash::CrossLeafPairs(ti, tj, o.clearance);
      s.leaf_pairs_tree += cross.size();
      if (filtered[i] && filtered[j]) {
        clash::FilterCrossLeafPairs(ti, tj, o.clearance, pool, &cross, &needed[i], &needed[j]);
      } else if (!cross.empty()) {
        needed[i].all = needed[j].all = true;
      }
      for (const clash::LeafPair& lp : cross) pairs.push_back({lp.p + leaf_base[i], lp.q + leaf_base[j]});
    }
  }
  s.leaf_pairs_visited = pairs.size();
  s.window_budget_bytes = o.window_bytes ? o.window_bytes
                                         : std::max<uint64_t>(kDefaultClashWindowBytes,
                                                              kDecodedBytesPerPayloadByte * cache_bytes);
  const uint32_t total_leaves = leaf_base[np];
  std::vector<uint64_t> leaf_bytes(total_leaves);
  for (uint32_t g = 0; g < total_leaves; ++g)
    leaf_bytes[g] =
        DecodedLeafEstimate(parts[part_of[g]].leaves->reader().tree().leaves[g - leaf_base[part_of[g]]]);
  clash::SweepPlan plan;
  if (np == 1) {
    plan = clash::PlanSweep(parts[0].leaves->reader().tree(), std::move(pairs), leaf_bytes,
                            s.window_budget_bytes, kBatchPairs);
  } else {
    Box3f root;
    std::vector<Box3f> boxes(total_leaves);
    bool any = false;
    for (size_t k = 0; k < np; ++k) {
      const MKTree& t = parts[k].leaves->reader().tree();
      for (size_t l = 0; l < t.leaves.size(); ++l) boxes[leaf_base[k] + l] = t.leaves[l].box;
      if (t.empty()) continue;
      if (!any) {
        root = t.nodes[0].box;
      } else {
        for (int i = 0; i < 3; ++i) {
          root.min[i] = std::min(root.min[i], t.nodes[0].box.min[i]);
          root.max[i] = std::max(root.max[i], t.nodes[0].box.max[i]);
        }
      }
      any = true;
    }
    plan = clash::PlanSweep(root, boxes, std::move(pairs), leaf_bytes, s.window_budget_bytes, kBatchPairs);
  }
  s.leaf_reads = plan.leaf_reads;
  s.leaf_rereads = plan.leaf_rereads;
  s.broad_seconds = Since(start);
  const Vec3d origin = parts[0].leaves->reader().tree().origin;

  std::vector<std::unique_ptr<LoadedLeaf>> window(total_leaves);
  uint64_t window_bytes = 0;
  std::vector<PinnedLeaf> pinned;
  std::vector<uint64_t> seen;
  IoCount io;
  Emitter emit{o, visit, s};
  std::vector<PairWork> work, previous;  // this chunk's results, the last chunk's (not yet handed on)
  size_t previous_count = 0;
  auto emit_previous = [&] {
    for (size_t k = 0; k < previous_count; ++k) emit.Add(previous[k]);
    previous_count = 0;
  };
  std::vector<Status> errors;
  struct DecodeTask {
    size_t load;  // index into the batch's loads
    uint32_t pos;
  };
  std::vector<DecodeTask> tasks;
  std::vector<std::unique_ptr<LoadedLeaf>> loaded;
  for (size_t bi = 0; bi < plan.batches.size(); ++bi) {
    const clash::SweepBatch& b = plan.batches[bi];
    auto drop = [&](uint32_t leaf) {
      if (window[leaf]) window_bytes -= window[leaf]->bytes;
      window[leaf].reset();
    };
    for (uint32_t leaf : b.evict) drop(leaf);

    // Read: the pages in sweep order on this thread (so that the cache's counts do not depend on the
    // threads), then the meshes and shapes of the objects that may be in a pair, on all threads.
    Clock::time_point t = Clock::now();
    if (pinned.size() < b.load.size()) pinned.resize(b.load.size());
    loaded.clear();
    tasks.clear();
    for (size_t i = 0; i < b.load.size(); ++i) {
      const uint32_t k = part_of[b.load[i]];
      const uint32_t leaf = b.load[i] - leaf_base[k];
      const LeafSource& st = *parts[k].leaves;
      MKTREE_RETURN_IF_ERROR(ReadPinned(st, leaf, &io, &seen, &pinned[i], page_base[k]));
      auto l = std::make_unique<LoadedLeaf>();
      const auto& entries = pinned[i].view.entries();
      l->objects.resize(entries.size());
      for (uint32_t pos = 0; pos < entries.size(); ++pos) {
        l->objects[pos].id = global_id(k, entries[pos].id);
        l->objects[pos].box = clash::ToBox3d(entries[pos].box);
        if (needed[k](st.reader().tree(), leaf, pos)) tasks.push_back({i, pos});
      }
      loaded.push_back(std::move(l));
    }
    errors.assign(tasks.size(), Status::Ok());
    pool.For(tasks.size(), [&](size_t k) {
      const DecodeTask& task = tasks[k];
      const ObjectEntryView& e = pinned[task.load].view.entry(task.pos);
      LoadedObject& obj = loaded[task.load]->objects[task.pos];
      obj.resolution = CoordinateResolution(e.box);
      obj.mesh = std::make_unique<Mesh>();
      errors[k] = parts[part_of[b.load[task.load]]].leaves->DecodeMesh(e, obj.mesh.get());
      if (errors[k].ok()) obj.shape = std::make_unique<ClashShape>(*obj.mesh, StoredEdges(e));
    });
    for (size_t i = 0; i < b.load.size(); ++i) pinned[i].Release();
    MKTREE_RETURN_IF_ERROR(FirstError(errors));
    s.shapes_prepared += tasks.size();
    for (size_t i = 0; i < b.load.size(); ++i) {
      loaded[i]->bytes = DecodedLeafBytes(*loaded[i]);
      window_bytes += loaded[i]->bytes;
      window[b.load[i]] = std::move(loaded[i]);
    }
    s.window_peak_bytes = std::max(s.window_peak_bytes, window_bytes);
    s.read_seconds += Since(t);

    // Narrow phase: the batch's leaf pairs on all threads, a chunk at a time; meanwhile this thread hands
    // the previous chunk's pairs on, in order (formatting and writing millions of pairs is serial work).
    // Chunks, not whole batches, so that the pairs found but not yet handed on stay few.
    t = Clock::now();
    const size_t n = b.pair_end - b.pair_begin;
    for (size_t from = 0; from < n; from += kNarrowChunk) {
      const size_t count = std::min(kNarrowChunk, n - from);
      if (work.size() < count) work.resize(count);
      errors.assign(count, Status::Ok());
      pool.For(
          count,
          [&](size_t k) {
            const clash::LeafPair& lp = plan.pairs[b.pair_begin + from + k];
            work[k].Clear();
            errors[k] = TestLeafPair(parts[part_of[lp.p]].leaves->reader().path(), *window[lp.p],
                                     *window[lp.q], lp.p == lp.q, o, ex, origin, &work[k]);
          },
          [&] { emit_previous(); });
      MKTREE_RETURN_IF_ERROR(FirstError(errors));
      std::swap(work, previous);
      previous_count = count;
    }
    // The shapes' parts built by these pairs: the window holds them until the leaves leave.
    for (size_t k = b.pair_begin; k < b.pair_end; ++k)
      for (uint32_t leaf : {plan.pairs[k].p, plan.pairs[k].q}) {
        LoadedLeaf& l = *window[leaf];
        const uint64_t now = DecodedLeafBytes(l);
        window_bytes += now - l.bytes;
        l.bytes = now;
      }
    s.window_peak_bytes = std::max(s.window_peak_bytes, window_bytes);
    s.narrow_seconds += Since(t);
    for (uint32_t leaf : b.drop) drop(leaf);
    if (o.progress) o.progress(bi + 1, plan.batches.size());
  }
  emit_previous();
  io.Fill(&s);
  s.total_seconds = Since(start);
  return Status::Ok();
}

Status CheckCollideMesh(const Mesh& mesh, const std::optional<RigidTransform>& transform) {
  if (mesh.triangles.empty() || mesh.vertices.empty())
    return Status::InvalidArgument("collide: the object's mesh is empty");
  if (mesh.vertices.size() % 3 || mesh.triangles.size() % 3)
    return Status::InvalidArgument("collide: the object's mesh arrays are not triples");
  for (double v : mesh.vertices)
    if (!std::isfinite(v)) return Status::InvalidArgument("collide: the object has a non-finite vertex");
  for (uint32_t t : mesh.triangles)
    if (t >= mesh.vertex_count())
      return Status::InvalidArgument("collide: the object has a triangle index out of range");
  if (transform) {
    const double* m = transform->rotation;
    const Vec3d& tr = transform->translation;
    for (int i = 0; i < 9; ++i)
      if (!std::isfinite(m[i])) return Status::InvalidArgument("collide: a non-finite rotation");
    if (!std::isfinite(tr.x) || !std::isfinite(tr.y) || !std::isfinite(tr.z))
      return Status::InvalidArgument("collide: a non-finite translation");
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        const double dot = m[3 * i] * m[3 * j] + m[3 * i + 1] * m[3 * j + 1] + m[3 * i + 2] * m[3 * j + 2];
        if (std::abs(dot - (i == j ? 1.0 : 0.0)) > 1e-9)
          return Status::InvalidArgument("collide: the rotation is not orthonormal");
      }
    }
    const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
                       m[2] * (m[3] * m[7] - m[4] * m[6]);
    if (det < 0) return Status::InvalidArgument("collide: the rotation is a reflection");
  }
  return Status::Ok();
}

Status RunCollide(const LeafSource& st, const Mesh& mesh, const std::optional<RigidTransform>& transform,
                  const ClashOptions& o, const ClashVisitor& visit, ClashStats* stats) {
  ClashStats local;
  ClashStats& s = stats ? *stats : local;
  s = ClashStats();
  MKTREE_RETURN_IF_ERROR(clash::CheckOptions(o));
  MKTREE_RETURN_IF_ERROR(CheckCollideMesh(mesh, transform));
  const Clock::time_point start = Clock::now();
  const StoreReader& reader = st.reader();
  const MKTree& tree = reader.tree();
  s.store_pages = StorePages(tree);

  // The object in the store's frame.
  Mesh q;
  q.triangles = mesh.triangles;
  q.vertices.resize(mesh.vertices.size());
  for (size_t v = 0; v < mesh.vertex_count(); ++v) {
    Vec3d p{mesh.vertices[3 * v], mesh.vertices[3 * v + 1], mesh.vertices[3 * v + 2]};
    if (transform) p = transform->Apply(p);
    for (int i = 0; i < 3; ++i) q.vertices[3 * v + i] = p[i] - tree.origin[i];
  }
  for (double v : q.vertices)
    if (!std::isfinite(v))
      return Status::InvalidArgument("collide: the moved object has a non-finite vertex");
  const ClashShape shape(q);
  const Box3d qbox = q.Bounds();
  const Box3d grown = clash::Grow(qbox, o.clearance);

  // Broad phase: the leaves the grown box reaches, then those the leaf filter admits.
  std::vector<uint32_t> leaves;
  QueryStats route;
  if (!tree.empty()) tree.RouteBox(grown, &leaves, &route);
  s.leaf_pairs_tree = leaves.size();
  const bool filter = !tree.leaf_filter.empty() && tree.leaf_filter_begin.size() == tree.leaves.size() + 1;
  std::erase_if(leaves, [&](uint32_t leaf) {
    if (!filter) return false;
    const LeafInfo& info = tree.leaves[leaf];
    return !FilterMeetsBox(info.box, tree.leaf_filter.data() + tree.leaf_filter_begin[leaf],
                           info.object_count, grown);
  });
  s.leaf_pairs_visited = leaves.size();
  s.leaf_reads = leaves.size();
  s.broad_seconds = Since(start);

  clash::WorkPool pool(ThreadCount(o.threads));
  IoCount io;
  std::vector<uint64_t> seen;
  Emitter emit{o, visit, s};
  // Candidates are found as their leaves are read (on this thread, in leaf order); their leaves stay
  // pinned until their chunk of candidates is decoded, prepared and tested on all threads. While one
  // chunk is tested this thread reads the next one's leaves (each leaf is still read once, in leaf
  // order: the same pages and counts).
  struct Candidate {
    size_t pin;  // index into the chunk's pins
    uint32_t pos;
  };
  struct Chunk {
    std::vector<PinnedLeaf> pins = std::vector<PinnedLeaf>(kCollidePinnedLeaves);
    size_t pinned = 0;
    std::vector<Candidate> candidates;
  };
  Chunk chunks[2];
  size_t next_leaf = 0;
  uint64_t candidates = 0, excluded = 0;
  std::vector<uint64_t> reported((reader.object_count() + 63) / 64);  // one bit an object: ids reported
  // Reads leaves into `c` until it holds kCollideChunk candidates or kCollidePinnedLeaves leaves with
  // candidates, or no leaf is left.
  auto fill = [&](Chunk& c) -> Status {
    const Clock::time_point t = Clock::now();
    while (next_leaf < leaves.size() && c.candidates.size() < kCollideChunk && c.pinned < c.pins.size()) {
      PinnedLeaf& pin = c.pins[c.pinned];
      MKTREE_RETURN_IF_ERROR(ReadPinned(st, leaves[next_leaf++], &io, &seen, &pin));
      const size_t before = c.candidates.size();
      const auto& entries = pin.view.entries();
      for (uint32_t pos = 0; pos < entries.size(); ++pos) {
        const ObjectEntryView& e = entries[pos];
        if (!clash::GrownMeet(clash::ToBox3d(e.box), qbox, o.clearance)) continue;
        ++candidates;
        if (o.exclude && o.exclude(e.id, kCollideObject)) {
          ++excluded;
          continue;
        }
        c.candidates.push_back({c.pinned, pos});
      }
      if (c.candidates.size() > before) {
        ++c.pinned;
      } else {
        pin.Release();
      }
    }
    s.read_seconds += Since(t);
    return Status::Ok();
  };
  // A chunk's pairs go to the visitor while the next chunk is tested (this thread, before it joins the
  // loop), in chunk order: the same calls in the same order. Two sets of results, one a chunk.
  std::vector<PairWork> work[2];
  size_t pending = 0;  // candidates of the chunk before `cur` whose pairs the visitor has not had
  auto emit_pending = [&](const std::vector<PairWork>& w) {
    for (size_t k = 0; k < pending; ++k) emit.Add(w[k]);
    pending = 0;
  };
  std::vector<Status> errors;
  MKTREE_RETURN_IF_ERROR(fill(chunks[0]));
  size_t cur = 0;
  for (; !chunks[cur].candidates.empty(); cur ^= 1) {
    Chunk& c = chunks[cur];
    std::vector<PairWork>& w = work[cur];
    const Clock::time_point t = Clock::now();
    w.resize(std::max(w.size(), c.candidates.size()));
    errors.assign(c.candidates.size(), Status::Ok());
    Status read_status;
    pool.For(
        c.candidates.size(),
        [&](size_t k) {
          w[k].Clear();
          const ObjectEntryView& e = c.pins[c.candidates[k].pin].view.entry(c.candidates[k].pos);
          Mesh mesh;
          errors[k] = st.DecodeMesh(e, &mesh);
          if (!errors[k].ok()) return;
          const ClashShape other(mesh, StoredEdges(e));
          const double r = CoordinateResolution(e.box);
          const Separation sep = Separate(other, shape, clash::NarrowMaxDistance(o, r), &w[k].narrow,
                                          clash::NarrowOptions(o, r));
          ClashPair pair;
          if (clash::Classify(sep, o, r, e.id, kCollideObject, tree.origin, &pair))
            w[k].found.push_back(pair);
        },
        [&] {
          emit_pending(work[cur ^ 1]);
          read_status = fill(chunks[cur ^ 1]);
        });
    for (size_t i = 0; i < c.pinned; ++i) c.pins[i].Release();
    c.pinned = 0;
    s.narrow_seconds += Since(t);
    MKTREE_RETURN_IF_ERROR(FirstError(errors));
    // An id reported twice is in two leaves, which only id digests made to collide let through.
    for (size_t k = 0; k < c.candidates.size(); ++k)
      for (const ClashPair& p : w[k].found) {
        const uint64_t bit = uint64_t{1} << (p.a & 63);
        if (reported[p.a >> 6] & bit)
          return Status::Corruption(reader.path() + ": object " + std::to_string(p.a) +
                                    " is in two leaves (their id digests were made to collide)");
        reported[p.a >> 6] |= bit;
      }
    pending = c.candidates.size();
    c.candidates.clear();
    if (!read_status.ok()) {
      emit_pending(w);
      return read_status;
    }
  }
  emit_pending(work[cur ^ 1]);  // the last chunk's (chunks[cur] came out empty)
  s.candidate_pairs = candidates;
  s.excluded_pairs = excluded;
  io.Fill(&s);
  s.total_seconds = Since(start);
  return Status::Ok();
}

// Adds the counts of `b` to `a` (the window's bytes: the larger).
void AddClashStats(ClashStats* a, const ClashStats& b) {
  for (auto [x, y] : {std::pair{&a->pages_read, b.pages_read},
                      {&a->pages_touched, b.pages_touched},
                      {&a->distinct_pages, b.distinct_pages},
                      {&a->store_pages, b.store_pages},
                      {&a->leaf_reads, b.leaf_reads},
                      {&a->leaf_rereads, b.leaf_rereads},
                      {&a->leaf_pairs_tree, b.leaf_pairs_tree},
                      {&a->leaf_pairs_visited, b.leaf_pairs_visited},
                      {&a->candidate_pairs, b.candidate_pairs},
                      {&a->excluded_pairs, b.excluded_pairs},
                      {&a->bound_rejects, b.bound_rejects},
                      {&a->triangle_tests, b.triangle_tests},
                      {&a->containment_tests, b.containment_tests},
                      {&a->shapes_prepared, b.shapes_prepared},
                      {&a->hierarchies_built, b.hierarchies_built},
                      {&a->classifiers_built, b.classifiers_built},
                      {&a->hard, b.hard},
                      {&a->touch, b.touch},
                      {&a->clearance, b.clearance},
                      {&a->reported_pairs, b.reported_pairs},
                      {&a->capped_pairs, b.capped_pairs},
                      {&a->unreported_touches, b.unreported_touches}})
    *x += y;
  a->window_peak_bytes = std::max(a->window_peak_bytes, b.window_peak_bytes);
  a->window_budget_bytes = std::max(a->window_budget_bytes, b.window_budget_bytes);
  a->broad_seconds += b.broad_seconds;
  a->read_seconds += b.read_seconds;
  a->narrow_seconds += b.narrow_seconds;
}

}  // namespace mktree
