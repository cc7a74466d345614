// Reading one leaf through the page cache: its pages pinned (each a cache lookup, a miss being a disk
// access) and parsed into a LeafView that stays valid as long as the PinnedLeaf lives.
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
};

// Pins pages [info.first_page, + info.page_count) of `cache` (adding to *stats if non-null) and parses
// them as leaf `leaf` of `store_name`. Errors name the store and the page.
Result<PinnedLeaf> ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                            uint64_t mem_page, bool verify_checksums, QueryStats* stats);

}  // namespace mktree
