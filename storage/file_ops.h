// FileOps: the system calls that write a store or an AtomicFile (page and metadata writes, truncation,
// fsync, the commit's rename) and that write and read back the build's spill files (the object and record
// spills, the tree build's list spill, the OBJ reader's vertex spill), behind one interface so that tests
// inject faults where they happen: LevelDB's Env, reduced to what writing files needs. The default methods
// are the POSIX calls; a test subclass overrides some to fail, write short, or change bytes at chosen points
// (tests/ingest/fault_injection_test.cc, tests/ingest/spill_fault_test.cc,
// tests/storage/atomic_file_test.cc). Calls follow POSIX: -1 with errno set on failure.
//
// Thread safety: calls come from several threads at once: the store writer's leaf pages and record pages
// are written by two write-behind threads into one file, and a build's spills are read by the leaf pages'
// read-ahead and the object table's thread. An override that keeps state must guard it (atomics, as the
// fault tests do). DefaultFileOps() is stateless.
#pragma once

#include <sys/types.h>
#include <sys/uio.h>

#include <cstddef>
#include <cstdint>
#include <string>

namespace mktree {

class FileOps {
 public:
  virtual ~FileOps() = default;
  virtual ssize_t Pwrite(int fd, const void* buf, size_t n, uint64_t offset);
  virtual ssize_t Pread(int fd, void* buf, size_t n, uint64_t offset);
  virtual ssize_t Preadv(int fd, const iovec* iov, int count, uint64_t offset);
  virtual int Ftruncate(int fd, uint64_t size);
  // fsync(2) of a file or, for the commit, of the directory that holds it.
  virtual int Fsync(int fd);
  virtual int Rename(const std::string& from, const std::string& to);
};

// The POSIX calls.
FileOps& DefaultFileOps();

}  // namespace mktree
