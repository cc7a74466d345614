// The page header: every leaf page of a store is exactly MemPage bytes, a 32-byte header (this file)
// followed by a slice of one leaf's payload and zero padding. The header binds the page to its leaf
// and position, and an XXH3-64 checksum covers every byte of the page, padding included.
//
//   offset size field
//   0      4    magic "MKPG"
//   4      2    format version (kPageFormatVersion)
//   6      2    reserved, 0
//   8      4    leaf index
//   12     4    page index within the leaf (0-based)
//   16     4    pages in the leaf
//   20     4    payload bytes carried by this page (<= MemPage - 32)
//   24     8    XXH3-64 of the page, computed with this field zeroed (see PageChecksum)
//
// Thread safety: pure functions.
#pragma once

#include <cstdint>
#include <string>

#include "mktree/status.h"
#include "storage/page_format.h"

namespace mktree {

inline constexpr uint32_t kPageMagic = 0x47504b4d;        // "MKPG" little-endian: leaf pages
inline constexpr uint32_t kRecordPageMagic = 0x524f4b4d;  // "MKOR": object record pages (same header)
inline constexpr uint16_t kPageFormatVersion = 1;

struct PageHeader {
  uint32_t leaf_index = 0;
  uint32_t page_in_leaf = 0;
  uint32_t page_count = 1;
  uint32_t payload_bytes = 0;
};

// XXH3-64 over the page with the checksum field (bytes 24..31) taken as zero.
uint64_t PageChecksum(const uint8_t* page, uint64_t mem_page);

// Writes the header (magic, version, fields) and the checksum into page[0, 32). The payload must already
// be in page[32, 32 + payload_bytes) and the rest of the page zero. Record pages use the same header
// with kRecordPageMagic; their "leaf index" field holds the first object id of their group.
void SealPage(const PageHeader& h, uint8_t* page, uint64_t mem_page, uint32_t magic = kPageMagic);

// Parses and verifies a page's header (and its checksum when `verify_checksum`). `store_name` and
// `page_index` (the page's index in the store) only name the page in the error.
Result<PageHeader> CheckPage(const uint8_t* page, uint64_t mem_page, bool verify_checksum,
                             const std::string& store_name, uint64_t page_index, uint32_t magic = kPageMagic);

}  // namespace mktree
