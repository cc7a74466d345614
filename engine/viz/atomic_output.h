// Output files that never appear half-written: AtomicOutputFile writes "<path>.tmp.<pid>" and renames it
// to `path` on Commit (after fsync); if it is destroyed uncommitted, the temporary file is removed.
// SpoolFile is a scratch file next to an output, unlinked as soon as it is opened (the kernel frees it
// however the process ends), for data that must be written before its size is known.
//
// Thread safety: one object per thread.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include "mktree/status.h"

namespace mktree {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

class AtomicOutputFile {
 public:
  // Errors name `path` (e.g. "out.ply: cannot write: No such file or directory").
  static Result<std::unique_ptr<AtomicOutputFile>> Create(const std::string& path);
  ~AtomicOutputFile();
  AtomicOutputFile(const AtomicOutputFile&) = delete;
  AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

  std::FILE* file() { return file_.get(); }
  // Writes n bytes; IOError naming the path on failure.
  Status Write(const void* data, size_t n);
  // Flushes, fsyncs, closes and renames onto the final path. No further calls after it.
  Status Commit();
  const std::string& path() const { return path_; }

 private:
  AtomicOutputFile(std::string path, std::string temp, FilePtr f)
      : path_(std::move(path)), temp_(std::move(temp)), file_(std::move(f)) {}
  std::string path_, temp_;
  FilePtr file_;
  bool committed_ = false;
};

// A read/write scratch file created (and at once unlinked) in the directory of `near_path`, so that big
// spools go to the output's file system rather than a possibly small /tmp.
Result<FilePtr> OpenSpoolFile(const std::string& near_path);

// Appends everything written to `spool` (from its start) to `out`; errors name `out_name`.
Status CopySpool(std::FILE* spool, std::FILE* out, const std::string& out_name);

}  // namespace mktree
