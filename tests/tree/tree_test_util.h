// Scenes of records for the tree tests, and a full structural check of a built tree against its input.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "engine/tree/mktree_builder.h"
#include "engine/tree/page_budget.h"

namespace mktree::testing {

enum class SceneKind {
  kUniform,    // boxes of mixed sizes spread uniformly
  kClustered,  // a few dense clusters
  kIdentical,  // every box the same
  kPlates,     // zero-thickness boxes (min == max on one axis), on a coarse grid
  kHuge,       // one box covering everything among small ones
  kOversized,  // some objects bigger than a page
  kShip,       // long thin axis-aligned pipes, plates and chunky equipment, coordinates on a 0.5 grid
  kGrid,       // unit cubes on an integer lattice: many exactly touching faces
};

inline const char* Name(SceneKind k) {
  switch (k) {
    case SceneKind::kUniform:
      return "uniform";
    case SceneKind::kClustered:
      return "clustered";
    case SceneKind::kIdentical:
      return "identical";
    case SceneKind::kPlates:
      return "plates";
    case SceneKind::kHuge:
      return "huge";
    case SceneKind::kOversized:
      return "oversized";
    case SceneKind::kShip:
      return "ship";
    case SceneKind::kGrid:
      return "grid";
  }
  return "?";
}

// Every split policy: structural and routing checks hold for all of them.
inline constexpr SplitPolicy kAllPolicies[] = {SplitPolicy::kSoa, SplitPolicy::kCompact};

inline const char* Name(SplitPolicy p) { return p == SplitPolicy::kSoa ? "soa" : "compact"; }

inline BuildTuning WithPolicy(SplitPolicy p) {
  BuildTuning t;
  t.split_policy = p;
  return t;
}

inline std::vector<BuildObject> MakeScene(SceneKind kind, size_t n, uint64_t seed,
                                          uint64_t mem_page = 12288) {
  std::mt19937_64 rng(seed);
  auto uni = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  auto pick = [&](int n_) { return static_cast<int>(rng() % static_cast<uint64_t>(n_)); };
  std::vector<BuildObject> out(n);
  std::vector<std::array<double, 3>> centers;
  for (int c = 0; c < 5; ++c) centers.push_back({uni(0, 100), uni(0, 100), uni(0, 100)});
  for (size_t i = 0; i < n; ++i) {
    BuildObject& r = out[i];
    r.id = static_cast<ObjectId>(i);
    r.encoded_bytes = static_cast<uint32_t>(400 + rng() % 2601);
    std::array<double, 3> lo{}, hi{};
    switch (kind) {
      case SceneKind::kUniform:
      case SceneKind::kOversized:
      case SceneKind::kHuge:
        for (int a = 0; a < 3; ++a) {
          const double size = std::exp(uni(std::log(0.05), std::log(5.0)));
          lo[a] = uni(0, 100);
          hi[a] = lo[a] + size;
        }
        break;
      case SceneKind::kClustered: {
        const auto& c = centers[pick(5)];
        std::normal_distribution<double> g(0, 3);
        for (int a = 0; a < 3; ++a) {
          lo[a] = c[a] + g(rng);
          hi[a] = lo[a] + uni(0.01, 1.5);
        }
        break;
      }
      case SceneKind::kIdentical:
        lo = {1, 2, 3};
        hi = {4, 6, 8};
        break;
      case SceneKind::kPlates: {
        const int flat = pick(3);
        for (int a = 0; a < 3; ++a) {
          lo[a] = pick(40) * 2.5;
          hi[a] = a == flat ? lo[a] : lo[a] + 2.5 * (1 + pick(3));
        }
        break;
      }
      case SceneKind::kShip: {
        const int cls = pick(10);
        const int along = pick(3);
        for (int a = 0; a < 3; ++a) lo[a] = pick(200) * 0.5;
        if (cls < 6) {  // pipe
          for (int a = 0; a < 3; ++a) hi[a] = lo[a] + (a == along ? 0.5 * (1 + pick(60)) : 0.5);
        } else if (cls < 9) {  // plate
          for (int a = 0; a < 3; ++a) hi[a] = lo[a] + (a == along ? 0.0 : 0.5 * (1 + pick(12)));
        } else {  // equipment
          for (int a = 0; a < 3; ++a) hi[a] = lo[a] + 0.5 * (1 + pick(6));
        }
        break;
      }
      case SceneKind::kGrid:
        for (int a = 0; a < 3; ++a) {
          lo[a] = pick(30);
          hi[a] = lo[a] + 1;
        }
        break;
    }
    for (int a = 0; a < 3; ++a) {
      r.box.min[a] = static_cast<float>(lo[a]);
      r.box.max[a] = static_cast<float>(hi[a]);
    }
  }
  if (kind == SceneKind::kHuge && n > 0) {
    out[n / 2].box.min = {-1, -1, -1};
    out[n / 2].box.max = {110, 110, 110};
  }
  if (kind == SceneKind::kOversized) {
    for (size_t i = 0; i < n; i += 37)
      out[i].encoded_bytes = static_cast<uint32_t>(mem_page * (1 + rng() % 3));
  }
  return out;
}

// Objects of each node's subtree: the range of leaf_objects between its first and last leaf.
struct NodeRanges {
  std::vector<uint64_t> begin, end;   // positions in leaf_objects
  std::vector<uint32_t> subtree_end;  // one past the last node of the subtree
};

inline NodeRanges ComputeRanges(const BuildResult& r) {
  const auto& nodes = r.tree.nodes;
  NodeRanges nr;
  nr.begin.assign(nodes.size(), 0);
  nr.end.assign(nodes.size(), 0);
  nr.subtree_end.assign(nodes.size(), 0);
  for (size_t i = nodes.size(); i-- > 0;) {
    const TreeNode& n = nodes[i];
    if (n.is_leaf()) {
      nr.begin[i] = r.leaf_offsets[n.leaf];
      nr.end[i] = r.leaf_offsets[n.leaf + 1];
      nr.subtree_end[i] = static_cast<uint32_t>(i + 1);
    } else {
      nr.begin[i] = nr.begin[n.child[0]];
      nr.end[i] = nr.end[n.child[1]];
      nr.subtree_end[i] = nr.subtree_end[n.child[1]];
    }
  }
  return nr;
}

// Descends the SplitTree of node `n` to the cells a closed box meets, calling f(cell, cell region).
template <typename F>
void ForEachCell(const MKTree& t, const TreeNode& n, F&& f) {
  Box3f q = n.box;
  q.min[n.axis] = n.a;
  q.max[n.axis] = n.b;
  std::vector<std::pair<uint32_t, Box3f>> stack{{n.split_root, q}};
  while (!stack.empty()) {
    auto [i, region] = stack.back();
    stack.pop_back();
    const SplitNode& s = t.split_nodes[i];
    if (s.is_cell()) {
      f(s, region);
      continue;
    }
    Box3f lo = region, hi = region;
    lo.max[s.axis] = std::min(lo.max[s.axis], s.cut);
    hi.min[s.axis] = std::max(hi.min[s.axis], s.cut);
    stack.push_back({s.child[0], lo});
    stack.push_back({s.child[1], hi});
  }
}

inline bool LabelAllows(CellLabel l, int side) {
  return (static_cast<uint8_t>(l) & (side == 0 ? 1 : 2)) != 0;
}

// Every structural property of docs/design.md §2-4 and the flat layout. Returns the number of checks failed
// (also reported through gtest).
inline void CheckTree(const std::vector<BuildObject>& recs, const BuildResult& r, const BuildParams& p) {
  const MKTree& t = r.tree;
  ASSERT_EQ(r.leaf_offsets.size(), t.leaves.size() + 1);
  ASSERT_EQ(r.leaf_objects.size(), recs.size());
  EXPECT_EQ(r.leaf_offsets.front(), 0u);
  EXPECT_EQ(r.leaf_offsets.back(), recs.size());
  std::unordered_map<ObjectId, size_t> by_id;
  for (size_t i = 0; i < recs.size(); ++i) by_id[recs[i].id] = i;
  // Every object in exactly one leaf.
  std::vector<int> seen(recs.size(), 0);
  for (ObjectId id : r.leaf_objects) {
    auto it = by_id.find(id);
    ASSERT_NE(it, by_id.end()) << "unknown id " << id;
    ++seen[it->second];
  }
  for (size_t i = 0; i < recs.size(); ++i) ASSERT_EQ(seen[i], 1) << "object " << recs[i].id;
  if (recs.empty()) {
    EXPECT_TRUE(t.empty());
    return;
  }
  const NodeRanges nr = ComputeRanges(r);
  EXPECT_EQ(nr.subtree_end[0], t.nodes.size());
  auto box_of = [&](uint64_t pos) -> const Box3f& { return recs[by_id.at(r.leaf_objects[pos])].box; };
  uint32_t next_leaf = 0;
  uint64_t next_page = 0;
  for (uint32_t i = 0; i < t.nodes.size(); ++i) {
    const TreeNode& n = t.nodes[i];
    Box3f u;
    uint64_t bytes = 0;
    for (uint64_t k = nr.begin[i]; k < nr.end[i]; ++k) {
      u.Extend(box_of(k));
      bytes += recs[by_id.at(r.leaf_objects[k])].encoded_bytes;
    }
    ASSERT_EQ(n.box, u) << "node " << i << ": R(Sn) is not the union of its objects' boxes";
    if (n.is_leaf()) {
      // Leaves in DFS order, pages consecutive, budget respected.
      ASSERT_EQ(n.leaf, next_leaf++) << "node " << i;
      const LeafInfo& lf = t.leaves[n.leaf];
      EXPECT_EQ(lf.node, i);
      EXPECT_EQ(lf.box, n.box);
      EXPECT_EQ(lf.object_count, nr.end[i] - nr.begin[i]);
      EXPECT_EQ(lf.payload_bytes, LeafPayloadBytes(bytes));
      EXPECT_EQ(lf.page_count, PagesForLeaf(bytes, p.mem_page()));
      EXPECT_EQ(lf.first_page, next_page);
      next_page += lf.page_count;
      if (lf.object_count > 1) {
        EXPECT_TRUE(FitsInOnePage(bytes, p.mem_page())) << "leaf " << n.leaf;
      }
      continue;
    }
    ASSERT_LT(n.axis, 3);
    ASSERT_EQ(n.child[0], i + 1) << "not DFS preorder";
    ASSERT_EQ(n.child[1], nr.subtree_end[i + 1]) << "not DFS preorder";
    // A node only splits when its objects do not fit in one page.
    EXPECT_FALSE(nr.end[i] - nr.begin[i] > 1 && FitsInOnePage(bytes, p.mem_page())) << "node " << i;
    const int w = n.axis;
    float a = std::numeric_limits<float>::infinity(), b = -std::numeric_limits<float>::infinity();
    for (uint64_t k = nr.begin[n.child[1]]; k < nr.end[n.child[1]]; ++k) a = std::min(a, box_of(k).min[w]);
    for (uint64_t k = nr.begin[n.child[0]]; k < nr.end[n.child[0]]; ++k) b = std::max(b, box_of(k).max[w]);
    ASSERT_EQ(n.a, a) << "node " << i << ": a is not min over Sn2 of min_w";
    ASSERT_EQ(n.b, b) << "node " << i << ": b is not max over Sn1 of max_w";
    for (uint64_t k = nr.begin[i]; k < nr.end[i]; ++k) {
      const Box3f& bx = box_of(k);
      const int side = k < nr.begin[n.child[1]] ? 0 : 1;
      if (bx.min[w] < n.a) {
        ASSERT_EQ(side, 0) << "WW/W object not in Sn1 at node " << i;
      }
      if (bx.max[w] > n.b) {
        ASSERT_EQ(side, 1) << "BB/B object not in Sn2 at node " << i;
      }
    }
    if (n.split_root == kNoIndex || n.a >= n.b) continue;
    // SplitTree invariant: every object whose box meets a cell (within Q) is allowed by the cell's label.
    uint32_t split_nodes = 0;
    std::vector<std::pair<CellLabel, Box3f>> cells;
    ForEachCell(t, n, [&](const SplitNode& s, const Box3f& region) { cells.push_back({s.label, region}); });
    {
      std::vector<uint32_t> st{n.split_root};
      while (!st.empty()) {
        const SplitNode& s = t.split_nodes[st.back()];
        st.pop_back();
        ++split_nodes;
        if (!s.is_cell()) {
          st.push_back(s.child[0]);
          st.push_back(s.child[1]);
        }
      }
    }
    EXPECT_LE(split_nodes, p.split_tree_node_budget);
    for (uint64_t k = nr.begin[i]; k < nr.end[i]; ++k) {
      const Box3f& bx = box_of(k);
      if (bx.max[w] < n.a || bx.min[w] > n.b) continue;
      const int side = k < nr.begin[n.child[1]] ? 0 : 1;
      for (const auto& [label, region] : cells) {
        if (region.Intersects(bx)) {
          ASSERT_TRUE(LabelAllows(label, side))
              << "SplitTree invariant broken at node " << i << ", object " << r.leaf_objects[k];
        }
      }
    }
  }
  EXPECT_EQ(next_leaf, t.leaves.size());
}

}  // namespace mktree::testing
