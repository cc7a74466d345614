// A paged file: a header page, then pages of page_bytes at page-aligned offsets (page i at
// (1 + i) * page_bytes), then checksummed sections back to back. PagedFileStore is its pages as a
// PageStore; WriteSections/ReadSections handle the sections, described by a table of 24-byte entries
// (offset u64, bytes u64, XXH3-64 u64) that the caller keeps in its header page. What the header and the
// sections hold is the caller's (engine/store/paged_file.cc).
// Thread safety: as PageStore (reads with pread, from any thread).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "mktree/status.h"
#include "storage/file_ops.h"
#include "storage/page_store.h"

namespace mktree {

class PagedFileStore : public PageStore {
 public:
  // Creates (truncates) `path` for writing through `ops`; pages are written from index 0.
  static Result<std::unique_ptr<PagedFileStore>> Create(const std::string& path, uint64_t page_bytes,
                                                        FileOps& ops);
  PagedFileStore(std::string name, int fd, uint64_t page_bytes, uint64_t page_count,
                 FileOps& ops = DefaultFileOps());
  ~PagedFileStore() override;

  uint64_t page_bytes() const override { return page_bytes_; }
  uint64_t page_count() const override { return count_; }
  const std::string& name() const override { return name_; }
  Status ReadPage(uint64_t index, uint8_t* out) const override;
  Status WritePage(uint64_t index, const uint8_t* data) override;
  Status Sync() override;

  // Sets up the reads of a store opened for reading. With `direct_io`, pages are read with O_DIRECT where the
  // page size and the filesystem allow it; otherwise (or when they do not) with pread through the OS
  // cache. Not mapped: every page touched through a mapping would stay in the process's RSS, which then
  // grows with the pages a run reads instead of the cache's size. Returns why direct I/O was asked for and
  // is not used, or "".
  std::string StartReading(bool direct_io);

  int fd() const { return fd_; }
  FileOps& ops() const { return *ops_; }
  // The file offset just past the pages: where sections start.
  uint64_t end_of_pages() const { return (1 + count_) * page_bytes_; }
  // An error from close(2) is returned: some filesystems (NFS) report a deferred write error, such as a
  // full disk, only there.
  Status Close();

 private:
  std::string name_;
  int fd_;
  int direct_fd_ = -1;
  uint64_t page_bytes_;
  uint64_t count_;
  FileOps* ops_;  // writes (the writer's; fault injection in tests)
};

inline constexpr size_t kSectionEntryBytes = 24;

// Writes sections 0..count-1 of `fd` back to back from `offset` (encode(i) makes section i, freed once
// written) and fills their entries in `table`. Returns the offset past the last one.
Result<uint64_t> WriteSections(int fd, uint64_t offset, uint32_t count,
                               const std::function<std::vector<uint8_t>(uint32_t)>& encode, uint8_t* table,
                               const std::string& path, FileOps& ops);
// Reads the sections of `table` (one entry per name) in order, handing each to `take` as soon as it is
// read and checked, so that the caller can decode and free it before the next one is read: each must
// start where the previous one ends (the first at `offset`), fit in `file_bytes` and match its checksum;
// Corruption "<path>: <name> section out of place" or "... section checksum mismatch" otherwise. An error
// from `take` stops the reading. Returns the offset past the last one.
Result<uint64_t> ReadSections(int fd, const uint8_t* table, std::span<const char* const> names,
                              uint64_t offset, uint64_t file_bytes, const std::string& path,
                              const std::function<Status(size_t i, std::vector<uint8_t>&& bytes)>& take);

}  // namespace mktree
