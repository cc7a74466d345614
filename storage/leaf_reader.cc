#include "storage/leaf_reader.h"

#include "storage/page_codec.h"

namespace mktree {

Status ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                uint64_t mem_page, bool verify_checksums, QueryStats* stats, PinnedLeaf* out) {
  out->Release();
  out->page_data.clear();
  for (uint64_t p = info.first_page; p < info.first_page + info.page_count; ++p) {
    auto h = cache.Pin(p, stats);
    if (!h.ok()) {
      out->Release();
      return h.status();
    }
    if (verify_checksums && !h->verified()) {
      auto checked = CheckPage(h->data(), mem_page, true, store_name, p);
      if (!checked.ok()) {
        out->Release();
        return checked.status();
      }
      h->MarkVerified();
    }
    out->page_data.push_back(h->data());
    out->pages.push_back(std::move(*h));
  }
  // Checksums are settled above; Parse still checks every header and entry.
  Status st = LeafView::Parse(store_name, leaf, info.first_page, out->page_data, mem_page, false, &out->view);
  if (!st.ok()) out->Release();
  return st;
}

Result<PinnedLeaf> ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                            uint64_t mem_page, bool verify_checksums, QueryStats* stats) {
  PinnedLeaf out;
  MKTREE_RETURN_IF_ERROR(ReadLeaf(cache, store_name, leaf, info, mem_page, verify_checksums, stats, &out));
  return out;
}

}  // namespace mktree
