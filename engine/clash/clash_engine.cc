#include "engine/clash/clash_engine.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <span>
#include <thread>
#include <utility>
#include <vector>

#include "engine/clash/broad_phase.h"
#include "engine/clash/clash_reads.h"
#include "engine/clash/clash_window.h"
#include "engine/clash/collide_chunks.h"
#include "engine/clash/narrow_batches.h"
#include "engine/clash/pair_emitter.h"
#include "engine/clash/pair_rules.h"
#include "engine/clash/part_exclusions.h"
#include "engine/clash/part_numbering.h"
#include "engine/clash/stage_clock.h"
#include "engine/clash/work_pool.h"

namespace mktree {

namespace {

using clash::SecondsSince;
using clash::StageClock;

unsigned ThreadCount(unsigned t) { return t ? t : std::max(1u, std::thread::hardware_concurrency()); }

// The collide object moved by `transform` into the store's frame (origin at `origin`).
Status MoveIntoStoreFrame(const Mesh& mesh, const std::optional<RigidTransform>& transform,
                          const Vec3d& origin, Mesh* q) {
  q->triangles = mesh.triangles;
  q->vertices.resize(mesh.vertices.size());
  for (size_t v = 0; v < mesh.vertex_count(); ++v) {
    Vec3d p{mesh.vertices[3 * v], mesh.vertices[3 * v + 1], mesh.vertices[3 * v + 2]};
    if (transform) p = transform->Apply(p);
    for (int i = 0; i < 3; ++i) q->vertices[3 * v + i] = p[i] - origin[i];
  }
  for (double v : q->vertices)
    if (!std::isfinite(v))
      return Status::InvalidArgument("collide: the moved object has a non-finite vertex");
  return Status::Ok();
}

}  // namespace

Status RunSelfClash(const LeafSource& st, const ClashOptions& o, const ClashVisitor& visit,
                    ClashStats* stats) {
  return RunMultiClash({ClashPart{&st, nullptr}}, MultiClashScope{}, o, visit, stats);
}

Status RunMultiClash(const std::vector<ClashPart>& parts, const ClashPartPairs& want, const ClashOptions& o,
                     const ClashVisitor& visit, ClashStats* stats) {
  return RunMultiClash(parts, MultiClashScope{want, nullptr}, o, visit, stats);
}

Status RunMultiClash(const std::vector<ClashPart>& parts, const MultiClashScope& scope, const ClashOptions& o,
                     const ClashVisitor& visit, ClashStats* stats) {
  ClashStats local;
  ClashStats& s = stats ? *stats : local;
  s = ClashStats();
  MKTREE_RETURN_IF_ERROR(clash::CheckOptions(o));
  const StageClock::time_point start = StageClock::now();
  if (parts.empty()) return Status::Ok();
  MKTREE_ASSIGN_OR_RETURN(const clash::PartNumbering numbering, clash::PartNumbering::Make(parts));
  s.store_pages = numbering.store_pages();
  std::optional<clash::ClashFocus> focus;
  if (scope.partner && !scope.focus) return Status::InvalidArgument("clash: a partner set without a focus");
  if (scope.focus) {
    MKTREE_ASSIGN_OR_RETURN(focus, clash::ClashFocus::Make(numbering, *scope.focus, scope.partner));
  }
  clash::WorkPool pool(ThreadCount(o.threads));
  std::optional<clash::Exclusions> ex;
  MKTREE_RETURN_IF_ERROR(clash::MakePartExclusions(numbering, o, &ex));

  // Broad phase: the leaf pairs, then the plan of the sweep through the window.
  const clash::ClashFocus* f = focus ? &*focus : nullptr;
  clash::ClashLeafPairs broad = clash::FindLeafPairs(numbering, scope.want, f, o.clearance, pool, &s);
  s.window_budget_bytes = clash::WindowBudget(o, numbering);
  const clash::SweepPlan plan =
      clash::PlanClashSweep(numbering, std::move(broad.pairs), s.window_budget_bytes);
  s.leaf_reads = plan.leaf_reads;
  s.leaf_rereads = plan.leaf_rereads;
  s.broad_seconds = SecondsSince(start);

  // Per batch: the window reads, then the narrow batches on the leaves the window holds.
  clash::ClashWindow window(numbering, broad.needed, f);
  clash::NarrowBatches narrow(numbering, o, *ex, numbering.tree(0).origin, clash::PairEmitter{o, visit, s});
  for (size_t bi = 0; bi < plan.batches.size(); ++bi) {
    const clash::SweepBatch& b = plan.batches[bi];
    window.Drop(b.evict);
    StageClock::time_point t = StageClock::now();
    MKTREE_RETURN_IF_ERROR(window.Read(b.load, pool, &s));
    s.read_seconds += SecondsSince(t);
    t = StageClock::now();
    const std::span<const clash::LeafPair> batch_pairs(plan.pairs.data() + b.pair_begin,
                                                       b.pair_end - b.pair_begin);
    MKTREE_RETURN_IF_ERROR(narrow.Test(batch_pairs, window, pool));
    window.Recount(batch_pairs, &s);  // the shapes' parts built by these pairs
    s.narrow_seconds += SecondsSince(t);
    window.Drop(b.drop);
    if (o.progress) o.progress(bi + 1, plan.batches.size());
  }
  narrow.Finish();
  window.io().Fill(&s);
  s.total_seconds = SecondsSince(start);
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
  return RunCollide(ClashPart{&st, nullptr, nullptr}, mesh, transform, o, visit, stats);
}

Status RunCollide(const ClashPart& part, const Mesh& mesh, const std::optional<RigidTransform>& transform,
                  const ClashOptions& o, const ClashVisitor& visit, ClashStats* stats) {
  ClashStats local;
  ClashStats& s = stats ? *stats : local;
  s = ClashStats();
  MKTREE_RETURN_IF_ERROR(clash::CheckOptions(o));
  MKTREE_RETURN_IF_ERROR(CheckCollideMesh(mesh, transform));
  const std::vector<ClashPart> parts{part};
  MKTREE_ASSIGN_OR_RETURN(const clash::PartNumbering numbering, clash::PartNumbering::Make(parts));
  const LeafSource& st = *part.leaves;
  const StageClock::time_point start = StageClock::now();
  const MKTree& tree = st.reader().tree();
  s.store_pages = clash::StorePages(tree);
  Mesh q;
  MKTREE_RETURN_IF_ERROR(MoveIntoStoreFrame(mesh, transform, tree.origin, &q));
  const ClashShape shape(q);
  const Box3d qbox = q.Bounds();

  // Broad phase: the leaves the grown box reaches, then those the leaf filter admits.
  const std::vector<uint32_t> leaves = clash::CollideLeaves(tree, clash::Grow(qbox, o.clearance), &s);
  s.broad_seconds = SecondsSince(start);

  // The reads and the narrow phase, a chunk of candidates at a time.
  clash::WorkPool pool(ThreadCount(o.threads));
  clash::CollideChunks chunks(numbering, leaves, shape, qbox, o, &s);
  MKTREE_RETURN_IF_ERROR(chunks.Run(pool, clash::PairEmitter{o, visit, s}));
  s.total_seconds = SecondsSince(start);
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
