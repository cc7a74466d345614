// The byte budget of a leaf page: the one function the builder (InPage) and the leaf writer
// (engine/store_format/leaf_codec.h) agree on. A leaf payload is a leaf header followed by one entry per
// object, cut into pages (storage/page_format.h); an object's entry size (header + encoded geometry) is
// decided once, at ingest, by encoding that object alone (BuildObject::encoded_bytes), so the sum below is
// exact, never an estimate.
#pragma once

#include <cstdint>

#include "storage/page_format.h"

namespace mktree {

inline constexpr uint64_t kLeafHeaderBytes = 16;  // see engine/store_format/leaf_codec.h for its fields

// Encoded bytes of a leaf holding objects whose BuildObject::encoded_bytes add up to `sum_entry_bytes`.
inline constexpr uint64_t LeafPayloadBytes(uint64_t sum_entry_bytes) {
  return kLeafHeaderBytes + sum_entry_bytes;
}
// InPage: the leaf fits in one page.
inline constexpr bool FitsInOnePage(uint64_t sum_entry_bytes, uint64_t mem_page) {
  return LeafPayloadBytes(sum_entry_bytes) <= PagePayloadCapacity(mem_page);
}
// Pages a leaf spans (1 unless it is a single oversized object).
inline constexpr uint64_t PagesForLeaf(uint64_t sum_entry_bytes, uint64_t mem_page) {
  const uint64_t cap = PagePayloadCapacity(mem_page);
  return (LeafPayloadBytes(sum_entry_bytes) + cap - 1) / cap;
}

}  // namespace mktree
