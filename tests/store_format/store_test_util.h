// Shared helpers for the storage tests: mesh generators (pipe prisms, boxes, random soups) and a
// builder that packs objects into leaves and a small valid MKTree, the way ingest does.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "engine/store_format/leaf_codec.h"
#include "engine/store_format/object_codec.h"
#include "engine/store_format/tree_codec.h"
#include "engine/tree/mktree.h"
#include "engine/tree/page_budget.h"
#include "mktree/scene.h"
#include "storage/page_store.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree::testing {

// A closed prism of `sides` sides along `axis`, as the tanker's pipes.
inline Mesh PrismMesh(std::mt19937& g, int sides, int axis) {
  std::uniform_real_distribution<double> u(0, 1);
  const double r = 0.025 + 0.225 * u(g), len = 0.3 + 39.7 * u(g);
  const double c[3] = {300 * u(g), 50 * u(g) - 25, 30 * u(g)};
  Mesh m;
  for (int e = 0; e < 2; ++e)
    for (int i = 0; i < sides; ++i) {
      const double a = 2 * M_PI * i / sides;
      double p[3];
      p[axis] = c[axis] + e * len;
      p[(axis + 1) % 3] = c[(axis + 1) % 3] + r * std::cos(a);
      p[(axis + 2) % 3] = c[(axis + 2) % 3] + r * std::sin(a);
      for (double v : p) m.vertices.push_back(static_cast<float>(v));
    }
  const uint32_t n = static_cast<uint32_t>(sides);
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t a = i, b = (i + 1) % n, cc = n + i, d = n + (i + 1) % n;
    m.triangles.insert(m.triangles.end(), {a, b, d, a, d, cc});
  }
  for (uint32_t i = 1; i + 1 < n; ++i) {
    m.triangles.insert(m.triangles.end(), {0u, i + 1, i});
    m.triangles.insert(m.triangles.end(), {n, n + i, n + i + 1});
  }
  return m;
}

// A closed axis-aligned box, as plates, walls and equipment.
inline Mesh BoxMesh(std::mt19937& g) {
  std::uniform_real_distribution<double> u(0, 1);
  const double x0 = 300 * u(g), y0 = 50 * u(g) - 25, z0 = 30 * u(g);
  const double dx = 0.01 + 5 * u(g), dy = 0.01 + 5 * u(g), dz = 0.01 + 3 * u(g);
  Mesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.push_back(static_cast<float>(x0 + (i & 1) * dx));
    m.vertices.push_back(static_cast<float>(y0 + ((i >> 1) & 1) * dy));
    m.vertices.push_back(static_cast<float>(z0 + ((i >> 2) & 1) * dz));
  }
  m.triangles = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  return m;
}

// Random vertices and triangles: incompressible-ish geometry.
inline Mesh RandomMesh(std::mt19937& g, uint32_t vertices, uint32_t triangles) {
  std::uniform_real_distribution<float> u(-1000, 1000);
  Mesh m;
  for (uint32_t i = 0; i < 3 * vertices; ++i) m.vertices.push_back(u(g));
  for (uint32_t i = 0; i < 3 * triangles; ++i) m.triangles.push_back(vertices ? g() % vertices : 0);
  return m;
}

// A mix like the tanker: mostly prisms and boxes, a few random meshes, occasionally a big one that needs
// a multi-page leaf.
inline std::vector<SceneObject> MakeObjects(uint32_t n, uint32_t seed, bool with_big = true) {
  std::mt19937 g(seed);
  std::vector<SceneObject> out(n);
  for (uint32_t i = 0; i < n; ++i) {
    SceneObject& o = out[i];
    o.id = i;
    const uint32_t kind = g() % 10;
    if (with_big && i % 97 == 50) {
      o.mesh = RandomMesh(g, 1500, 2000);  // ~42 KB raw: spans several 12 KiB pages
      o.name = "big_" + std::to_string(i);
    } else if (kind < 6) {
      o.mesh = PrismMesh(g, 8 + static_cast<int>(g() % 9), static_cast<int>(g() % 3));
      o.name = "pipe_" + std::to_string(i);
    } else if (kind < 9) {
      o.mesh = BoxMesh(g);
      o.name = "plate_" + std::to_string(i);
    } else {
      o.mesh = RandomMesh(g, 20 + g() % 30, 10 + g() % 40);
      o.name = "equipment_" + std::to_string(i) + (i % 7 == 0 ? std::string(40, 'x') : "");
    }
  }
  return out;
}

// What a test build produced: the tree, each object's leaf, and the encoded entries.
struct BuiltStore {
  MKTree tree;
  std::vector<uint32_t> object_leaf;
  ObjectTable objects;                        // count and leaf id digests (what CheckLeafEntries needs)
  std::vector<std::vector<uint8_t>> entries;  // by object id
};

// Packs objects into leaves in id order (a new leaf when the next entry would not fit), writes the
// leaf pages to `store`, and builds a balanced binary tree over the leaves with small SplitTrees.
inline Status BuildTestStore(const std::vector<SceneObject>& objects, const CodecOptions& codec,
                             const BuildParams& params, PageStore* store, BuiltStore* out) {
  out->tree = MKTree();
  out->tree.params = params;
  const uint64_t mem_page = params.mem_page();
  out->entries.clear();
  for (const SceneObject& o : objects) {
    std::vector<uint8_t> e;
    if (EncodeObjectEntry(o, codec, &e) == 0) return Status::Internal("encode failed");
    out->entries.push_back(std::move(e));
  }
  std::vector<std::vector<uint32_t>> groups;
  uint64_t sum = 0;
  for (uint32_t i = 0; i < objects.size(); ++i) {
    const uint64_t sz = out->entries[i].size();
    if (groups.empty() || !FitsInOnePage(sum + sz, mem_page)) {
      groups.emplace_back();
      sum = 0;
    }
    groups.back().push_back(i);
    sum += sz;
  }
  out->object_leaf.assign(objects.size(), 0);
  out->objects = ObjectTable();
  out->objects.count = objects.size();
  uint64_t page = 0;
  for (uint32_t l = 0; l < groups.size(); ++l) {
    std::vector<std::span<const uint8_t>> spans;
    LeafInfo info;
    uint64_t entry_sum = 0;
    for (uint32_t id : groups[l]) {
      spans.emplace_back(out->entries[id]);
      entry_sum += out->entries[id].size();
      info.box.Extend(objects[id].Aabb());
      out->object_leaf[id] = l;
    }
    out->objects.leaf_digest.push_back(0);
    for (uint32_t id : groups[l]) out->objects.leaf_digest.back() += ObjectIdHash(id);
    info.object_count = static_cast<uint32_t>(groups[l].size());
    info.payload_bytes = LeafPayloadBytes(entry_sum);
    info.first_page = page;
    info.page_count = static_cast<uint32_t>(PagesForLeaf(entry_sum, mem_page));
    Status st =
        EncodeLeafPages(l, spans, mem_page, [&](const uint8_t* p) { return store->WritePage(page++, p); });
    if (!st.ok()) return st;
    out->tree.leaves.push_back(info);
  }
  // Balanced tree over leaves [lo, hi): returns the node index.
  std::function<uint32_t(uint32_t, uint32_t, uint8_t)> build = [&](uint32_t lo, uint32_t hi, uint8_t depth) {
    const uint32_t idx = static_cast<uint32_t>(out->tree.nodes.size());
    out->tree.nodes.emplace_back();
    TreeNode n;
    n.depth = depth;
    for (uint32_t l = lo; l < hi; ++l) n.box.Extend(out->tree.leaves[l].box);
    if (hi - lo == 1) {
      n.leaf = lo;
      out->tree.leaves[lo].node = idx;
    } else {
      const uint32_t mid = (lo + hi) / 2;
      n.axis = depth % 3;
      const uint32_t s = static_cast<uint32_t>(out->tree.split_nodes.size());
      SplitNode inner;
      inner.axis = (depth + 1) % 3;
      inner.cut = 0.5f * depth;
      inner.child[0] = s + 1;
      inner.child[1] = s + 2;
      SplitNode left, right;
      left.label = CellLabel::kLeft;
      right.label = static_cast<CellLabel>(depth % 4);
      out->tree.split_nodes.insert(out->tree.split_nodes.end(), {inner, left, right});
      n.split_root = s;
      n.child[0] = build(lo, mid, depth + 1);
      n.child[1] = build(mid, hi, depth + 1);
      // The overlap planes as docs/design.md §3.3 defines them (stores refuse others).
      n.a = out->tree.nodes[n.child[1]].box.min[n.axis];
      n.b = out->tree.nodes[n.child[0]].box.max[n.axis];
    }
    out->tree.nodes[idx] = n;
    return idx;
  };
  if (!groups.empty()) build(0, static_cast<uint32_t>(groups.size()), 0);
  return Status::Ok();
}

}  // namespace mktree::testing
