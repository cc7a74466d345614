#include "storage/tree_codec.h"

#include "engine/tree/leaf_filter.h"

#include <xxhash.h>

#include <cmath>

#include "storage/byte_io.h"

namespace mktree {

using storage_internal::ByteReader;
using storage_internal::ByteWriter;

namespace {

void PutBox(ByteWriter& w, const Box3f& b) {
  for (int i = 0; i < 3; ++i) w.Put<float>(b.min[i]);
  for (int i = 0; i < 3; ++i) w.Put<float>(b.max[i]);
}
Box3f GetBox(ByteReader& r) {
  Box3f b;
  for (int i = 0; i < 3; ++i) b.min[i] = r.Get<float>();
  for (int i = 0; i < 3; ++i) b.max[i] = r.Get<float>();
  return b;
}

Status CheckSize(std::span<const uint8_t> in, size_t record, const char* what) {
  if (in.size() % record != 0)
    return Status::Corruption(std::string(what) + " section size " + std::to_string(in.size()) +
                              " is not a multiple of its record size " + std::to_string(record));
  return Status::Ok();
}

}  // namespace

std::vector<uint8_t> EncodeParams(const BuildParams& p, const CodecOptions& c) {
  std::vector<uint8_t> out;
  ByteWriter w(&out);
  w.Put<uint32_t>(p.block_size);
  w.Put<uint32_t>(p.blocks_per_page);
  w.Put<double>(p.balance_r);
  w.Put<uint32_t>(p.split_tree_node_budget);
  w.Put<uint8_t>(static_cast<uint8_t>(c.codec));
  w.Put<uint8_t>(c.shuffle ? 1 : 0);
  w.Put<uint16_t>(0);
  w.Put<int32_t>(c.zstd_level);
  return out;
}

Status DecodeParams(std::span<const uint8_t> in, BuildParams* p, CodecOptions* c) {
  if (in.size() != kParamsRecordBytes) return Status::Corruption("parameter record has the wrong size");
  ByteReader r(in.data(), in.size());
  p->block_size = r.Get<uint32_t>();
  p->blocks_per_page = r.Get<uint32_t>();
  p->balance_r = r.Get<double>();
  p->split_tree_node_budget = r.Get<uint32_t>();
  const uint8_t codec = r.Get<uint8_t>();
  const uint8_t shuffle = r.Get<uint8_t>();
  r.Get<uint16_t>();
  c->zstd_level = r.Get<int32_t>();
  if (codec > 1 || shuffle > 1) return Status::Corruption("unknown codec in parameters");
  c->codec = static_cast<Codec>(codec);
  c->shuffle = shuffle == 1;
  const uint64_t mem_page = p->mem_page();
  if (p->block_size == 0 || p->blocks_per_page == 0 || mem_page <= 64 || mem_page > (uint64_t{1} << 30))
    return Status::Corruption("page size " + std::to_string(mem_page) + " out of range");
  if (!(p->balance_r >= 0 && p->balance_r < 0.5)) return Status::Corruption("balance ratio out of range");
  return Status::Ok();
}

std::vector<uint8_t> EncodeNodes(const std::vector<TreeNode>& nodes) {
  std::vector<uint8_t> out;
  out.reserve(nodes.size() * kNodeRecordBytes);
  ByteWriter w(&out);
  for (const TreeNode& n : nodes) {
    PutBox(w, n.box);
    w.Put<float>(n.a);
    w.Put<float>(n.b);
    w.Put<uint32_t>(n.child[0]);
    w.Put<uint32_t>(n.child[1]);
    w.Put<uint32_t>(n.leaf);
    w.Put<uint32_t>(n.split_root);
    w.Put<uint8_t>(n.axis);
    w.Put<uint8_t>(n.depth);
    w.Put<uint16_t>(0);
  }
  return out;
}

Status DecodeNodes(std::span<const uint8_t> in, std::vector<TreeNode>* nodes) {
  MKTREE_RETURN_IF_ERROR(CheckSize(in, kNodeRecordBytes, "node"));
  ByteReader r(in.data(), in.size());
  nodes->resize(in.size() / kNodeRecordBytes);
  for (TreeNode& n : *nodes) {
    n.box = GetBox(r);
    n.a = r.Get<float>();
    n.b = r.Get<float>();
    n.child[0] = r.Get<uint32_t>();
    n.child[1] = r.Get<uint32_t>();
    n.leaf = r.Get<uint32_t>();
    n.split_root = r.Get<uint32_t>();
    n.axis = r.Get<uint8_t>();
    n.depth = r.Get<uint8_t>();
    r.Get<uint16_t>();
  }
  return Status::Ok();
}

std::vector<uint8_t> EncodeSplitNodes(const std::vector<SplitNode>& nodes) {
  std::vector<uint8_t> out;
  out.reserve(nodes.size() * kSplitNodeRecordBytes);
  ByteWriter w(&out);
  for (const SplitNode& n : nodes) {
    w.Put<float>(n.cut);
    w.Put<uint32_t>(n.child[0]);
    w.Put<uint32_t>(n.child[1]);
    w.Put<uint8_t>(n.axis);
    w.Put<uint8_t>(static_cast<uint8_t>(n.label));
    w.Put<uint16_t>(0);
  }
  return out;
}

Status DecodeSplitNodes(std::span<const uint8_t> in, std::vector<SplitNode>* nodes) {
  MKTREE_RETURN_IF_ERROR(CheckSize(in, kSplitNodeRecordBytes, "split node"));
  ByteReader r(in.data(), in.size());
  nodes->resize(in.size() / kSplitNodeRecordBytes);
  for (SplitNode& n : *nodes) {
    n.cut = r.Get<float>();
    n.child[0] = r.Get<uint32_t>();
    n.child[1] = r.Get<uint32_t>();
    n.axis = r.Get<uint8_t>();
    const uint8_t label = r.Get<uint8_t>();
    r.Get<uint16_t>();
    if (label > 3) return Status::Corruption("split node label out of range");
    n.label = static_cast<CellLabel>(label);
  }
  return Status::Ok();
}

std::vector<uint8_t> EncodeLeaves(const std::vector<LeafInfo>& leaves) {
  std::vector<uint8_t> out;
  out.reserve(leaves.size() * kLeafRecordBytes);
  ByteWriter w(&out);
  for (const LeafInfo& l : leaves) {
    PutBox(w, l.box);
    w.Put<uint32_t>(l.node);
    w.Put<uint32_t>(l.object_count);
    w.Put<uint64_t>(l.payload_bytes);
    w.Put<uint64_t>(l.first_page);
    w.Put<uint32_t>(l.page_count);
    w.Put<uint32_t>(0);
  }
  return out;
}

Status DecodeLeaves(std::span<const uint8_t> in, std::vector<LeafInfo>* leaves) {
  MKTREE_RETURN_IF_ERROR(CheckSize(in, kLeafRecordBytes, "leaf"));
  ByteReader r(in.data(), in.size());
  leaves->resize(in.size() / kLeafRecordBytes);
  for (LeafInfo& l : *leaves) {
    l.box = GetBox(r);
    l.node = r.Get<uint32_t>();
    l.object_count = r.Get<uint32_t>();
    l.payload_bytes = r.Get<uint64_t>();
    l.first_page = r.Get<uint64_t>();
    l.page_count = r.Get<uint32_t>();
    r.Get<uint32_t>();
  }
  return Status::Ok();
}

std::vector<uint8_t> EncodeObjectLeaves(const ObjectTable& t) {
  std::vector<uint8_t> out(t.leaf.size() * 4);
  for (size_t i = 0; i < t.leaf.size(); ++i) storage_internal::Put<uint32_t>(out.data() + 4 * i, t.leaf[i]);
  return out;
}

std::vector<uint8_t> EncodeObjectNameEnds(const ObjectTable& t) {
  std::vector<uint8_t> out(t.name_end.size() * 8);
  for (size_t i = 0; i < t.name_end.size(); ++i) storage_internal::Put<uint64_t>(out.data() + 8 * i, t.name_end[i]);
  return out;
}

Status DecodeObjectTable(std::span<const uint8_t> leaves, std::span<const uint8_t> name_ends,
                         std::span<const uint8_t> names, ObjectTable* t) {
  MKTREE_RETURN_IF_ERROR(CheckSize(leaves, 4, "object leaf"));
  MKTREE_RETURN_IF_ERROR(CheckSize(name_ends, 8, "object name"));
  const size_t n = leaves.size() / 4;
  if (name_ends.size() / 8 != n) return Status::Corruption("object table sections disagree on the object count");
  t->leaf.resize(n);
  t->name_end.resize(n);
  uint64_t prev = 0;
  for (size_t i = 0; i < n; ++i) {
    t->leaf[i] = storage_internal::Get<uint32_t>(leaves.data() + 4 * i);
    t->name_end[i] = storage_internal::Get<uint64_t>(name_ends.data() + 8 * i);
    if (t->name_end[i] < prev || t->name_end[i] > names.size())
      return Status::Corruption("object name offsets out of order");
    prev = t->name_end[i];
  }
  if (prev != names.size()) return Status::Corruption("object names section has trailing bytes");
  t->names.assign(reinterpret_cast<const char*>(names.data()), names.size());
  return Status::Ok();
}

uint64_t Checksum(std::span<const uint8_t> bytes) { return XXH3_64bits(bytes.data(), bytes.size()); }

Status ValidateStructure(const MKTree& tree, const ObjectTable& objects, uint64_t page_count,
                         const std::string& what) {
  auto bad = [&](const std::string& m) { return Status::Corruption(what + ": " + m); };
  const size_t nn = tree.nodes.size(), ns = tree.split_nodes.size(), nl = tree.leaves.size();
  for (size_t i = 0; i < nn; ++i) {
    const TreeNode& n = tree.nodes[i];
    if (n.axis > 3) return bad("node " + std::to_string(i) + ": bad axis");
    if (n.is_leaf()) {
      if (n.leaf >= nl) return bad("node " + std::to_string(i) + ": leaf index out of range");
    } else {
      if (n.child[0] >= nn || n.child[1] >= nn || n.child[0] == i || n.child[1] == i)
        return bad("node " + std::to_string(i) + ": child index out of range");
      if (n.split_root != kNoIndex && n.split_root >= ns)
        return bad("node " + std::to_string(i) + ": SplitTree root out of range");
    }
  }
  for (size_t i = 0; i < ns; ++i) {
    const SplitNode& s = tree.split_nodes[i];
    if (s.axis > 3) return bad("split node " + std::to_string(i) + ": bad axis");
    if (!s.is_cell() && (s.child[0] >= ns || s.child[1] >= ns))
      return bad("split node " + std::to_string(i) + ": child index out of range");
  }
  uint64_t objects_in_leaves = 0;
  for (size_t i = 0; i < nl; ++i) {
    const LeafInfo& l = tree.leaves[i];
    if (l.node != kNoIndex && l.node >= nn) return bad("leaf " + std::to_string(i) + ": node index out of range");
    if (l.page_count == 0 || l.first_page + l.page_count > page_count || l.first_page + l.page_count < l.first_page)
      return bad("leaf " + std::to_string(i) + ": pages out of range (store has " + std::to_string(page_count) +
                 " pages)");
    objects_in_leaves += l.object_count;
  }
  for (size_t i = 0; i < objects.size(); ++i)
    if (objects.leaf[i] >= nl) return bad("object " + std::to_string(i) + ": leaf index out of range");
  if (objects_in_leaves != objects.size())
    return bad("leaves hold " + std::to_string(objects_in_leaves) + " objects but the object table has " +
               std::to_string(objects.size()));
  if (!tree.leaf_filter.empty() && tree.leaf_filter.size() != uint64_t{kLeafFilterBytesPerObject} * objects.size())
    return bad("leaf filter holds " + std::to_string(tree.leaf_filter.size()) + " bytes for " +
               std::to_string(objects.size()) + " objects");
  return Status::Ok();
}

bool SameTree(const MKTree& a, const MKTree& b) {
  return EncodeNodes(a.nodes) == EncodeNodes(b.nodes) &&
         EncodeSplitNodes(a.split_nodes) == EncodeSplitNodes(b.split_nodes) &&
         EncodeLeaves(a.leaves) == EncodeLeaves(b.leaves) && a.leaf_filter == b.leaf_filter &&
         EncodeParams(a.params, {}) == EncodeParams(b.params, {}) && a.origin.x == b.origin.x &&
         a.origin.y == b.origin.y && a.origin.z == b.origin.z;
}

}  // namespace mktree
