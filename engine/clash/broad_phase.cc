#include "engine/clash/broad_phase.h"

#include <algorithm>
#include <utility>

#include "engine/clash/clash_window.h"
#include "engine/clash/pair_rules.h"
#include "engine/tree/leaf_filter.h"

namespace mktree::clash {

namespace {

// Leaf pairs in one batch of the sweep.
constexpr size_t kBatchPairs = 1024;

// The box of the parts' roots (their union).
Box3f PartsRoot(const PartNumbering& parts) {
  Box3f root;
  bool any = false;
  for (size_t k = 0; k < parts.part_count(); ++k) {
    const MKTree& t = parts.tree(k);
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
  return root;
}

}  // namespace

ClashLeafPairs FindLeafPairs(const PartNumbering& parts, const ClashPartPairs& want, const ClashFocus* focus,
                             double c, WorkPool& pool, ClashStats* s) {
  const uint32_t np = static_cast<uint32_t>(parts.part_count());
  auto wanted = [&](uint32_t i, uint32_t j) { return !want || want(i, j); };
  auto marks = [&](uint32_t k) { return focus ? &focus->marks(k) : nullptr; };
  auto partner = [&](uint32_t k) { return focus ? focus->partner_marks(k) : nullptr; };
  ClashLeafPairs out;
  out.needed.resize(np);
  std::vector<uint8_t> filtered(np, 0);
  for (uint32_t k = 0; k < np; ++k) {
    const MKTree& t = parts.tree(k);
    filtered[k] = InitNeeded(t, &out.needed[k]);
    if (!wanted(k, k)) continue;
    std::vector<LeafPair> own = TreeLeafPairs(t, c, marks(k), partner(k));
    s->leaf_pairs_tree += own.size();
    FilterLeafPairs(t, c, pool, &own, &out.needed[k], marks(k), partner(k));
    const uint32_t base = parts.leaf_base(k);
    for (const LeafPair& lp : own) out.pairs.push_back({lp.p + base, lp.q + base});
  }
  for (uint32_t i = 0; i < np; ++i) {
    const MKTree& ti = parts.tree(i);
    for (uint32_t j = i + 1; j < np; ++j) {
      const MKTree& tj = parts.tree(j);
      if (!wanted(i, j) || ti.empty() || tj.empty() ||
          !GrownMeet(ToBox3d(ti.nodes[0].box), ToBox3d(tj.nodes[0].box), c))
        continue;
      std::vector<LeafPair> cross = CrossLeafPairs(ti, tj, c, marks(i), marks(j), partner(i), partner(j));
      s->leaf_pairs_tree += cross.size();
      if (filtered[i] && filtered[j]) {
        FilterCrossLeafPairs(ti, tj, c, pool, &cross, &out.needed[i], &out.needed[j], marks(i), marks(j),
                             partner(i), partner(j));
      } else if (!cross.empty()) {
        out.needed[i].all = out.needed[j].all = true;
      }
      for (const LeafPair& lp : cross)
        out.pairs.push_back({lp.p + parts.leaf_base(i), lp.q + parts.leaf_base(j)});
    }
  }
  s->leaf_pairs_visited = out.pairs.size();
  return out;
}

SweepPlan PlanClashSweep(const PartNumbering& parts, std::vector<LeafPair> pairs, uint64_t window_bytes) {
  const uint32_t total_leaves = parts.leaf_count();
  std::vector<uint64_t> leaf_bytes(total_leaves);
  for (uint32_t g = 0; g < total_leaves; ++g) leaf_bytes[g] = DecodedLeafEstimate(parts.leaf_info(g));
  if (parts.part_count() == 1)
    return PlanSweep(parts.tree(0), std::move(pairs), leaf_bytes, window_bytes, kBatchPairs);
  std::vector<Box3f> boxes(total_leaves);
  for (uint32_t g = 0; g < total_leaves; ++g) boxes[g] = parts.leaf_info(g).box;
  return PlanSweep(PartsRoot(parts), boxes, std::move(pairs), leaf_bytes, window_bytes, kBatchPairs);
}

std::vector<uint32_t> CollideLeaves(const MKTree& tree, const Box3d& grown, ClashStats* s) {
  std::vector<uint32_t> leaves;
  QueryStats route;
  if (!tree.empty()) tree.RouteBox(grown, &leaves, &route);
  s->leaf_pairs_tree = leaves.size();
  const bool filter = !tree.leaf_filter.empty() && tree.leaf_filter_begin.size() == tree.leaves.size() + 1;
  std::erase_if(leaves, [&](uint32_t leaf) {
    if (!filter) return false;
    const LeafInfo& info = tree.leaves[leaf];
    return !FilterMeetsBox(info.box, tree.leaf_filter.data() + tree.leaf_filter_begin[leaf],
                           info.object_count, grown);
  });
  s->leaf_pairs_visited = leaves.size();
  s->leaf_reads = leaves.size();
  return leaves;
}

}  // namespace mktree::clash
