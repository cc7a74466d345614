// Files that appear whole or not at all. Every file mktree writes (stores, scenes, query files, exports,
// pictures) is written under one temporary name beside its target, "<target>.tmp.<pid>", made durable
// (fsync), renamed over the target, and the rename made durable (fsync of the directory). A temporary that
// is never committed is removed; the temporaries of killed writers are removed by the next writer of the
// same target (RemoveStaleTemps).
//
// AtomicFile does all of it for a writer that produces bytes. The store, whose backends create their file by
// name (HDF5 opens it itself) and which reads the file back before the rename, uses the steps one by one:
// AtomicTempPath, RemoveStaleTemps and RenameOverTarget (engine/store_format/store_file.cc).
//
// Every write, fsync and rename goes through FileOps (storage/file_ops.h), so that tests inject faults.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mktree/status.h"
#include "storage/file_ops.h"

namespace mktree {

// "<target>.tmp.<pid>".
std::string AtomicTempPath(const std::string& target);

// Removes the temporaries "<target>.tmp.<digits>" that no live writer holds: an AtomicFile holds a flock(2)
// on its temporary for as long as it lives, so only the leftovers of dead processes are removed, whatever
// their pid namespace. The store's temporaries carry no flock: the store calls this while holding its writer
// lock, which keeps every other writer of its target out. Errors are ignored (a file it cannot remove
// stays).
void RemoveStaleTemps(const std::string& target);

// The last steps of an atomic write: renames `temp` over `target`, then fsyncs their directory so that the
// rename survives a power loss. Sets *renamed to whether the rename happened. Errors:
//   rename:          IOError "<target>: rename from <temp>: <error>" (the target is untouched);
//   directory fsync: IOError "<dir>: fsync directory: <error> (<what> is in place but may not survive a
//                    power loss)".
Status RenameOverTarget(const std::string& temp, const std::string& target, FileOps& ops,
                        const std::string& what, bool* renamed);

// Thread safety: one object per thread. A second writer of the same target while one lives (in this process
// or another with the same pid) fails at Create.
class AtomicFile {
 public:
  // Removes stale temporaries of `target`, then creates and locks AtomicTempPath(target). Errors name
  // `target` (e.g. "out.ply: cannot create file: No such file or directory").
  static Result<std::unique_ptr<AtomicFile>> Create(const std::string& target,
                                                    FileOps& ops = DefaultFileOps());
  // Removes the temporary unless committed.
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  // Appends n bytes (buffered). IOError "<target>: write failed: <error>".
  Status Write(const void* data, size_t n);
  // Overwrites bytes already written (a header patched at the end). REQUIRES: offset + n <= size().
  Status WriteAt(uint64_t offset, const void* data, size_t n);
  // Bytes written so far.
  uint64_t size() const { return size_; }
  // Writes what is buffered, fsyncs, closes and renames over the target (RenameOverTarget); on failure the
  // temporary is removed and the target is untouched, except when only the directory's fsync failed: the
  // new file is then in place and the error says so. No further calls after it, whatever its outcome.
  Status Commit();

  const std::string& target() const { return target_; }
  const std::string& temp_path() const { return temp_; }

 private:
  AtomicFile(std::string target, std::string temp, int fd, FileOps& ops);
  Status Flush();
  Status PwriteAll(const void* data, size_t n, uint64_t offset);
  void Discard();  // closes and removes the temporary

  std::string target_, temp_;
  int fd_ = -1;
  FileOps* ops_;
  std::vector<uint8_t> buffer_;  // appended bytes not yet written, from offset flushed_
  uint64_t flushed_ = 0;
  uint64_t size_ = 0;
  bool done_ = false;  // committed or discarded
};

}  // namespace mktree
