// A paged file: a header page, then pages of page_bytes at page-aligned offsets (page i at
// (1 + i) * page_bytes), then checksummed sections back to back. PagedFileStore is its pages as a
// PageStore; WriteSections/ReadSections handle the sections, described by a table of 24-byte entries
// (offset u64, bytes u64, XXH3-64 u64) that the caller keeps in its header page. What the header and the
// sections hold is the caller's (engine/store_format/paged_file_layout.cc).
// Thread safety: as PageStore (reads with pread, from any thread).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "mktree/status.h"
#include "storage/file_ops.h"
#include "storage/file_util.h"
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
  uint64_t page_count() const override { return count_.load(std::memory_order_relaxed); }
  const std::string& name() const override { return name_; }
  Status ReadPage(uint64_t index, uint8_t* out) const override;
  Status WritePage(uint64_t index, const uint8_t* data) override { return WritePages(index, 1, data); }
  Status WritePages(uint64_t first, uint64_t count, const uint8_t* data) override;
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
  uint64_t end_of_pages() const { return (1 + page_count()) * page_bytes_; }
  // An error from close(2) is returned: some filesystems (NFS) report a deferred write error, such as a
  // full disk, only there.
  Status Close();

 private:
  std::string name_;
  int fd_;
  int direct_fd_ = -1;
  uint64_t page_bytes_;
  std::atomic<uint64_t> count_;  // written under write_mu_
  std::mutex write_mu_;          // the count and the writeback pacing, for writes from two threads
  FileOps* ops_;                 // writes (the writer's; fault injection in tests)
  storage_internal::WritebackPacer writeback_;
};

inline constexpr size_t kSectionEntryBytes = 24;

// Writes sections 0..count-1 of `fd` back to back from `offset` (encode(i) makes section i, freed once
// written) and fills their entries in `table`. Returns the offset past the last one.
Result<uint64_t> WriteSections(int fd, uint64_t offset, uint32_t count,
                               const std::function<std::vector<uint8_t>(uint32_t)>& encode, uint8_t* table,
                               const std::string& path, FileOps& ops);
// One section being read: its bytes come in order, in as many pieces as the reader asks for, each
// hashed as it is read, so that a section is decoded into its final structure without a copy of it.
class SectionReader {
 public:
  SectionReader(int fd, uint64_t offset, uint64_t bytes, const std::string& path);
  ~SectionReader();
  SectionReader(const SectionReader&) = delete;
  SectionReader& operator=(const SectionReader&) = delete;

  uint64_t bytes() const { return bytes_; }
  uint64_t left() const { return bytes_ - done_; }
  // Reads the next n bytes into dst. REQUIRES: n <= left().
  Status Read(void* dst, uint64_t n);
  // The XXH3-64 of the bytes read so far.
  uint64_t Checksum() const;

 private:
  int fd_;
  uint64_t offset_, bytes_, done_ = 0;
  const std::string& path_;
  void* state_;  // XXH3_state_t
};

// Reads the sections of `table` (one entry per name) in order: each must start where the previous one ends
// (the first at `offset`) and fit in `file_bytes`, else Corruption "<path>: <name> section out of place".
// take(i, reader) reads section i whole through `reader` (decoding it as it goes, so that open's peak is
// the structure plus a piece of a section); then its checksum must match, else Corruption "<path>: <name>
// section checksum mismatch". The bytes take sees are not yet checksummed: it must treat them as
// untrusted, and whatever it built is dropped when the checksum fails. An error from take stops the
// reading. Returns the offset past the last one.
Result<uint64_t> ReadSections(int fd, const uint8_t* table, std::span<const char* const> names,
                              uint64_t offset, uint64_t file_bytes, const std::string& path,
                              const std::function<Status(size_t i, SectionReader& reader)>& take);

}  // namespace mktree
