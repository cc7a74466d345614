#include "engine/tree/tree_stats.h"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <thread>

#include "engine/tree/split_tree_walk.h"

namespace mktree {
namespace {

double Volume(const Box3f& b) {
  double v = 1;
  for (int i = 0; i < 3; ++i) v *= std::max(0.0, double{b.max[i]} - double{b.min[i]});
  return v;
}

struct SplitTreeShape {
  uint32_t nodes = 0, cells = 0, both = 0;
  double volume = 0, both_volume = 0;
};

// Walks one SplitTree, each cell with its part of the overlap region q.
SplitTreeShape Shape(const MKTree& t, uint32_t root, const Box3f& q) {
  SplitTreeShape s;
  uint64_t nodes = 0;
  ForEachSplitCell(
      t.split_nodes, root, SplitRegion{q},
      [&](const SplitNode& cell, const Box3f& region) {
        ++s.cells;
        const double v = Volume(region);
        s.volume += v;
        if (cell.label == CellLabel::kBoth) {
          ++s.both;
          s.both_volume += v;
        }
        return true;
      },
      &nodes);
  s.nodes = static_cast<uint32_t>(nodes);
  return s;
}

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

TreeStats ComputeTreeStats(const MKTree& tree, uint64_t object_count,
                           std::span<const uint32_t> overlap_counts, int threads) {
  TreeStats s;
  s.objects = object_count;
  s.mem_page = tree.params.mem_page();
  s.has_overlap_counts = !overlap_counts.empty() && overlap_counts.size() == tree.nodes.size();
  if (tree.empty()) return s;
  // The shape of every node's SplitTree (most of the work: a tree has about as many SplitTree nodes as
  // objects),
  // by node index, in two halves when there are two threads; the walk below sums them in its own order.
  std::vector<SplitTreeShape> shapes(tree.nodes.size());
  auto measure = [&](size_t lo, size_t hi) {
    for (size_t ni = lo; ni < hi; ++ni) {
      const TreeNode& n = tree.nodes[ni];
      if (n.is_leaf() || n.split_root == kNoIndex) continue;
      Box3f q = n.box;
      q.min[n.axis] = n.a;
      q.max[n.axis] = n.b;
      shapes[ni] = Shape(tree, n.split_root, q);
    }
  };
  const size_t half = tree.nodes.size() / 2;
  if (threads >= 2 && tree.split_nodes.size() >= 4096) {
    std::thread other(measure, size_t{0}, half);
    measure(half, tree.nodes.size());
    other.join();
  } else {
    measure(0, tree.nodes.size());
  }
  std::vector<double> slab_sum, vol_share_sum;
  std::vector<uint64_t> vol_nodes;
  // Depths by walking (TreeNode::depth saturates at 255).
  std::vector<std::pair<uint32_t, uint32_t>> stack{{0, 0}};
  while (!stack.empty()) {
    auto [ni, d] = stack.back();
    stack.pop_back();
    const TreeNode& n = tree.nodes[ni];
    if (s.levels.size() <= d) {
      s.levels.resize(d + 1);
      slab_sum.resize(d + 1, 0);
      vol_share_sum.resize(d + 1, 0);
      vol_nodes.resize(d + 1, 0);
      s.levels[d].depth = d;
    }
    LevelStats& L = s.levels[d];
    ++L.nodes;
    if (n.is_leaf()) continue;
    ++s.internal_nodes;
    ++L.internal_nodes;
    const double extent = double{n.box.max[n.axis]} - double{n.box.min[n.axis]};
    if (n.a < n.b) {
      ++L.overlap_nodes;
      if (extent > 0) slab_sum[d] += (double{n.b} - double{n.a}) / extent;
    }
    if (s.has_overlap_counts) L.overlap_objects += overlap_counts[ni];
    if (n.split_root != kNoIndex) {
      const SplitTreeShape& sh = shapes[ni];
      L.split_tree_nodes += sh.nodes;
      L.split_tree_cells += sh.cells;
      L.both_cells += sh.both;
      s.max_split_tree_nodes = std::max(s.max_split_tree_nodes, sh.nodes);
      if (sh.volume > 0) {
        vol_share_sum[d] += sh.both_volume / sh.volume;
        ++vol_nodes[d];
      }
    }
    stack.push_back({n.child[1], d + 1});
    stack.push_back({n.child[0], d + 1});
  }
  s.height = static_cast<uint32_t>(s.levels.size());
  for (size_t d = 0; d < s.levels.size(); ++d) {
    LevelStats& L = s.levels[d];
    if (L.internal_nodes > 0) {
      L.mean_overlap_objects = double(L.overlap_objects) / double(L.internal_nodes);
      L.mean_slab_rel_width = slab_sum[d] / double(L.internal_nodes);
    }
    if (L.split_tree_cells > 0) L.both_cell_share = double(L.both_cells) / double(L.split_tree_cells);
    if (vol_nodes[d] > 0) L.both_volume_share = vol_share_sum[d] / double(vol_nodes[d]);
    s.overlap_objects += L.overlap_objects;
    s.split_tree_nodes += L.split_tree_nodes;
    s.split_tree_cells += L.split_tree_cells;
    s.both_cells += L.both_cells;
  }

  s.leaves = tree.leaves.size();
  s.min_objects_per_leaf = std::numeric_limits<uint32_t>::max();
  double fill_sum = 0;
  uint64_t single = 0;
  s.min_page_fill = 1;
  for (const LeafInfo& lf : tree.leaves) {
    s.pages += lf.page_count;
    s.min_objects_per_leaf = std::min(s.min_objects_per_leaf, lf.object_count);
    s.max_objects_per_leaf = std::max(s.max_objects_per_leaf, lf.object_count);
    if (lf.page_count > 1) {
      ++s.multi_page_leaves;
      continue;
    }
    const double fill = double(lf.payload_bytes) / double(s.mem_page);
    fill_sum += fill;
    s.min_page_fill = std::min(s.min_page_fill, fill);
    ++single;
  }
  if (single == 0) s.min_page_fill = 0;
  s.mean_page_fill = single ? fill_sum / double(single) : 0;
  s.mean_objects_per_leaf = s.leaves ? double(object_count) / double(s.leaves) : 0;
  if (object_count > 0) {
    s.index_bytes_per_object =
        double(s.internal_nodes * sizeof(TreeNode) + tree.split_nodes.size() * sizeof(SplitNode)) /
        double(object_count);
    s.tree_bytes_per_object = double(tree.MemoryBytes()) / double(object_count);
  }
  return s;
}

std::string TreeStats::ToJson() const {
  std::string j = "{";
  auto num = [&](const char* k, double v, bool integral) {
    if (j.size() > 1) j += ", ";
    j += '"';
    j += k;
    j += "\": ";
    j += integral ? std::to_string(static_cast<uint64_t>(v)) : Fmt("%.6g", v);
  };
  num("objects", double(objects), true);
  num("height", height, true);
  num("internal_nodes", double(internal_nodes), true);
  num("leaves", double(leaves), true);
  num("pages", double(pages), true);
  num("multi_page_leaves", double(multi_page_leaves), true);
  num("min_objects_per_leaf", min_objects_per_leaf, true);
  num("mean_objects_per_leaf", mean_objects_per_leaf, false);
  num("max_objects_per_leaf", max_objects_per_leaf, true);
  num("mem_page", double(mem_page), true);
  num("mean_page_fill", mean_page_fill, false);
  num("min_page_fill", min_page_fill, false);
  num("split_tree_nodes", double(split_tree_nodes), true);
  num("max_split_tree_nodes", max_split_tree_nodes, true);
  num("split_tree_cells", double(split_tree_cells), true);
  num("both_cells", double(both_cells), true);
  if (has_overlap_counts) num("overlap_objects", double(overlap_objects), true);
  num("index_bytes_per_object", index_bytes_per_object, false);
  num("tree_bytes_per_object", tree_bytes_per_object, false);
  j += ", \"levels\": [";
  for (size_t d = 0; d < levels.size(); ++d) {
    const LevelStats& L = levels[d];
    std::string o = "{";
    auto m = [&](const char* k, double v, bool integral) {
      if (o.size() > 1) o += ", ";
      o += '"';
      o += k;
      o += "\": ";
      o += integral ? std::to_string(static_cast<uint64_t>(v)) : Fmt("%.6g", v);
    };
    m("depth", L.depth, true);
    m("nodes", double(L.nodes), true);
    m("internal_nodes", double(L.internal_nodes), true);
    m("overlap_nodes", double(L.overlap_nodes), true);
    if (has_overlap_counts) {
      m("overlap_objects", double(L.overlap_objects), true);
      m("mean_overlap_objects", L.mean_overlap_objects, false);
    }
    m("mean_slab_rel_width", L.mean_slab_rel_width, false);
    m("split_tree_nodes", double(L.split_tree_nodes), true);
    m("split_tree_cells", double(L.split_tree_cells), true);
    m("both_cells", double(L.both_cells), true);
    m("both_cell_share", L.both_cell_share, false);
    m("both_volume_share", L.both_volume_share, false);
    j += (d ? ", " : "") + o + "}";
  }
  j += "]}";
  return j;
}

std::string TreeStats::ToString() const {
  std::string s;
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "objects %llu, height %u, internal nodes %llu, leaves %llu, pages %llu (MemPage %llu B)\n",
                (unsigned long long)objects, height, (unsigned long long)internal_nodes,
                (unsigned long long)leaves, (unsigned long long)pages, (unsigned long long)mem_page);
  s += buf;
  std::snprintf(
      buf, sizeof buf,
      "objects/leaf min %u mean %.2f max %u; page fill mean %.1f%% min %.1f%%; multi-page leaves %llu\n",
      min_objects_per_leaf, mean_objects_per_leaf, max_objects_per_leaf, 100 * mean_page_fill,
      100 * min_page_fill, (unsigned long long)multi_page_leaves);
  s += buf;
  std::snprintf(buf, sizeof buf,
                "SplitTrees: %llu nodes (largest %u), %llu cells, %llu BOTH; |Sm| total %s\n",
                (unsigned long long)split_tree_nodes, max_split_tree_nodes,
                (unsigned long long)split_tree_cells, (unsigned long long)both_cells,
                has_overlap_counts ? std::to_string(overlap_objects).c_str() : "unknown");
  s += buf;
  std::snprintf(buf, sizeof buf,
                "RAM: index (internal nodes + SplitTrees) %.2f B/object, whole tree %.2f B/object\n",
                index_bytes_per_object, tree_bytes_per_object);
  s += buf;
  s += "depth  nodes  internal  mean|Sm|  slab/extent  sp.nodes  BOTH%cells  BOTH%vol\n";
  for (const LevelStats& L : levels) {
    std::snprintf(buf, sizeof buf, "%5u %6llu %9llu %9.2f %12.4f %9llu %10.1f %9.1f\n", L.depth,
                  (unsigned long long)L.nodes, (unsigned long long)L.internal_nodes, L.mean_overlap_objects,
                  L.mean_slab_rel_width, (unsigned long long)L.split_tree_nodes, 100 * L.both_cell_share,
                  100 * L.both_volume_share);
    s += buf;
  }
  return s;
}

}  // namespace mktree
