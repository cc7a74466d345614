// A temporary append-then-read file for ingest: geometry entries and names are appended while the scene
// streams in, and read back by offset once the tree is known. The file has no name (O_TMPFILE) or, where
// the filesystem refuses that, is unlinked as soon as it is created ("<dir>/<stem>.XXXXXX"), so it
// disappears with its descriptor, even when the process is killed (BuildStore removes the rare named
// leftover of a build killed between the two steps). Its writes and reads go through a FileOps
// (storage/file_ops.h), so that tests inject faults; an error names the file.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mktree/status.h"
#include "storage/file_ops.h"

namespace mktree {

class SpillFile {
 public:
  ~SpillFile();
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;

  // Creates a new spill file in `dir` named after `stem`, written and read through `ops` (which must
  // outlive it).
  static Result<std::unique_ptr<SpillFile>> Create(const std::string& dir, const std::string& stem,
                                                   FileOps& ops = DefaultFileOps());

  // Appends bytes (buffered); returns the offset they start at.
  Result<uint64_t> Append(const void* data, uint64_t size);
  // Flushes what Append buffered and frees the buffer; call before reading.
  Status Flush();
  // Reads exactly `size` bytes at `offset` (after Flush).
  Status ReadAt(uint64_t offset, uint64_t size, void* out) const;

  // One range to read: `size` bytes at `offset` into `out`.
  struct Range {
    uint64_t offset;
    uint64_t size;
    uint8_t* out;
  };
  // Reads many ranges (after Flush) with few system calls: sorted by offset, ranges whose gaps are small
  // are gathered into one preadv (the gap bytes read into a scratch buffer), so that reading a leaf's
  // scattered entries costs about one call per run of nearby entries rather than one per entry.
  // Sorts `ranges` in place.
  Status ReadMany(std::vector<Range>* ranges) const;
  uint64_t size() const { return size_; }
  const std::string& path() const { return path_; }

 private:
  SpillFile(int fd, std::string path, FileOps& ops) : fd_(fd), path_(std::move(path)), ops_(&ops) {}
  Status WriteBuffer();  // writes out what Append buffered, keeping the buffer
  int fd_ = -1;
  std::string path_;
  FileOps* ops_;
  std::vector<uint8_t> buffer_;
  uint64_t size_ = 0;     // bytes appended, buffered or not
  uint64_t flushed_ = 0;  // bytes on disk
};

// Reads a spill file front to back in large blocks (after Flush): for data spilled in the order it is
// needed, such as the object names.
class SpillCursor {
 public:
  explicit SpillCursor(const SpillFile& file) : file_(file) {}
  // Reads the next `size` bytes into `out`.
  Status Read(uint64_t size, void* out);

 private:
  const SpillFile& file_;
  std::vector<uint8_t> block_;
  uint64_t block_offset_ = 0;  // file offset of block_[0]
  size_t at_ = 0;              // next unread byte in block_
};

}  // namespace mktree
