#include "engine/store_format/tree_codec.h"

#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <new>

#include "engine/store_format/record_codec.h"
#include "engine/tree/leaf_filter.h"
#include "engine/tree/page_budget.h"

namespace mktree {

ParamsRecord ToParamsRecord(const BuildParams& p, const CodecOptions& c) {
  ParamsRecord r;
  r.block_size = p.block_size;
  r.blocks_per_page = p.blocks_per_page;
  r.balance_r = p.balance_r;
  r.split_tree_node_budget = p.split_tree_node_budget;
  r.codec = static_cast<uint8_t>(c.codec);
  r.shuffle = c.shuffle ? 1 : 0;
  r.zstd_level = c.zstd_level;
  return r;
}

std::vector<uint8_t> EncodeParams(const BuildParams& p, const CodecOptions& c) {
  const ParamsRecord r = ToParamsRecord(p, c);
  return EncodeRecords<kParamsRecord>(std::span<const ParamsRecord>(&r, 1));
}

Status DecodeParams(std::span<const uint8_t> in, BuildParams* p, CodecOptions* c) {
  if (in.size() != kParamsRecordBytes) return Status::Corruption("parameter record has the wrong size");
  ParamsRecord r;
  MKTREE_RETURN_IF_ERROR(DecodeRecords(kParamsRecord, in, &r));
  p->block_size = r.block_size;
  p->blocks_per_page = r.blocks_per_page;
  p->balance_r = r.balance_r;
  p->split_tree_node_budget = r.split_tree_node_budget;
  c->zstd_level = r.zstd_level;
  if (r.codec > 1 || r.shuffle > 1) return Status::Corruption("unknown codec in parameters");
  c->codec = static_cast<Codec>(r.codec);
  c->shuffle = r.shuffle == 1;
  const uint64_t mem_page = p->mem_page();
  if (p->block_size == 0 || p->blocks_per_page == 0 || mem_page <= 64 || mem_page > (uint64_t{1} << 30))
    return Status::Corruption("page size " + std::to_string(mem_page) + " out of range");
  if (!(p->balance_r >= 0 && p->balance_r < 0.5)) return Status::Corruption("balance ratio out of range");
  return Status::Ok();
}

std::vector<uint8_t> EncodeNodes(const std::vector<TreeNode>& nodes) {
  return EncodeRecords<kNodeRecord>(std::span(nodes));
}
Status DecodeNodes(std::span<const uint8_t> in, std::vector<TreeNode>* nodes) {
  return DecodeRecords<kNodeRecord>(in, nodes);
}
std::vector<uint8_t> EncodeSplitNodes(const std::vector<SplitNode>& nodes) {
  return EncodeRecords<kSplitNodeRecord>(std::span(nodes));
}
Status DecodeSplitNodes(std::span<const uint8_t> in, std::vector<SplitNode>* nodes) {
  return DecodeRecords<kSplitNodeRecord>(in, nodes);
}
std::vector<uint8_t> EncodeLeaves(const std::vector<LeafInfo>& leaves) {
  return EncodeRecords<kLeafRecord>(std::span(leaves));
}
Status DecodeLeaves(std::span<const uint8_t> in, std::vector<LeafInfo>* leaves) {
  return DecodeRecords<kLeafRecord>(in, leaves);
}
std::vector<uint8_t> EncodeLeafDigests(const ObjectTable& t) {
  return EncodeRecords<kLeafDigestColumn>(std::span(t.leaf_digest));
}
Status DecodeObjectTable(uint64_t count, std::span<const uint8_t> leaf_digests,
                         std::span<const uint8_t> directory, std::span<const uint8_t> sources,
                         ObjectTable* t) {
  t->count = count;
  MKTREE_RETURN_IF_ERROR(DecodeRecords<kLeafDigestColumn>(leaf_digests, &t->leaf_digest));
  MKTREE_RETURN_IF_ERROR(DecodeRecords<kRecordDirectoryColumn>(directory, &t->record_directory));
  return DecodeSources(sources, &t->sources);
}

uint64_t Checksum(std::span<const uint8_t> bytes) { return XXH3_64bits(bytes.data(), bytes.size()); }

uint64_t RecordsChecksum(const RecordSchema& s, const void* records, size_t n) {
  constexpr size_t kBlock = 65536;
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), XXH3_freeState);
  if (!state) throw std::bad_alloc();
  XXH3_64bits_reset(state.get());
  std::vector<uint8_t> block;
  const auto* in = static_cast<const uint8_t*>(records);
  for (size_t at = 0; at < n; at += kBlock) {
    const size_t k = std::min(kBlock, n - at);
    block.clear();
    EncodeRecords(s, in + at * s.ram_bytes, k, &block);
    XXH3_64bits_update(state.get(), block.data(), block.size());
  }
  return XXH3_64bits_digest(state.get());
}

namespace {

bool HasNan(const Box3f& b) {
  for (int i = 0; i < 3; ++i)
    if (std::isnan(b.min[i]) || std::isnan(b.max[i])) return true;
  return false;
}

std::string Num(uint64_t v) { return std::to_string(v); }

}  // namespace

Status ValidateStructure(const MKTree& tree, const ObjectTable& objects, uint64_t page_count,
                         const std::string& what) {
  auto bad = [&](const std::string& m) { return Status::Corruption(what + ": " + m); };
  const size_t nn = tree.nodes.size(), ns = tree.split_nodes.size(), nl = tree.leaves.size();
  const uint64_t n_objects = objects.size();
  // Indices are uint32 with kNoIndex reserved; object ids are uint32.
  if (nn >= kNoIndex || ns >= kNoIndex || nl >= kNoIndex || n_objects > UINT32_MAX)
    return bad("too many nodes, leaves or objects for 32-bit indices");
  if (nn == 0) {
    if (ns != 0 || nl != 0 || n_objects != 0)
      return bad("an empty tree with " + Num(ns) + " split nodes, " + Num(nl) + " leaves and " +
                 Num(n_objects) + " objects");
  }

  // The nodes, walked in depth-first preorder: the node reached next must be the next index.
  std::vector<uint8_t> split_seen(ns, 0);
  std::vector<std::pair<uint32_t, uint32_t>> split_stack;  // (split node, level)
  auto check_split_tree = [&](uint32_t node, uint32_t root) -> Status {
    split_stack.assign(1, {root, 1});
    while (!split_stack.empty()) {
      // Not a structured binding: clang 14 (the fuzz build) cannot capture one in the lambda below.
      const uint32_t s = split_stack.back().first, level = split_stack.back().second;
      split_stack.pop_back();
      auto name = [&] { return "split node " + Num(s) + " (SplitTree of node " + Num(node) + ")"; };
      if (split_seen[s]) return bad(name() + ": reached twice (a cycle or a shared split node)");
      split_seen[s] = 1;
      if (level > kMaxSplitTreeLevels)
        return bad(name() + ": SplitTree deeper than " + Num(kMaxSplitTreeLevels) + " levels");
      const SplitNode& sn = tree.split_nodes[s];
      if (sn.is_cell()) continue;
      if (sn.axis > 3) return bad(name() + ": bad axis");
      if (std::isnan(sn.cut)) return bad(name() + ": cut is not a number");
      for (uint32_t c : sn.child) {
        if (c >= ns) return bad(name() + ": child index out of range");
        split_stack.push_back({c, level + 1});
      }
    }
    return Status::Ok();
  };

  struct Visit {
    uint32_t node, depth;
  };
  std::vector<Visit> stack;
  if (nn > 0) stack.push_back({0, 0});
  uint32_t next = 0, next_leaf = 0;
  while (!stack.empty()) {
    const Visit v = stack.back();
    stack.pop_back();
    const uint32_t i = v.node;
    auto name = [&] { return "node " + Num(i); };
    if (i < next) return bad(name() + ": reached twice (a cycle or a shared child)");
    if (i > next) return bad("node " + Num(next) + ": not reached in depth-first order from the root");
    ++next;
    const TreeNode& n = tree.nodes[i];
    if (n.depth != v.depth)
      return bad(name() + ": depth " + Num(n.depth) + " where " + Num(v.depth) + " was expected");
    if (HasNan(n.box)) return bad(name() + ": box is not a number");
    if (n.is_leaf()) {
      if (n.child[0] != kNoIndex || n.child[1] != kNoIndex || n.split_root != kNoIndex)
        return bad(name() + ": a leaf node with children or a SplitTree");
      if (n.leaf >= nl) return bad(name() + ": leaf index out of range");
      if (n.leaf < next_leaf) return bad(name() + ": leaf " + Num(n.leaf) + " referenced twice");
      if (n.leaf > next_leaf)
        return bad(name() + ": leaf " + Num(n.leaf) + " where leaf " + Num(next_leaf) +
                   " was expected (leaves are numbered in depth-first order)");
      ++next_leaf;
      const LeafInfo& l = tree.leaves[n.leaf];
      if (l.node != i)
        return bad("leaf " + Num(n.leaf) + ": refers to node " + (l.node == kNoIndex ? "none" : Num(l.node)) +
                   " but node " + Num(i) + " refers to it");
      if (!(l.box == n.box)) return bad("leaf " + Num(n.leaf) + ": box differs from its node's");
      continue;
    }
    if (n.axis > 2) return bad(name() + ": bad axis");
    if (n.leaf != kNoIndex) return bad(name() + ": an internal node with a leaf");
    if (n.child[0] >= nn || n.child[1] >= nn) return bad(name() + ": child index out of range");
    if (n.depth == 255) return bad(name() + ": tree deeper than 256 levels");
    const TreeNode& left = tree.nodes[n.child[0]];
    const TreeNode& right = tree.nodes[n.child[1]];
    if (!BoxWithin(left.box, n.box) || !BoxWithin(right.box, n.box) || HasNan(left.box) || HasNan(right.box))
      return bad(name() + ": a child's box is not within the node's box");
    if (!(n.a == right.box.min[n.axis]) || !(n.b == left.box.max[n.axis]))
      return bad(name() + ": overlap planes a, b disagree with its children's boxes");
    if (n.split_root != kNoIndex) {
      if (n.split_root >= ns) return bad(name() + ": SplitTree root out of range");
      MKTREE_RETURN_IF_ERROR(check_split_tree(i, n.split_root));
    }
    // Right pushed first: the left subtree comes next in preorder.
    stack.push_back({n.child[1], v.depth + 1u});
    stack.push_back({n.child[0], v.depth + 1u});
  }
  if (next != nn) return bad("node " + Num(next) + ": not reachable from the root");
  if (next_leaf != nl) return bad("leaf " + Num(next_leaf) + ": not referenced by any node");
  for (size_t s = 0; s < ns; ++s)
    if (!split_seen[s]) return bad("split node " + Num(s) + ": not in any node's SplitTree");

  // The record pages follow the leaf pages: the directory has one entry per record page.
  if (objects.record_directory.size() > page_count)
    return bad(Num(objects.record_directory.size()) + " record pages in a store of " + Num(page_count) +
               " pages");
  MKTREE_RETURN_IF_ERROR(ValidateRecordDirectory(objects.record_directory, n_objects, what));
  page_count -= objects.record_directory.size();

  const uint64_t mem_page = tree.params.mem_page();
  uint64_t pages_end = 0;
  for (size_t i = 0; i < nl; ++i) {
    const LeafInfo& l = tree.leaves[i];
    auto name = [&] { return "leaf " + Num(i); };
    if (l.page_count == 0 || l.first_page > page_count || l.page_count > page_count - l.first_page)
      return bad(name() + ": pages out of range (store has " + Num(page_count) + " pages)");
    if (l.first_page < pages_end)
      return bad(name() + ": pages overlap the previous leaf's or are out of order");
    pages_end = l.first_page + l.page_count;
    if (l.payload_bytes < kLeafHeaderBytes ||
        l.page_count != PagesForLeaf(l.payload_bytes - kLeafHeaderBytes, mem_page))
      return bad(name() + ": " + Num(l.page_count) + " pages for " + Num(l.payload_bytes) + " payload bytes");
    if (l.object_count == 0 ||
        uint64_t{l.object_count} * kObjectEntryHeaderBytes > l.payload_bytes - kLeafHeaderBytes)
      return bad(name() + ": " + Num(l.object_count) + " objects in " + Num(l.payload_bytes) +
                 " payload bytes");
  }

  // Each leaf's entries are checked against its count and digest when it is read (CheckLeafEntries): the
  // counts and digests must account for every object once.
  if (objects.leaf_digest.size() != nl)
    return bad(Num(objects.leaf_digest.size()) + " leaf id digests for " + Num(nl) + " leaves");
  uint64_t in_leaves = 0, digests = 0;
  for (size_t i = 0; i < nl; ++i) {
    in_leaves += tree.leaves[i].object_count;
    digests += objects.leaf_digest[i];
  }
  if (in_leaves != n_objects)
    return bad("the leaves hold " + Num(in_leaves) + " objects but the store has " + Num(n_objects));
  if (digests != AllIdsDigest(n_objects))
    return bad("the leaves' id digests do not add up to the store's " + Num(n_objects) + " objects");
  if (!tree.leaf_filter.empty() && tree.leaf_filter.size() != uint64_t{kLeafFilterBytesPerObject} * n_objects)
    return bad("leaf filter holds " + Num(tree.leaf_filter.size()) + " bytes for " + Num(n_objects) +
               " objects");
  return Status::Ok();
}

namespace {

// The keys TreeStats::ToJson and LevelStats write (engine/tree/tree_stats.cc).
// clang-format off
constexpr std::string_view kStatsKeys[] = {
    "objects", "height", "internal_nodes", "leaves", "pages", "multi_page_leaves", "min_objects_per_leaf",
    "mean_objects_per_leaf", "max_objects_per_leaf", "mem_page", "mean_page_fill", "min_page_fill",
    "split_tree_nodes", "max_split_tree_nodes", "split_tree_cells", "both_cells", "overlap_objects",
    "index_bytes_per_object", "tree_bytes_per_object", "levels"};
constexpr std::string_view kLevelKeys[] = {
    "depth", "nodes", "internal_nodes", "overlap_nodes", "overlap_objects", "mean_overlap_objects",
    "mean_slab_rel_width", "split_tree_nodes", "split_tree_cells", "both_cells", "both_cell_share",
    "both_volume_share"};
// clang-format on
constexpr size_t kMaxStatsLevels = 256;

// A strict reader of the statistics' JSON subset: objects of known keys with number values, one array.
class StatsJsonReader {
 public:
  explicit StatsJsonReader(std::string_view s) : s_(s) {}

  Status Read() {
    Space();
    if (at_ == s_.size()) return Status::Ok();  // no statistics
    MKTREE_RETURN_IF_ERROR(Object(kStatsKeys, true));
    Space();
    if (at_ != s_.size()) return Fail("trailing bytes after the object");
    return Status::Ok();
  }

 private:
  template <size_t N>
  Status Object(const std::string_view (&keys)[N], bool top) {
    if (!Eat('{')) return Fail("an object was expected");
    bool seen[N] = {};
    Space();
    if (Eat('}')) return Status::Ok();
    for (;;) {
      Space();
      std::string_view key;
      MKTREE_RETURN_IF_ERROR(Key(&key));
      size_t k = 0;
      while (k < N && keys[k] != key) ++k;
      if (k == N) return Fail("unknown key \"" + std::string(key) + "\"");
      if (seen[k]) return Fail("key \"" + std::string(key) + "\" appears twice");
      seen[k] = true;
      Space();
      if (!Eat(':')) return Fail("':' expected");
      Space();
      if (top && key == "levels") {
        MKTREE_RETURN_IF_ERROR(Levels());
      } else {
        MKTREE_RETURN_IF_ERROR(Number(key));
      }
      Space();
      if (Eat('}')) return Status::Ok();
      if (!Eat(',')) return Fail("',' or '}' expected");
    }
  }

  Status Levels() {
    if (!Eat('[')) return Fail("\"levels\" is not an array");
    Space();
    if (Eat(']')) return Status::Ok();
    for (size_t n = 1;; ++n) {
      if (n > kMaxStatsLevels) return Fail("more than " + std::to_string(kMaxStatsLevels) + " levels");
      Space();
      MKTREE_RETURN_IF_ERROR(Object(kLevelKeys, false));
      Space();
      if (Eat(']')) return Status::Ok();
      if (!Eat(',')) return Fail("',' or ']' expected");
    }
  }

  // Keys are lower-case words: nothing to escape.
  Status Key(std::string_view* key) {
    if (!Eat('"')) return Fail("a key was expected");
    const size_t b = at_;
    while (at_ < s_.size() && ((s_[at_] >= 'a' && s_[at_] <= 'z') || s_[at_] == '_')) ++at_;
    if (!Eat('"')) return Fail("a key was expected");
    *key = s_.substr(b, at_ - 1 - b);
    return Status::Ok();
  }

  // A JSON number: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?
  Status Number(std::string_view key) {
    auto digits = [&] {
      const size_t b = at_;
      while (at_ < s_.size() && s_[at_] >= '0' && s_[at_] <= '9') ++at_;
      return at_ > b;
    };
    const size_t b = at_;
    Eat('-');
    if (!Eat('0') && !digits()) return Fail("the value of \"" + std::string(key) + "\" is not a number");
    if (Eat('.') && !digits()) return Fail("the value of \"" + std::string(key) + "\" is not a number");
    if (Eat('e') || Eat('E')) {
      if (!Eat('+')) Eat('-');
      if (!digits()) return Fail("the value of \"" + std::string(key) + "\" is not a number");
    }
    return at_ > b ? Status::Ok() : Fail("a number was expected");
  }

  void Space() {
    while (at_ < s_.size() && (s_[at_] == ' ' || s_[at_] == '\n' || s_[at_] == '\t' || s_[at_] == '\r'))
      ++at_;
  }
  bool Eat(char c) {
    if (at_ < s_.size() && s_[at_] == c) {
      ++at_;
      return true;
    }
    return false;
  }
  Status Fail(const std::string& what) const {
    return Status::Corruption("build statistics: " + what + " at byte " + std::to_string(at_));
  }

  std::string_view s_;
  size_t at_ = 0;
};

}  // namespace

Status ValidateStatsJson(std::string_view json) { return StatsJsonReader(json).Read(); }

bool SameTree(const MKTree& a, const MKTree& b) {
  return EncodeNodes(a.nodes) == EncodeNodes(b.nodes) &&
         EncodeSplitNodes(a.split_nodes) == EncodeSplitNodes(b.split_nodes) &&
         EncodeLeaves(a.leaves) == EncodeLeaves(b.leaves) && a.leaf_filter == b.leaf_filter &&
         EncodeParams(a.params, {}) == EncodeParams(b.params, {}) && a.origin.x == b.origin.x &&
         a.origin.y == b.origin.y && a.origin.z == b.origin.z;
}

}  // namespace mktree
