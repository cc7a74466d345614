#include "engine/viz/level_colouring.h"

#include <vector>

#include "engine/store_format/leaf_source.h"

namespace mktree {

Rgb GroupColour(LevelGroup g) {
  switch (g) {
    case LevelGroup::kSn1:
      return {40, 90, 230};
    case LevelGroup::kSn2:
      return {220, 40, 40};
    case LevelGroup::kOverlap:
      return {30, 185, 60};
    case LevelGroup::kAboveLevel:
      break;
  }
  return {150, 150, 150};
}

const char* GroupName(LevelGroup g) {
  switch (g) {
    case LevelGroup::kSn1:
      return "Sn1";
    case LevelGroup::kSn2:
      return "Sn2";
    case LevelGroup::kOverlap:
      return "Sm";
    case LevelGroup::kAboveLevel:
      break;
  }
  return "above";
}

Status ForEachObjectAtLevel(const StoreReader& store, int k, const LevelVisitor& visit,
                            const std::function<void(uint64_t, uint64_t)>& progress) {
  if (k < 0) return Status::InvalidArgument("level must be >= 0");
  const MKTree& tree = store.tree();
  // Capacity 0: a page lives only while pinned, so RAM is one leaf whatever the store size.
  PageCache cache(&store.pages(), 0);
  const LeafSource leaves(store, cache, /*verify_checksums=*/true);
  const uint64_t n = tree.leaves.size();
  PinnedLeaf read;  // reused leaf after leaf: its buffers are allocated once
  for (uint32_t leaf = 0; leaf < n; ++leaf) {
    MKTREE_RETURN_IF_ERROR(leaves.Read(leaf, nullptr, &read));
    for (const ObjectEntryView& e : read.view.entries())
      MKTREE_RETURN_IF_ERROR(visit(leaf, e, GroupAtLevel(tree, leaf, e.box, k)));
    if (progress && (leaf % 256 == 0 || leaf + 1 == n)) progress(leaf + 1, n);
  }
  return Status::Ok();
}

}  // namespace mktree
