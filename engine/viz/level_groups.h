// The level-k grouping of docs/design.md §9, which the pictures and exports colour by: at an object's
// ancestor of depth k, whether it is in that node's overlap set Sm or on one side of it.
#pragma once

#include <cstdint>

#include "engine/tree/mktree.h"
#include "mktree/geometry.h"

namespace mktree {

// The group of an object stored in leaf `leaf`, at the ancestor of that leaf at depth k: kOverlap when it
// is in that node's overlap set Sm (max_w > a and min_w < b), else the side (child subtree) that holds it.
// kAboveLevel when the leaf itself is at depth <= k (no node at depth k splits it), or when k < 0 or
// `leaf` is out of range.
enum class LevelGroup { kSn1, kSn2, kOverlap, kAboveLevel };
LevelGroup GroupAtLevel(const MKTree& tree, uint32_t leaf, const Box3f& object_box, int k);

}  // namespace mktree
