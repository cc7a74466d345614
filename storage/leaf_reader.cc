#include "storage/leaf_reader.h"

namespace mktree {

Result<PinnedLeaf> ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                            uint64_t mem_page, bool verify_checksums, QueryStats* stats) {
  PinnedLeaf out;
  std::vector<const uint8_t*> data;
  out.pages.reserve(info.page_count);
  data.reserve(info.page_count);
  for (uint64_t p = info.first_page; p < info.first_page + info.page_count; ++p) {
    auto h = cache.Pin(p, stats);
    if (!h.ok()) return h.status();
    data.push_back(h->data());
    out.pages.push_back(std::move(*h));
  }
  auto view = LeafView::Parse(store_name, leaf, info.first_page, data, mem_page, verify_checksums);
  if (!view.ok()) return view.status();
  out.view = std::move(*view);
  return out;
}

}  // namespace mktree
