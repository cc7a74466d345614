// Object records (docs/store_format.md, "Object record pages"): per object its AABB (float32, store
// frame), source index, name and attributes, in id order, packed into pages of MemPage bytes after the
// leaf pages. Pages carry the leaf pages' header with magic "MKOR"; its leaf-index field holds the first
// object id of the page's group. A group is one page of whole records, or the consecutive pages of one
// record too large for a page (as a big leaf spans pages). A group's payload is a count (u32), a reserved
// u32 and the records back to back. In RAM a store keeps only the directory (the first object id of each
// record page) and the sources table (the distinct input files), so a record costs a counted page read.
//
// Thread safety: RecordPager is used by one thread; RecordReader is one reader's state (one per thread);
// the free functions are pure.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "mktree/geometry.h"
#include "mktree/query_stats.h"
#include "mktree/scene.h"
#include "mktree/status.h"
#include "storage/page_cache.h"
#include "storage/page_store.h"

namespace mktree {

inline constexpr uint64_t kRecordGroupHeaderBytes = 8;  // record count u32, reserved u32
// A record's fixed part: its length u32, box 6 x f32, source u32, leaf u32, name length u32, attribute
// count u32.
inline constexpr uint64_t kRecordFixedBytes = 4 + 24 + 4 + 4 + 4 + 4;
// The leaf of a record not yet placed in one (ingest's spilled records).
inline constexpr uint32_t kRecordNoLeaf = UINT32_MAX;

// One object's record as stored (box in the store frame).
struct StoredRecord {
  Box3f box;
  uint32_t source = 0;            // index into the sources table
  uint32_t leaf = kRecordNoLeaf;  // the leaf whose entries hold the object
  std::string name;
  std::vector<ObjectAttribute> attributes;
};

// Appends one record's bytes to *out. InvalidArgument if it would exceed 4 GiB (the length is a u32).
Status EncodeRecord(const Box3f& box, uint32_t source, uint32_t leaf, std::string_view name,
                    std::span<const ObjectAttribute> attributes, std::vector<uint8_t>* out);
// A record in no leaf yet (kRecordNoLeaf).
inline Status EncodeRecord(const Box3f& box, uint32_t source, std::string_view name,
                           std::span<const ObjectAttribute> attributes, std::vector<uint8_t>* out) {
  return EncodeRecord(box, source, kRecordNoLeaf, name, attributes, out);
}
// Parses the record at data[0, n): sets *used to its bytes. Corruption (message without the file) if a
// length runs past `n` or past the record.
Status ParseRecord(const uint8_t* data, uint64_t n, uint64_t* used, StoredRecord* out);

// The sources table: count u32, then per source its length u32 and bytes.
std::vector<uint8_t> EncodeSources(const std::vector<std::string>& sources);
// Checks every length against the bytes before allocating.
Status DecodeSources(std::span<const uint8_t> in, std::vector<std::string>* sources);
// The directory: u32 per record page.
std::vector<uint8_t> EncodeRecordDirectory(const std::vector<uint32_t>& directory);
Status DecodeRecordDirectory(std::span<const uint8_t> in, std::vector<uint32_t>* directory);
// The directory is the one the writer makes for `object_count` objects: one page at least when there are
// objects, starting at id 0, non-decreasing, every id below object_count. Errors: Corruption with `what`.
Status ValidateRecordDirectory(std::span<const uint32_t> directory, uint64_t object_count,
                               const std::string& what);

// Numbers the distinct source files of a store's objects in order of first use, appending each new one to
// *names (a record carries the number). Objects come in runs from one file, so the last one is compared
// before the map is consulted (a string built and hashed per object otherwise).
class SourceIndex {
 public:
  explicit SourceIndex(std::vector<std::string>* names) : names_(names) {}
  uint32_t Of(std::string_view source) {
    if (last_ < names_->size() && (*names_)[last_] == source) return last_;
    auto [it, added] = index_.try_emplace(std::string(source), static_cast<uint32_t>(names_->size()));
    if (added) names_->emplace_back(source);
    return last_ = it->second;
  }

 private:
  std::vector<std::string>* names_;
  std::unordered_map<std::string, uint32_t> index_;
  uint32_t last_ = UINT32_MAX;
};

// Packs records into sealed pages, written in order through `write` as they fill.
class RecordPager {
 public:
  using WritePage = std::function<Status(const uint8_t* page)>;
  RecordPager(uint64_t mem_page, WritePage write) : mem_page_(mem_page), write_(std::move(write)) {}
  // Adds object `id`'s record. REQUIRES: ids 0, 1, 2, ...
  Status Add(uint32_t id, std::span<const uint8_t> record);
  // Writes the last page.
  Status Finish();
  // The first object id of each page written.
  const std::vector<uint32_t>& directory() const { return directory_; }
  std::vector<uint32_t> TakeDirectory() { return std::move(directory_); }

 private:
  Status Flush();

  uint64_t mem_page_;
  WritePage write_;
  std::vector<uint8_t> group_;  // the current group's payload (header included)
  uint32_t group_first_ = 0, group_count_ = 0;
  std::vector<uint8_t> page_;
  std::vector<uint32_t> directory_;
};

// What a reader needs to find records: the store's pages, where the record pages start, the directory.
struct RecordLayout {
  const PageStore* store = nullptr;
  std::string store_name;
  uint64_t first_page = 0;  // the page index of record page 0 (the number of leaf pages)
  std::span<const uint32_t> directory;
  uint64_t object_count = 0;
  uint64_t leaf_count = 0;  // a record naming a leaf past it is Corruption
  uint64_t mem_page = 0;
};

// Reads records group by group, keeping the last group's pages: reading ids in order reads each page
// once. Pages come through `cache` (a counted lookup each, added to the stats) or, with a null cache,
// straight from the store. Every page is checked (magic, checksum unless verified in the cache, header
// fields against the directory) and its group parsed whole before any record of it is returned.
class RecordReader {
 public:
  RecordReader(const RecordLayout& layout, PageCache* cache, bool verify_checksums)
      : layout_(layout), cache_(cache), verify_(verify_checksums) {}
  // Object `id`'s record, valid until the next call. InvalidArgument for an id past the end; Corruption
  // naming the store and the page for a damaged page.
  Result<const StoredRecord*> Get(uint32_t id, QueryStats* stats);

 private:
  Status LoadGroup(uint64_t group_page, uint64_t pages, QueryStats* stats);

  RecordLayout layout_;
  PageCache* cache_;
  bool verify_;
  bool loaded_ = false;
  uint32_t first_ = 0;  // ids [first_, first_ + records_.size()) are in records_
  std::vector<StoredRecord> records_;
  std::vector<uint8_t> payload_, page_;
};

}  // namespace mktree
