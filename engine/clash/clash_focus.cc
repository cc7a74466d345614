#include "engine/clash/clash_focus.h"

#include <algorithm>
#include <utility>

#include "engine/clash/pair_rules.h"
#include "engine/store_format/record_codec.h"
#include "engine/tree/leaf_filter.h"

namespace mktree::clash {

namespace {

bool Contains(const Box3d& outer, const Box3d& inner) {
  for (int i = 0; i < 3; ++i)
    if (inner.min[i] < outer.min[i] || inner.max[i] > outer.max[i]) return false;
  return true;
}

// Marks node n if its subtree holds a marked leaf; returns the mark.
bool MarkNodes(const MKTree& tree, uint32_t n, const std::vector<uint8_t>& leaf_marked,
               std::vector<uint8_t>* nodes) {
  const TreeNode& node = tree.nodes[n];
  const bool marked = node.is_leaf() ? leaf_marked[node.leaf] != 0
                                     : MarkNodes(tree, node.child[0], leaf_marked, nodes) |
                                           MarkNodes(tree, node.child[1], leaf_marked, nodes);
  (*nodes)[n] = marked;
  return marked;
}

// Part k's focus marks for the focused global ids `ids` (increasing).
Status MarkPart(const PartNumbering& parts, size_t k, const std::vector<ObjectId>& ids, FocusMarks* out) {
  const MKTree& tree = parts.tree(k);
  const LeafSource& store = parts.store(k);
  RecordReader records(store.reader().record_layout(), nullptr, store.verify_checksums());
  const bool filter = !tree.leaf_filter.empty() && tree.leaf_filter_begin.size() == tree.leaves.size() + 1;
  std::vector<uint8_t> leaf_marked(tree.leaves.size(), 0);
  bool any = false;
  for (ObjectId g : ids) {
    ObjectId local = g;
    if (const std::vector<ObjectId>* map = parts.ids(k)) {
      const auto at = std::lower_bound(map->begin(), map->end(), g);
      if (at == map->end() || *at != g) continue;
      local = static_cast<ObjectId>(at - map->begin());
    } else if (g >= parts.object_count(k)) {
      break;
    }
    if (parts.hidden(k, local)) continue;
    auto record = records.Get(local, nullptr);
    if (!record.ok()) return record.status();
    const uint32_t leaf = (*record)->leaf;
    if (leaf >= tree.leaves.size())
      return Status::Corruption(parts.path(k) + ": the record of object " + std::to_string(local) +
                                " names no leaf of the tree");
    leaf_marked[leaf] = 1;
    any = true;
    if (!filter) continue;
    const LeafInfo& info = tree.leaves[leaf];
    const uint64_t base = tree.leaf_filter_begin[leaf] / kLeafFilterBytesPerObject;
    const uint8_t* q = tree.leaf_filter.data() + tree.leaf_filter_begin[leaf];
    const Box3d box = ToBox3d((*record)->box);
    const size_t before = out->slots.size();
    for (uint32_t i = 0; i < info.object_count; ++i)
      if (Contains(DequantizeBox(info.box, q + i * kLeafFilterBytesPerObject), box))
        out->slots.push_back(base + i);
    if (out->slots.size() == before)
      for (uint32_t i = 0; i < info.object_count; ++i) out->slots.push_back(base + i);
  }
  std::sort(out->slots.begin(), out->slots.end());
  out->slots.erase(std::unique(out->slots.begin(), out->slots.end()), out->slots.end());
  out->nodes.assign(tree.nodes.size(), 0);
  if (any) MarkNodes(tree, 0, leaf_marked, &out->nodes);
  return Status::Ok();
}

}  // namespace

Result<ClashFocus> ClashFocus::Make(const PartNumbering& parts, std::vector<ObjectId> ids,
                                    const std::vector<ObjectId>* partner) {
  auto sorted = [](std::vector<ObjectId>* v) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  };
  sorted(&ids);
  ClashFocus f;
  f.marks_.resize(parts.part_count());
  for (size_t k = 0; k < parts.part_count(); ++k)
    MKTREE_RETURN_IF_ERROR(MarkPart(parts, k, ids, &f.marks_[k]));
  f.ids_ = std::move(ids);
  if (partner) {
    f.has_partner_ = true;
    f.partner_ids_ = *partner;
    sorted(&f.partner_ids_);
    f.partner_marks_.resize(parts.part_count());
    for (size_t k = 0; k < parts.part_count(); ++k)
      MKTREE_RETURN_IF_ERROR(MarkPart(parts, k, f.partner_ids_, &f.partner_marks_[k]));
  }
  return f;
}

bool ClashFocus::Holds(ObjectId id) const { return std::binary_search(ids_.begin(), ids_.end(), id); }

bool ClashFocus::HoldsPartner(ObjectId id) const {
  return !has_partner_ || std::binary_search(partner_ids_.begin(), partner_ids_.end(), id);
}

}  // namespace mktree::clash
