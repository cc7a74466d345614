// How the clash stages read a store (LeafSource): leaves pinned through its page cache, with the page
// lookups counted for ClashStats, and object meshes decoded with its dictionary. The stages reach the
// store's leaves and meshes only through these. Thread safety: ReadPinned and IoCount on one thread (the
// calling thread, so that the cache's counts do not depend on the workers); DecodeMesh on any thread.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "engine/clash/clash_engine.h"
#include "engine/geometry/mesh_separation.h"
#include "engine/store_format/leaf_reader.h"
#include "mktree/query_stats.h"

namespace mktree::clash {

// The I/O counts of a call: the cache's, and which pages were looked up.
struct IoCount {
  QueryStats q;
  std::vector<uint8_t> touched;
  void Mark(const LeafInfo& info, uint64_t base = 0);
  // pages_read, pages_touched, distinct_pages.
  void Fill(ClashStats* s) const;
};

// ReadLeaf with one duplicate-id scratch for every pinned leaf: ReadLeaf leaves it all zero, and each
// PinnedLeaf's own would keep a bit per object of the store (a batch pins up to hundreds of leaves).
// The leaf's pages count from `page_base` in io (several stores' pages numbered one after the other).
Status ReadPinned(const LeafSource& st, uint32_t leaf, IoCount* io, std::vector<uint64_t>* seen,
                  PinnedLeaf* out, uint64_t page_base = 0);

// DecodeStoredMesh with the store's name and dictionary.
Status DecodeMesh(const LeafSource& st, const ObjectEntryView& e, Mesh* mesh);

// The edge check ingest stored with the entry (computed by ClashShape when absent).
std::optional<EdgeCheck> StoredEdges(const ObjectEntryView& e);

// The pages of the tree's leaves (ClashStats::store_pages).
uint64_t StorePages(const MKTree& tree);

}  // namespace mktree::clash
