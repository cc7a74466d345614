// Reading one leaf through the page cache: its pages pinned (each a cache lookup, a miss being a disk
// access) and parsed into a LeafView that stays valid as long as the PinnedLeaf holds them.
#pragma once

#include <string>
#include <vector>

#include "engine/tree/mktree.h"
#include "mktree/query_stats.h"
#include "storage/leaf_codec.h"
#include "storage/page_cache.h"

namespace mktree {

struct PinnedLeaf {
  std::vector<PageHandle> pages;  // declared first: destroyed after `view`, which points into them
  LeafView view;
  std::vector<const uint8_t*> page_data;  // the pages' bytes, as LeafView::Parse takes them

  // Unpins the pages and empties the view, keeping the buffers for the next ReadLeaf.
  void Release() {
    view.Clear();
    pages.clear();
  }
};

// Pins pages [info.first_page, + info.page_count) of `cache` (adding to *stats if non-null) and parses
// them as leaf `leaf` of `store_name` into *out (releasing what it held first; its buffers are reused).
// With `verify_checksums`, a page's checksum is verified the first time it is read after being loaded
// into the cache (PageHandle::verified), so a corrupt page is refused on every read, but a cached page
// is not hashed again on every hit. Errors name the store and the page; on error *out holds nothing.
Status ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                uint64_t mem_page, bool verify_checksums, QueryStats* stats, PinnedLeaf* out);
// The same, into a new PinnedLeaf.
Result<PinnedLeaf> ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                            uint64_t mem_page, bool verify_checksums, QueryStats* stats);

}  // namespace mktree
