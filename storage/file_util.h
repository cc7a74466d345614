// POSIX file helpers that return Status and name the file (storage/ and the store files of
// engine/store_format).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mktree/status.h"
#include "storage/file_ops.h"

namespace mktree::storage_internal {

std::string ErrnoText(int err);
// Reads exactly n bytes at `offset` (retrying on EINTR and partial reads); a short read is an IOError
// that says "truncated".
Status PreadFull(int fd, void* buf, size_t n, uint64_t offset, const std::string& name,
                 FileOps& ops = DefaultFileOps());
Status PwriteFull(int fd, const void* buf, size_t n, uint64_t offset, const std::string& name,
                  FileOps& ops = DefaultFileOps());
Result<uint64_t> FileSize(int fd, const std::string& name);
// fsync of the directory holding `path`, so that a rename in it is durable.
Status SyncParentDir(const std::string& path, FileOps& ops = DefaultFileOps());
// Hands a file's newly written bytes to the kernel's writeback in runs of kBytes as a writer goes, so that
// its final fsync finds little left to write (the disk works while the writer computes). Only starts the
// writes: no wait, no durability (the fsync stays), and a failure is harmless, so none is reported.
class WritebackPacer {
 public:
  static constexpr uint64_t kBytes = uint64_t{8} << 20;
  // Call after each write of `bytes`.
  void Wrote(int fd, uint64_t bytes);

 private:
  uint64_t pending_ = 0;
};
// A scratch file that has no name, so that a killed process leaves nothing behind: O_TMPFILE in `dir`,
// or, where the filesystem refuses that, `dir`/`stem`.XXXXXX unlinked as soon as it is created.
// An empty `dir` means $TMPDIR, else /tmp. `where` names the file in errors: dir/stem.XXXXXX, the X's
// filled in when it had a name.
struct UnnamedFile {
  int fd = -1;
  std::string where;
};
// IOError "DIR: cannot create WHAT: why" when neither works.
Result<UnnamedFile> OpenUnnamedFile(const std::string& dir, const std::string& stem, const std::string& what);
// Reads up to n bytes from the start of `path`; returns how many were read. Anything but a regular file
// (a directory, FIFO, device) is InvalidArgument, without blocking.
Result<size_t> ReadPrefix(const std::string& path, void* buf, size_t n);
// The error of a store whose format version (`found`) is not the one this build reads: Unsupported,
// naming the file, the format, both versions, and what to do.
Status UnsupportedFormatVersion(const std::string& path, const std::string& format, uint32_t found,
                                uint32_t reads);

// Checks of the files a caller names, made before any work: inputs must be regular files (a FIFO would
// block the reader, a directory or device is no scene, store or query file), and an output must not be one
// of the inputs nor replace anything but a regular file.
// NotFound if `path` does not exist; InvalidArgument naming what it is if it is not a regular file (after
// symbolic links).
Status CheckInputFile(const std::string& path);
// InvalidArgument if `output` is empty, exists and is not a regular file, or is the same file as one of
// `inputs` (the same path, a hard link or a symbolic link to it). Inputs that do not exist are skipped.
Status CheckOutputFile(const std::string& output, const std::vector<std::string>& inputs);

}  // namespace mktree::storage_internal
