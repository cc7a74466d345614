// The paged-file store layout (docs/store_format.md, engine/store_format/paged_file_layout.cc) as the
// store_open fuzz target and the seed tool need it: assembling a file with valid checksums from its parts,
// and resealing a mutated file's checksums. Checksums are not a MAC, so these are also what a crafted store
// looks like. Kept in step with engine/store_format/paged_file_layout.cc by the replay test's --min-accepted
// check on the seeds.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "engine/store_format/tree_codec.h"
#include "storage/byte_io.h"
#include "storage/page_codec.h"

namespace mktree::fuzz {

inline constexpr char kPagedMagic[8] = {'M', 'K', 'T', 'R', 'E', 'E', 'P', 'F'};
inline constexpr uint32_t kPagedVersion = 6;  // the origin (offset 304) stays 0: a frame at the world's
inline constexpr uint32_t kFixedHeaderBytes = 512;
inline constexpr uint32_t kParamsOffset = 16;
inline constexpr uint32_t kSectionCount = 9;  // nodes, split nodes, leaves, leaf id digests, record
                                              // directory, sources, stats JSON, leaf filter,
                                              // codec dictionary
inline constexpr uint32_t kSectionTableOffset = 80;
inline constexpr uint32_t kHeaderChecksumOffset = kSectionTableOffset + kSectionCount * 24;

// Structured input of the store_open target, after its mode byte: the 28-byte parameter record, then
// chunks separated by kChunkSeparator: the pages, leaf then record pages (concatenated; each page's
// checksum is recomputed),
// the nine sections in file order, and optionally query coordinates (6 doubles a query).
inline constexpr uint8_t kChunkSeparator[8] = {0xff, 'M', 'K', 'S', 'E', 'C', 'T', 0xff};
inline constexpr size_t kChunkCount = 1 + kSectionCount + 1;

inline std::vector<std::span<const uint8_t>> SplitChunks(const uint8_t* data, size_t size) {
  std::vector<std::span<const uint8_t>> chunks;
  const uint8_t* end = data + size;
  const uint8_t* at = data;
  for (;;) {
    const uint8_t* sep = std::search(at, end, std::begin(kChunkSeparator), std::end(kChunkSeparator));
    chunks.emplace_back(at, static_cast<size_t>(sep - at));
    if (sep == end) break;
    at = sep + sizeof(kChunkSeparator);
  }
  return chunks;
}

// The header page's checksum: XXH3-64 of the page with the checksum field taken as zero.
inline uint64_t HeaderPageChecksum(const uint8_t* header, uint64_t mem_page) {
  std::vector<uint8_t> copy(header, header + mem_page);
  std::memset(copy.data() + kHeaderChecksumOffset, 0, 8);
  return Checksum(copy);
}

// A paged-file store: header page, leaf and record pages (`pages` split into mem_page pieces, the last one
// padded with zeros, each given a valid page checksum), then the sections. Every checksum is valid; the
// header's object count is the sum of the leaves' object counts (the leaf records' u32 at byte 28).
inline std::vector<uint8_t> AssemblePagedFile(std::span<const uint8_t> params_record, uint64_t mem_page,
                                              std::span<const uint8_t> pages,
                                              const std::span<const uint8_t> (&sections)[kSectionCount]) {
  using storage_internal::Put;
  const uint64_t page_count = (pages.size() + mem_page - 1) / mem_page;
  std::vector<uint8_t> file((1 + page_count) * mem_page, 0);
  for (uint64_t i = 0; i < page_count; ++i) {
    uint8_t* p = file.data() + (1 + i) * mem_page;
    std::memcpy(p, pages.data() + i * mem_page, std::min<uint64_t>(mem_page, pages.size() - i * mem_page));
    Put<uint64_t>(p + 24, PageChecksum(p, mem_page));
  }
  uint8_t* h = file.data();
  std::memcpy(h, kPagedMagic, 8);
  Put<uint32_t>(h + 8, kPagedVersion);
  Put<uint32_t>(h + 12, kFixedHeaderBytes);
  std::memcpy(h + kParamsOffset, params_record.data(),
              std::min<size_t>(params_record.size(), kParamsRecordBytes));
  Put<uint64_t>(h + 48, page_count);
  uint64_t objects = 0;
  for (size_t at = 0; at + kLeafRecordBytes <= sections[2].size(); at += kLeafRecordBytes)
    objects += storage_internal::Get<uint32_t>(sections[2].data() + at + 28);
  Put<uint64_t>(h + 56, objects);
  Put<uint32_t>(h + 72, kSectionCount);
  for (uint32_t i = 0; i < kSectionCount; ++i) {
    uint8_t* e = file.data() + kSectionTableOffset + 24 * i;  // `h` may move as the file grows
    Put<uint64_t>(e, file.size());
    Put<uint64_t>(e + 8, sections[i].size());
    Put<uint64_t>(e + 16, Checksum(sections[i]));
    file.insert(file.end(), sections[i].begin(), sections[i].end());
  }
  h = file.data();
  Put<uint64_t>(h + 64, file.size());
  Put<uint64_t>(h + kHeaderChecksumOffset, HeaderPageChecksum(h, mem_page));
  return file;
}

// Recomputes, in place, every checksum of a (mutated) paged file that its own header lets us find: the
// leaf pages' (those within the file), the sections' (those within the file) and the header page's.
// Fields are left as they are, consistent or not. `max_mem_page` bounds the page size believed.
inline void ResealPagedFile(std::vector<uint8_t>* file, uint64_t max_mem_page) {
  using storage_internal::Get;
  using storage_internal::Put;
  std::vector<uint8_t>& f = *file;
  if (f.size() < kFixedHeaderBytes) return;
  const uint64_t mem_page =
      uint64_t{Get<uint32_t>(f.data() + kParamsOffset)} * Get<uint32_t>(f.data() + kParamsOffset + 4);
  if (mem_page < kFixedHeaderBytes || mem_page > max_mem_page || mem_page > f.size()) return;
  const uint64_t page_count = Get<uint64_t>(f.data() + 48);
  for (uint64_t i = 0; i < page_count && (2 + i) * mem_page <= f.size(); ++i) {
    uint8_t* p = f.data() + (1 + i) * mem_page;
    Put<uint64_t>(p + 24, PageChecksum(p, mem_page));
  }
  for (uint32_t i = 0; i < kSectionCount; ++i) {
    uint8_t* e = f.data() + kSectionTableOffset + 24 * i;
    const uint64_t off = Get<uint64_t>(e), bytes = Get<uint64_t>(e + 8);
    if (off <= f.size() && bytes <= f.size() - off)
      Put<uint64_t>(e + 16, Checksum(std::span<const uint8_t>(f.data() + off, bytes)));
  }
  Put<uint64_t>(f.data() + kHeaderChecksumOffset, HeaderPageChecksum(f.data(), mem_page));
}

}  // namespace mktree::fuzz
