#include "engine/store/leaf_reader.h"

#include <algorithm>

#include "engine/store/tree_codec.h"
#include "storage/page_codec.h"

namespace mktree {

Status CheckLeafEntries(const LeafView& view, const std::string& store_name, uint32_t leaf,
                        const LeafInfo& info, std::span<const uint32_t> object_leaf,
                        std::vector<uint64_t>* seen) {
  auto fail = [&](const std::string& what) {
    return Status::Corruption(store_name + ": page " + std::to_string(info.first_page) + " (leaf " +
                              std::to_string(leaf) + "): " + what);
  };
  if (view.payload_bytes() != info.payload_bytes)
    return fail("holds a payload of " + std::to_string(view.payload_bytes()) + " bytes but the tree says " +
                std::to_string(info.payload_bytes));
  if (view.size() != info.object_count)
    return fail("holds " + std::to_string(view.size()) + " objects but the tree says " +
                std::to_string(info.object_count));
  // Duplicates: one bit per object id, set as ids are met and cleared (whole words: every bit set is
  // one of this leaf's) before returning, so that it is all zero between calls. Unlike sorting the ids,
  // this costs a few cache hits per entry.
  const size_t words = (object_leaf.size() + 63) / 64;
  if (seen->size() < words) seen->resize(words, 0);
  uint64_t* bits = seen->data();
  const std::vector<ObjectEntryView>& entries = view.entries();
  // The table lookups miss the CPU caches (ids are scattered over it): start them all first.
  for (const ObjectEntryView& e : entries)
    if (e.id < object_leaf.size()) __builtin_prefetch(&object_leaf[e.id]);
  size_t i = 0;
  std::string problem;
  for (; i < entries.size(); ++i) {
    const ObjectEntryView& e = entries[i];
    if (e.id >= object_leaf.size()) {
      problem = "object " + std::to_string(e.id) + " out of range (" + std::to_string(object_leaf.size()) +
                " objects)";
      break;
    }
    if (object_leaf[e.id] != leaf) {
      problem = "object " + std::to_string(e.id) + " belongs to leaf " + std::to_string(object_leaf[e.id]);
      break;
    }
    if (!BoxWithin(e.box, info.box)) {
      problem = "object " + std::to_string(e.id) + " lies outside the leaf's box";
      break;
    }
    uint64_t& word = bits[e.id >> 6];
    const uint64_t bit = uint64_t{1} << (e.id & 63);
    if (word & bit) {
      problem = "object " + std::to_string(e.id) + " appears twice";
      break;
    }
    word |= bit;
  }
  for (size_t j = 0; j < i; ++j) bits[entries[j].id >> 6] = 0;
  return problem.empty() ? Status::Ok() : fail(problem);
}

Status ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                std::span<const uint32_t> object_leaf, uint64_t mem_page, bool verify_checksums,
                QueryStats* stats, PinnedLeaf* out) {
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
  if (st.ok()) st = CheckLeafEntries(out->view, store_name, leaf, info, object_leaf, &out->seen);
  if (!st.ok()) out->Release();
  return st;
}

Result<PinnedLeaf> ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf,
                            const LeafInfo& info, std::span<const uint32_t> object_leaf, uint64_t mem_page,
                            bool verify_checksums, QueryStats* stats) {
  PinnedLeaf out;
  MKTREE_RETURN_IF_ERROR(
      ReadLeaf(cache, store_name, leaf, info, object_leaf, mem_page, verify_checksums, stats, &out));
  return out;
}

}  // namespace mktree
