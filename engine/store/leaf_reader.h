// Reading one leaf through the page cache: its pages pinned (each a cache lookup, a miss being a disk
// access) and parsed into a LeafView that stays valid as long as the PinnedLeaf holds them.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "engine/store/leaf_codec.h"
#include "engine/tree/mktree.h"
#include "mktree/query_stats.h"
#include "storage/page_cache.h"

namespace mktree {

struct PinnedLeaf {
  std::vector<PageHandle> pages;  // declared first: destroyed after `view`, which points into them
  LeafView view;
  std::vector<const uint8_t*> page_data;  // the pages' bytes, as LeafView::Parse takes them
  std::vector<uint64_t> seen;             // CheckLeafEntries' bit per object id, all zero between reads

  // Unpins the pages and empties the view, keeping the buffers for the next ReadLeaf.
  void Release() {
    view.Clear();
    pages.clear();
  }
};

// Checks that a parsed leaf holds what the tree and the object table say it does, so that a store
// tampered with behind valid checksums gives an error, never a duplicated or missing id: the payload
// size the tree records (info.payload_bytes), exactly info.object_count entries, each id an object that
// `object_leaf` (the object table's leaf of each object id) puts in leaf `leaf`, no id twice, each entry's
// box within info.box. With the table checked at open (each leaf's object_count is its number of objects in
// the table), the entries are then exactly the leaf's objects. `seen` is scratch: all zero (or empty) before
// the call, and again after it; it grows to one bit per object. Errors are Corruption naming the store and
// the leaf's first page.
Status CheckLeafEntries(const LeafView& view, const std::string& store_name, uint32_t leaf,
                        const LeafInfo& info, std::span<const uint32_t> object_leaf,
                        std::vector<uint64_t>* seen);

// Pins pages [info.first_page, + info.page_count) of `cache` (adding to *stats if non-null), parses them
// as leaf `leaf` of `store_name` into *out (releasing what it held first; its buffers are reused) and
// checks the entries against the tree and the object table (CheckLeafEntries; `object_leaf` is
// ObjectTable::leaf). With `verify_checksums`, a page's checksum is verified the first time it is read
// after being loaded into the cache (PageHandle::verified), so a corrupt page is refused on every read,
// but a cached page is not hashed again on every hit. Errors name the store and the page; on error *out
// holds nothing.
Status ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                std::span<const uint32_t> object_leaf, uint64_t mem_page, bool verify_checksums,
                QueryStats* stats, PinnedLeaf* out);
// The same, into a new PinnedLeaf.
Result<PinnedLeaf> ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf,
                            const LeafInfo& info, std::span<const uint32_t> object_leaf, uint64_t mem_page,
                            bool verify_checksums, QueryStats* stats);

// DecodeObjectMesh, naming the store in its error (the entry's own checks cannot know the file).
inline Status DecodeStoredMesh(const std::string& store_name, const ObjectEntryView& e, Mesh* mesh) {
  Status st = DecodeObjectMesh(e, mesh);
  return st.ok() ? st : Status::Corruption(store_name + ": " + st.message());
}

}  // namespace mktree
