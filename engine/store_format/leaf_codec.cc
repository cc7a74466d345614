#include "engine/store_format/leaf_codec.h"

#include <algorithm>
#include <cstring>

#include "storage/byte_io.h"
#include "storage/page_codec.h"

namespace mktree {

using storage_internal::Get;
using storage_internal::Put;

Status EncodeLeafPages(uint32_t leaf_index, const std::vector<std::span<const uint8_t>>& entries,
                       uint64_t mem_page, const std::function<Status(const uint8_t*)>& emit) {
  if (mem_page <= kPageHeaderBytes + kLeafHeaderBytes)
    return Status::InvalidArgument("page size " + std::to_string(mem_page) + " too small");
  uint64_t sum = 0;
  for (const auto& e : entries) sum += e.size();
  const uint64_t payload = LeafPayloadBytes(sum);
  const uint64_t page_count = PagesForLeaf(sum, mem_page);
  if (page_count > UINT32_MAX || entries.size() > UINT32_MAX)
    return Status::InvalidArgument("leaf " + std::to_string(leaf_index) + " too large");
  const uint64_t cap = PagePayloadCapacity(mem_page);

  uint8_t leaf_header[kLeafHeaderBytes];
  Put<uint32_t>(leaf_header + 0, static_cast<uint32_t>(entries.size()));
  Put<uint32_t>(leaf_header + 4, leaf_index);
  Put<uint64_t>(leaf_header + 8, payload);

  // Walk the payload pieces (leaf header, then each entry) and pour them into pages.
  std::vector<uint8_t> page(mem_page);
  size_t piece = 0;  // 0 = leaf header, i + 1 = entries[i]
  uint64_t piece_off = 0;
  auto piece_span = [&](size_t i) {
    return i == 0 ? std::span<const uint8_t>(leaf_header, kLeafHeaderBytes) : entries[i - 1];
  };
  for (uint64_t p = 0; p < page_count; ++p) {
    std::fill(page.begin(), page.end(), 0);
    const uint64_t take = std::min(cap, payload - p * cap);
    uint64_t filled = 0;
    while (filled < take) {
      const auto s = piece_span(piece);
      const uint64_t n = std::min<uint64_t>(s.size() - piece_off, take - filled);
      if (n > 0) std::memcpy(page.data() + kPageHeaderBytes + filled, s.data() + piece_off, n);
      filled += n;
      piece_off += n;
      if (piece_off == s.size()) {
        ++piece;
        piece_off = 0;
      }
    }
    PageHeader h;
    h.leaf_index = leaf_index;
    h.page_in_leaf = static_cast<uint32_t>(p);
    h.page_count = static_cast<uint32_t>(page_count);
    h.payload_bytes = static_cast<uint32_t>(take);
    SealPage(h, page.data(), mem_page);
    MKTREE_RETURN_IF_ERROR(emit(page.data()));
  }
  return Status::Ok();
}

Result<LeafView> LeafView::Parse(const std::string& store_name, uint32_t leaf_index, uint64_t first_page,
                                 const std::vector<const uint8_t*>& pages, uint64_t mem_page,
                                 bool verify_checksums) {
  LeafView v;
  MKTREE_RETURN_IF_ERROR(Parse(store_name, leaf_index, first_page, pages, mem_page, verify_checksums, &v));
  return v;
}

void LeafView::Clear() {
  leaf_index_ = 0;
  payload_bytes_ = 0;
  joined_.clear();
  entries_.clear();
}

Status LeafView::Parse(const std::string& store_name, uint32_t leaf_index, uint64_t first_page,
                       const std::vector<const uint8_t*>& pages, uint64_t mem_page, bool verify_checksums,
                       LeafView* out) {
  out->Clear();
  if (pages.empty())
    return Status::InvalidArgument(store_name + ": leaf " + std::to_string(leaf_index) + ": no pages");
  auto fail = [&](uint64_t page, const std::string& what) {
    out->Clear();  // a failed parse leaves *out empty, never half-filled
    return Status::Corruption(store_name + ": page " + std::to_string(page) + " (leaf " +
                              std::to_string(leaf_index) + "): " + what);
  };
  const uint64_t cap = PagePayloadCapacity(mem_page);
  uint64_t total = 0;
  for (size_t i = 0; i < pages.size(); ++i) {
    auto h = CheckPage(pages[i], mem_page, verify_checksums, store_name, first_page + i);
    if (!h.ok()) return h.status();
    if (h->leaf_index != leaf_index)
      return fail(first_page + i, "page belongs to leaf " + std::to_string(h->leaf_index));
    if (h->page_in_leaf != i || h->page_count != pages.size())
      return fail(first_page + i, "page " + std::to_string(h->page_in_leaf) + " of " +
                                      std::to_string(h->page_count) + " where page " + std::to_string(i) +
                                      " of " + std::to_string(pages.size()) + " was expected");
    if (i + 1 < pages.size() ? h->payload_bytes != cap : h->payload_bytes == 0)
      return fail(first_page + i, "bad payload size " + std::to_string(h->payload_bytes));
    total += h->payload_bytes;
  }

  LeafView& v = *out;
  v.leaf_index_ = leaf_index;
  const uint8_t* payload;
  if (pages.size() == 1) {
    payload = pages[0] + kPageHeaderBytes;
  } else {
    v.joined_.resize(total);
    for (size_t i = 0; i < pages.size(); ++i)
      std::memcpy(v.joined_.data() + i * cap, pages[i] + kPageHeaderBytes,
                  i + 1 < pages.size() ? cap : total - i * cap);
    payload = v.joined_.data();
  }
  if (total < kLeafHeaderBytes) return fail(first_page, "leaf header truncated");
  const uint32_t count = Get<uint32_t>(payload);
  const uint32_t stored_leaf = Get<uint32_t>(payload + 4);
  v.payload_bytes_ = Get<uint64_t>(payload + 8);
  if (stored_leaf != leaf_index)
    return fail(first_page, "leaf header names leaf " + std::to_string(stored_leaf));
  if (v.payload_bytes_ != total) return fail(first_page, "leaf payload size does not match its pages");
  // The count is not trusted for the allocation: no entry is shorter than its header.
  v.entries_.reserve(std::min<uint64_t>(count, total / kObjectEntryHeaderBytes));
  uint64_t off = kLeafHeaderBytes;
  // Each entry's size says where the next one starts, so on a page out of the CPU caches (a cache hit
  // read long ago) every entry would wait for memory in turn: keep a few lines ahead in flight.
  constexpr uint64_t kAhead = 512;
  for (uint64_t at = 0; at < std::min(kAhead, total); at += 64) __builtin_prefetch(payload + at);
  for (uint32_t i = 0; i < count; ++i) {
    __builtin_prefetch(payload + std::min(off + kAhead, total - 1));
    ObjectEntryView& e = v.entries_.emplace_back();
    Status st = ParseObjectEntry(payload + off, total - off, &e);
    if (!st.ok()) return fail(first_page + off / cap, st.message());
    off += e.entry_bytes();
  }
  if (off != total) return fail(first_page, "leaf payload has trailing bytes after its entries");
  return Status::Ok();
}

}  // namespace mktree
