#include "storage/page_codec.h"

#include <xxhash.h>

#include "storage/byte_io.h"

namespace mktree {

using storage_internal::Get;
using storage_internal::Put;

uint64_t PageChecksum(const uint8_t* page, uint64_t mem_page) {
  // Hash the first 24 header bytes, then use that as the seed for the rest: the same as hashing the page
  // with the checksum field skipped, without copying the page.
  const uint64_t head = XXH3_64bits(page, 24);
  return XXH3_64bits_withSeed(page + kPageHeaderBytes, mem_page - kPageHeaderBytes, head);
}

void SealPage(const PageHeader& h, uint8_t* page, uint64_t mem_page, uint32_t magic) {
  Put<uint32_t>(page + 0, magic);
  Put<uint16_t>(page + 4, kPageFormatVersion);
  Put<uint16_t>(page + 6, 0);
  Put<uint32_t>(page + 8, h.leaf_index);
  Put<uint32_t>(page + 12, h.page_in_leaf);
  Put<uint32_t>(page + 16, h.page_count);
  Put<uint32_t>(page + 20, h.payload_bytes);
  Put<uint64_t>(page + 24, PageChecksum(page, mem_page));
}

Result<PageHeader> CheckPage(const uint8_t* page, uint64_t mem_page, bool verify_checksum,
                             const std::string& store_name, uint64_t page_index, uint32_t magic) {
  auto fail = [&](const std::string& what) {
    return Status::Corruption(store_name + ": page " + std::to_string(page_index) + ": " + what);
  };
  if (Get<uint32_t>(page) != magic)
    return fail(magic == kPageMagic ? "bad page magic (not a leaf page)"
                                    : "bad page magic (not an object record page)");
  if (verify_checksum) {
    const uint64_t stored = Get<uint64_t>(page + 24);
    if (stored != PageChecksum(page, mem_page)) return fail("checksum mismatch");
  }
  const uint16_t version = Get<uint16_t>(page + 4);
  if (version != kPageFormatVersion)
    return fail("unsupported page format version " + std::to_string(version));
  PageHeader h;
  h.leaf_index = Get<uint32_t>(page + 8);
  h.page_in_leaf = Get<uint32_t>(page + 12);
  h.page_count = Get<uint32_t>(page + 16);
  h.payload_bytes = Get<uint32_t>(page + 20);
  if (h.page_count == 0 || h.page_in_leaf >= h.page_count) return fail("bad page position in leaf");
  if (h.payload_bytes > PagePayloadCapacity(mem_page)) return fail("payload larger than the page");
  return h;
}

}  // namespace mktree
