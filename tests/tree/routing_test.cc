// Routing never misses an object: for random (and adversarial: on planes a and b, on cuts, on box faces)
// queries, every object whose box meets the query must lie in a leaf the routing returns.
#include <gtest/gtest.h>

#include <random>
#include <tuple>
#include <unordered_map>

#include "engine/tree/leaf_filter.h"
#include "engine/tree/mktree_builder.h"
#include "tree/tree_test_util.h"

namespace mktree {
namespace {

using testing::MakeScene;
using testing::SceneKind;

struct Fixture {
  std::vector<BuildObject> recs;
  BuildResult built;
  std::vector<uint32_t> leaf_of;  // per record
};

Fixture Build(std::vector<BuildObject> recs, const BuildParams& p, const BuildTuning& tune = BuildTuning()) {
  Fixture f;
  f.recs = std::move(recs);
  auto r = BuildMKTree(f.recs, p, tune);
  EXPECT_TRUE(r.ok()) << r.status().ToString();
  f.built = std::move(r).value();
  std::unordered_map<ObjectId, size_t> idx;
  for (size_t i = 0; i < f.recs.size(); ++i) idx[f.recs[i].id] = i;
  f.leaf_of.assign(f.recs.size(), kNoIndex);
  for (uint32_t l = 0; l < f.built.tree.leaves.size(); ++l)
    for (uint64_t k = f.built.leaf_offsets[l]; k < f.built.leaf_offsets[l + 1]; ++k)
      f.leaf_of[idx[f.built.leaf_objects[k]]] = l;
  return f;
}

// Points that stress the closed boundaries: box corners and faces, and points on the planes a and b and
// on SplitTree cuts, the other coordinates taken from an object near the node.
std::vector<Vec3d> QueryPoints(const Fixture& f, size_t count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Vec3d> pts;
  if (f.recs.empty()) return pts;
  const Box3f& root = f.built.tree.nodes[0].box;
  auto uni = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  auto in_box = [&](const Box3f& b) {
    Vec3d p;
    for (int a = 0; a < 3; ++a) {
      const int mode = static_cast<int>(rng() % 4);
      p[a] = mode == 0 ? b.min[a] : mode == 1 ? b.max[a] : uni(b.min[a], b.max[a]);
    }
    return p;
  };
  for (size_t i = 0; i < count; ++i) {
    const int mode = static_cast<int>(rng() % 4);
    if (mode == 0) {  // anywhere, slightly beyond the scene too
      Vec3d p;
      for (int a = 0; a < 3; ++a) {
        const double e = double{root.max[a]} - double{root.min[a]};
        p[a] = uni(root.min[a] - 0.05 * e, root.max[a] + 0.05 * e);
      }
      pts.push_back(p);
    } else if (mode == 1) {  // on an object's corner / face / inside
      pts.push_back(in_box(f.recs[rng() % f.recs.size()].box));
    } else {  // on plane a or b (or a SplitTree cut) of a random internal node
      const auto& nodes = f.built.tree.nodes;
      const TreeNode& n = nodes[rng() % nodes.size()];
      Vec3d p = in_box(n.box);
      if (!n.is_leaf()) {
        p[n.axis] = (rng() % 2) ? n.a : n.b;
        if (mode == 3 && n.split_root != kNoIndex) {
          const SplitNode& s = f.built.tree.split_nodes[n.split_root];
          if (!s.is_cell()) p[s.axis] = s.cut;
        }
      }
      pts.push_back(p);
    }
  }
  return pts;
}

void CheckPoints(const Fixture& f, const std::vector<Vec3d>& pts) {
  std::vector<uint32_t> leaves;
  std::vector<uint8_t> reached(f.built.tree.leaves.size());
  for (const Vec3d& p : pts) {
    leaves.clear();
    QueryStats st;
    f.built.tree.RoutePoint(p, &leaves, &st);
    EXPECT_EQ(st.leaves_visited, leaves.size());
    for (size_t i = 1; i < leaves.size(); ++i)
      ASSERT_LT(leaves[i - 1], leaves[i]) << "leaf order / duplicates";
    std::fill(reached.begin(), reached.end(), 0);
    for (uint32_t l : leaves) reached[l] = 1;
    for (size_t i = 0; i < f.recs.size(); ++i) {
      if (f.recs[i].box.Contains(p)) {
        ASSERT_TRUE(reached[f.leaf_of[i]])
            << "point (" << p.x << "," << p.y << "," << p.z << ") misses object " << f.recs[i].id;
      }
    }
  }
}

void CheckBoxes(const Fixture& f, size_t count, uint64_t seed) {
  if (f.recs.empty()) return;
  std::mt19937_64 rng(seed);
  auto uni = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  const Box3f& root = f.built.tree.nodes[0].box;
  std::vector<uint32_t> leaves;
  std::vector<uint8_t> reached(f.built.tree.leaves.size());
  for (size_t i = 0; i < count; ++i) {
    Box3d q;
    const int mode = static_cast<int>(rng() % 3);
    if (mode == 0) {  // an object's own box, or one of its faces (zero thickness)
      const Box3f& b = f.recs[rng() % f.recs.size()].box;
      for (int a = 0; a < 3; ++a) {
        q.min[a] = b.min[a];
        q.max[a] = b.max[a];
      }
      const int face = static_cast<int>(rng() % 7);
      if (face < 6) {
        if (face % 2)
          q.min[face / 2] = q.max[face / 2];
        else
          q.max[face / 2] = q.min[face / 2];
      }
    } else {  // random boxes of varied size; mode 2: thin slabs through a node's plane
      for (int a = 0; a < 3; ++a) {
        const double e = double{root.max[a]} - double{root.min[a]};
        const double c = uni(root.min[a] - 0.02 * e, root.max[a] + 0.02 * e);
        const double h = e * std::exp(uni(std::log(1e-4), std::log(0.3)));
        q.min[a] = c - h;
        q.max[a] = c + h;
      }
      if (mode == 2) {
        const TreeNode& n = f.built.tree.nodes[rng() % f.built.tree.nodes.size()];
        if (!n.is_leaf()) q.min[n.axis] = q.max[n.axis] = (rng() % 2) ? n.a : n.b;
      }
    }
    leaves.clear();
    QueryStats st;
    f.built.tree.RouteBox(q, &leaves, &st);
    EXPECT_EQ(st.leaves_visited, leaves.size());
    for (size_t k = 1; k < leaves.size(); ++k) ASSERT_LT(leaves[k - 1], leaves[k]);
    std::fill(reached.begin(), reached.end(), 0);
    for (uint32_t l : leaves) reached[l] = 1;
    for (size_t k = 0; k < f.recs.size(); ++k) {
      if (f.recs[k].box.Intersects(q)) {
        ASSERT_TRUE(reached[f.leaf_of[k]]) << "box misses object " << f.recs[k].id;
      }
    }
  }
}

struct Case {
  SceneKind kind;
  size_t n;
  double r;
  SplitPolicy policy;
};

class RoutingTest : public ::testing::TestWithParam<Case> {};

TEST_P(RoutingTest, NeverMissesAnObject) {
  const Case c = GetParam();
  BuildParams p;
  p.balance_r = c.r;
  Fixture f = Build(MakeScene(c.kind, c.n, 1000 + c.n), p, testing::WithPolicy(c.policy));
  const size_t queries = c.n >= 10000 ? 150 : 400;
  CheckPoints(f, QueryPoints(f, queries, 7));
  CheckBoxes(f, queries, 8);
}

std::vector<Case> Cases() {
  std::vector<Case> cs;
  for (SplitPolicy pol : testing::kAllPolicies) {
    for (SceneKind k : {SceneKind::kUniform, SceneKind::kClustered, SceneKind::kIdentical, SceneKind::kPlates,
                        SceneKind::kHuge, SceneKind::kOversized, SceneKind::kShip, SceneKind::kGrid}) {
      for (size_t n : {1u, 2u, 7u, 300u, 5000u}) cs.push_back({k, n, 0.3, pol});
      cs.push_back({k, 3000, 0.0, pol});
      cs.push_back({k, 3000, 0.49, pol});
    }
    cs.push_back({SceneKind::kShip, 50000, 0.3, pol});
    cs.push_back({SceneKind::kUniform, 50000, 0.3, pol});
    cs.push_back({SceneKind::kGrid, 50000, 0.3, pol});
  }
  return cs;
}

INSTANTIATE_TEST_SUITE_P(Scenes, RoutingTest, ::testing::ValuesIn(Cases()), [](const auto& info) {
  return std::string(testing::Name(info.param.policy)) + "_" + testing::Name(info.param.kind) + "_" +
         std::to_string(info.param.n) + "_r" + std::to_string(static_cast<int>(info.param.r * 100));
});

// The leaf filter as the store builder writes it: each leaf's objects quantized in the leaf's order.
void AddLeafFilter(Fixture* f) {
  MKTree& t = f->built.tree;
  std::unordered_map<ObjectId, size_t> idx;
  for (size_t i = 0; i < f->recs.size(); ++i) idx[f->recs[i].id] = i;
  t.leaf_filter.clear();
  for (uint32_t l = 0; l < t.leaves.size(); ++l) {
    for (uint64_t k = f->built.leaf_offsets[l]; k < f->built.leaf_offsets[l + 1]; ++k) {
      t.leaf_filter.resize(t.leaf_filter.size() + kLeafFilterBytesPerObject);
      QuantizeBox(t.leaves[l].box, f->recs[idx[f->built.leaf_objects[k]]].box,
                  t.leaf_filter.data() + t.leaf_filter.size() - kLeafFilterBytesPerObject);
    }
  }
  ASSERT_TRUE(t.IndexLeafFilter());
}

auto StatsTuple(const QueryStats& s) {
  return std::make_tuple(s.internal_nodes_visited, s.split_nodes_visited, s.leaves_visited, s.leaves_filtered,
                         s.pages_touched, s.pages_read, s.cache_hits, s.bytes_read, s.candidates_tested,
                         s.hits, s.leaves_with_hits);
}

// The depth-first walk (small trees) against the breadth-first one (big trees; the walk every query took
// before): the same leaves in the same order and the same statistics, with and without the leaf filter,
// on trees from one leaf to thousands, for random boxes of every size and boxes that hold whole leaves.
TEST(Routing, DepthFirstAndBreadthFirstWalksAgree) {
  uint64_t compared = 0, nonempty = 0, filtered = 0;
  for (SceneKind kind :
       {SceneKind::kUniform, SceneKind::kClustered, SceneKind::kIdentical, SceneKind::kPlates,
        SceneKind::kHuge, SceneKind::kOversized, SceneKind::kShip, SceneKind::kGrid}) {
    for (size_t n : {1u, 2u, 7u, 40u, 300u, 2000u, 20000u}) {
      Fixture f = Build(MakeScene(kind, n, 77 + n), BuildParams());
      for (bool filter : {false, true}) {
        if (filter) AddLeafFilter(&f);
        const MKTree& t = f.built.tree;
        const Box3f& root = t.nodes[0].box;
        std::mt19937_64 rng(n * 31 + static_cast<uint64_t>(kind));
        auto uni = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
        for (int i = 0; i < 300; ++i) {
          Box3d q;
          if (i % 4 == 0) {  // a leaf's or node's box, grown a little or not: holds whole leaves
            const Box3f& b =
                (i % 8 == 0) ? t.leaves[rng() % t.leaves.size()].box : t.nodes[rng() % t.nodes.size()].box;
            const double grow = (i % 16 == 0) ? 0 : uni(0, 0.1);
            for (int a = 0; a < 3; ++a) {
              q.min[a] = b.min[a] - grow * (double{b.max[a]} - b.min[a]);
              q.max[a] = b.max[a] + grow * (double{b.max[a]} - b.min[a]);
            }
          } else {
            for (int a = 0; a < 3; ++a) {
              const double e = double{root.max[a]} - double{root.min[a]};
              const double c = uni(root.min[a] - 0.05 * e, root.max[a] + 0.05 * e);
              const double h = e * std::exp(uni(std::log(1e-4), std::log(0.7)));
              q.min[a] = c - h;
              q.max[a] = c + h;
            }
          }
          std::vector<uint32_t> depth_first{12345}, breadth_first{12345}, automatic{12345};  // appended to
          QueryStats sd, sb, sa;
          t.RouteBox(q, &depth_first, &sd, RouteWalk::kDepthFirst);
          t.RouteBox(q, &breadth_first, &sb, RouteWalk::kBreadthFirst);
          t.RouteBox(q, &automatic, &sa);
          ASSERT_EQ(depth_first, breadth_first) << testing::Name(kind) << " " << n << " query " << i;
          ASSERT_EQ(StatsTuple(sd), StatsTuple(sb)) << testing::Name(kind) << " " << n << " query " << i;
          ASSERT_EQ(automatic, depth_first);
          ASSERT_EQ(StatsTuple(sa), StatsTuple(sd));
          ++compared;
          nonempty += depth_first.size() > 1;
          filtered += sd.leaves_filtered;
        }
      }
    }
  }
  EXPECT_GT(nonempty, compared / 2);
  EXPECT_GT(filtered, 0u);
}

// A tree deeper than the depth-first walk's fixed stack (no store or build has one: the store loader
// refuses trees of more than 256 levels) still routes, through the growing stack, every leaf in leaf order.
TEST(Routing, TreesDeeperThanTheFixedStackRouteEveryLeaf) {
  constexpr uint32_t kDepth = 700;
  MKTree t;
  // Internal node i (index 2 i) has the next internal node on the left and a leaf on the right, so a
  // depth-first walk keeps one pending right leaf per level; the leaves are numbered in depth-first order.
  Box3f unit;
  unit.min = {0, 0, 0};
  unit.max = {1, 1, 1};
  for (uint32_t i = 0; i < kDepth; ++i) {
    TreeNode in;
    in.box = unit;
    in.axis = 0;
    in.a = 1;
    in.b = 0;  // a >= b: no overlap slab, the children's boxes decide
    in.child[0] = 2 * i + 2;
    in.child[1] = 2 * i + 1;
    t.nodes.push_back(in);
    TreeNode leaf;
    leaf.box = unit;
    leaf.leaf = kDepth - i;  // the deepest right leaf comes right after the bottom leaf (0)
    t.nodes.push_back(leaf);
  }
  TreeNode bottom;
  bottom.box = unit;
  bottom.leaf = 0;
  t.nodes.push_back(bottom);
  t.leaves.resize(kDepth + 1);
  for (uint32_t i = 0; i < kDepth; ++i) t.leaves[kDepth - i].node = 2 * i + 1;
  t.leaves[0].node = 2 * kDepth;
  for (LeafInfo& l : t.leaves) l.box = unit;

  std::vector<uint32_t> all(kDepth + 1);
  for (uint32_t i = 0; i <= kDepth; ++i) all[i] = i;
  Box3d q;
  q.min = {0.2, 0.2, 0.2};
  q.max = {0.5, 0.5, 0.5};
  for (RouteWalk walk : {RouteWalk::kAuto, RouteWalk::kDepthFirst, RouteWalk::kBreadthFirst}) {
    std::vector<uint32_t> leaves;
    QueryStats st;
    t.RouteBox(q, &leaves, &st, walk);
    EXPECT_EQ(leaves, all);
    EXPECT_EQ(st.internal_nodes_visited, kDepth);
    EXPECT_EQ(st.leaves_visited, kDepth + 1);
  }
  std::vector<uint32_t> leaves;
  QueryStats st;
  t.RoutePoint(Vec3d{0.5, 0.5, 0.5}, &leaves, &st);
  EXPECT_EQ(leaves, all);
  EXPECT_EQ(st.internal_nodes_visited, kDepth);
  EXPECT_EQ(st.leaves_visited, kDepth + 1);
}

TEST(Routing, StatsCountNodesAndPointsOutsideTheSceneReachNothing) {
  Fixture f = Build(MakeScene(SceneKind::kUniform, 5000, 4), BuildParams());
  std::vector<uint32_t> leaves;
  QueryStats st;
  f.built.tree.RoutePoint(Vec3d{-1000, 0, 0}, &leaves, &st);
  EXPECT_TRUE(leaves.empty());
  EXPECT_EQ(st.leaves_visited, 0u);
  const Box3f& b = f.recs[10].box;
  f.built.tree.RoutePoint(Vec3d{b.min[0], b.min[1], b.min[2]}, &leaves, &st);
  EXPECT_GE(leaves.size(), 1u);
  EXPECT_GE(st.internal_nodes_visited, f.built.stats.height > 1 ? 1u : 0u);
  EXPECT_EQ(st.leaves_visited, leaves.size());
  EXPECT_GT(f.built.tree.MemoryBytes(), 0u);
}

}  // namespace
}  // namespace mktree
