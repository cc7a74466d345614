// Reading one leaf through the page cache: its pages pinned (each a cache lookup, a miss being a disk
// access) and parsed into a LeafView that stays valid as long as the PinnedLeaf holds them. The engine
// reads a store's leaves through LeafSource (leaf_source.h), which calls these with the store's pieces;
// pages with no store around them (the leaf fuzzer, the page cache's tests) call them directly.
#pragma once

#include <atomic>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/store_format/leaf_codec.h"
#include "engine/store_format/tree_codec.h"
#include "engine/tree/mktree.h"
#include "mktree/query_stats.h"
#include "storage/page_cache.h"

namespace mktree {

// A leaf's entries decoded for scanning, kept in the page cache with its first page (PageAttachment) and
// built only from pages that passed every check ReadLeaf makes: ids, shape flags and float32 boxes as
// arrays (struct of arrays, each box plane padded to a multiple of kLanes with boxes that meet nothing),
// and, for exact mode, the meshes decoded so far, up to as many bytes as the leaf's pages hold. The planes
// and ids are one block of memory, so that a scan reads it as one stream (and Prefetch can start it).
// Thread safety: immutable once built, but for the mesh slots, which any number of threads may fill.
class DecodedLeaf final : public PageAttachment {
 public:
  static constexpr size_t kLanes = 8;
  DecodedLeaf(const LeafView& view, uint64_t mesh_budget, std::vector<uint64_t> later_page_loads);
  ~DecodedLeaf() override;

  size_t size() const { return size_; }
  const ObjectId* ids() const { return ids_; }
  uint8_t shape_flags(size_t i) const { return shape_flags_[i]; }
  // Plane p: 0-2 min x/y/z, 3-5 max x/y/z; padded_size() floats each.
  const float* plane(int p) const { return boxes_ + static_cast<size_t>(p) * padded_; }
  size_t padded_size() const { return padded_; }
  // Whether every box has min <= max on each axis (none empty, no NaN). Then, as CheckLeafEntries found
  // each box within the leaf's box, a query box containing the leaf's box meets every one of them.
  bool boxes_ordered() const { return boxes_ordered_; }
  // Starts loading the ids (and with `boxes`, the planes) into the CPU caches.
  void Prefetch(bool boxes) const;
  // Load ids (PageHandle::load_id) of the leaf's pages after the first, as they were when it was built.
  const std::vector<uint64_t>& later_page_loads() const { return later_page_loads_; }
  // Object i's mesh if cached, else null.
  const Mesh* mesh(size_t i) const { return meshes_[i].load(std::memory_order_acquire); }
  // Caches `mesh` as object i's if the budget allows; returns the cached mesh, or null (over budget).
  const Mesh* CacheMesh(size_t i, Mesh&& mesh) const;
  uint64_t bytes() const;  // memory held, meshes included

 private:
  struct FreeBlock {
    void operator()(void* p) const;
  };
  size_t size_ = 0;
  size_t padded_ = 0;
  std::unique_ptr<void, FreeBlock> block_;  // the planes, then the ids, then the shape flags
  float* boxes_ = nullptr;
  ObjectId* ids_ = nullptr;
  uint8_t* shape_flags_ = nullptr;
  bool boxes_ordered_ = true;
  std::vector<uint64_t> later_page_loads_;
  std::unique_ptr<std::atomic<const Mesh*>[]> meshes_;
  const uint64_t mesh_budget_;
  mutable std::atomic<uint64_t> mesh_bytes_{0};
};

struct PinnedLeaf {
  std::vector<PageHandle> pages;          // declared first: destroyed after `view`, which points into them
  LeafView view;                          // empty when `decoded` came from the cache (see ParsePinned)
  const DecodedLeaf* decoded = nullptr;   // ReadLeaf with `decode` only; valid while `pages` are pinned
  std::vector<const uint8_t*> page_data;  // the pages' bytes, as LeafView::Parse takes them
  std::vector<uint64_t> seen;             // CheckLeafEntries' bit per object id, all zero between reads
  uint32_t leaf = 0;
  uint64_t first_page = 0;
  PageCache* cache = nullptr;  // the pages' cache

  // Unpins the pages (under one lock) and empties the view, keeping the buffers for the next ReadLeaf.
  void Release() {
    view.Clear();
    decoded = nullptr;
    if (cache != nullptr && !pages.empty()) cache->Release(pages);
    pages.clear();
  }
};

// Checks that a parsed leaf holds what the tree and the object table say it does, so that a damaged
// store gives an error, never a duplicated or missing id: the payload size the tree records
// (info.payload_bytes), exactly info.object_count entries, each id below the object count, no id twice,
// their id digest (the sum of ObjectIdHash) the one `objects` holds for the leaf, each entry's box within
// info.box. With the digests checked at open (they add up to the digest of all ids, the counts to the
// object count), the entries are then the leaf's objects but for a digest collision, which damage makes
// with odds of 2^-64 (a crafted file can aim for one): so the first leaf to pass claims its ids
// (objects.claims, leaf_claims.h) and a leaf holding an id another leaf claimed is refused, which no
// answer path can then see twice. `seen` is scratch: all zero (or empty) before the
// call, and again after it; it grows to one bit per object. Errors are Corruption naming the store and
// the leaf's first page.
Status CheckLeafEntries(const LeafView& view, const std::string& store_name, uint32_t leaf,
                        const LeafInfo& info, const ObjectTable& objects, std::vector<uint64_t>* seen);

// Pins pages [info.first_page, + info.page_count) of `cache` (adding to *stats if non-null), parses them
// as leaf `leaf` of `store_name` into *out (releasing what it held first; its buffers are reused) and
// checks the entries against the tree and the object table (CheckLeafEntries). With `verify_checksums`, a
// page's checksum is verified the first time it is read after being loaded into the cache
// (PageHandle::verified), so a corrupt page is refused on every read, but a cached page is not hashed again
// on every hit. Errors name the store and the page; on error *out holds nothing.
//
// With `decode`, out->decoded is the leaf's DecodedLeaf: the one cached with its first page if none of its
// pages was reloaded since it was built (then the pages are pinned, counted and checksummed as always, but
// the entries are not parsed again and out->view stays empty), else one built now from the parsed and
// checked entries and cached.
Status ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                const ObjectTable& objects, uint64_t mem_page, bool verify_checksums, QueryStats* stats,
                PinnedLeaf* out, bool decode = false);
// Parses out->view from the pinned pages if it is empty (after a ReadLeaf that took a cached DecodedLeaf):
// the same bytes that were checked when the DecodedLeaf was built, so the same entries in the same order.
Status ParsePinned(const std::string& store_name, uint64_t mem_page, PinnedLeaf* out);
// ReadLeaf's warm path: if every page of the leaf is in the cache (PageCache::PinCached) and, with
// `verify_checksums`, verified already, pins them and does what ReadLeaf does after pinning, returning
// true; else returns false having pinned and counted nothing (ReadLeaf then reads it as always). Unlike
// ReadLeaf, on an error out->pages stay pinned for the caller to release (in the order it pinned them), and
// out->view and out->decoded are empty.
Result<bool> ReadCachedLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf,
                            const LeafInfo& info, const ObjectTable& objects, uint64_t mem_page,
                            bool verify_checksums, QueryStats* stats, PinnedLeaf* out, bool decode);

}  // namespace mktree
