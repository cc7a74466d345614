// The builder's records in RAM (BuildMKTree, mktree_builder.h), before any node is split: the records laid
// out by the Morton cell of their box centres, and the six key orders of docs/design.md §3.2 ("the paper
// sorts six times": min_w and max_w for each axis w), each by an LSD radix sort. Internal to engine/tree.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "engine/tree/build_memory.h"
#include "engine/tree/object_record.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree::build {

// What the builder reads of an object, 28 bytes instead of BuildObject's 32, in two arrays: the boxes,
// and the encoded sizes (read alone when a node sums its bytes, 16 to a cache line). The ids are kept
// apart, for the end only.
struct BuildRecords {
  BuildVector<Box3f> box;
  BuildVector<uint32_t> bytes;
};

// The builder's records, grouped by the Morton cell of their box centres (16 cells an axis), in input order
// within a cell, so that a node's objects lie close together in RAM: the split sweeps and the list
// partitions read records in key order, which in input order misses the cache all the way down the tree.
// Cells this coarse cost one counting pass, and keep what locality the input order has. `all`: the union
// of the boxes. Frees `records`, giving their pages back as they are copied; *ids: the object ids in the
// same layout. With `threads` >= 2 the passes run on two halves.
BuildRecords SpatialLayout(std::vector<BuildObject> records, const Box3f& all, BuildVector<ObjectId>* ids,
                           int threads);

// The six key orders: (*lists)[2 * w + key] holds the object indices 0..n-1 sorted by min_w (key 0) or
// max_w (key 1), stable (ties in layout order, so that the boxes are read in order, not gathered). One
// sort after another, on one thread: one pair of radix buffers (two sorts side by side held two pairs,
// 16 bytes an object more at the peak, and were no faster: the sorts are bound by memory).
// `sorted(l)` runs once list l is complete (BuildMKTree spills it there).
void SortKeyOrders(const BuildVector<Box3f>& box, std::array<BuildVector<uint32_t>, 6>* lists,
                   const std::function<void(int)>& sorted);

}  // namespace mktree::build
