// Scratch files for exports: a file next to an output, unlinked as soon as it is opened (the kernel frees it
// however the process ends), for data that must be written before its size is known (PLY faces, GLB
// buffers). The output itself is an AtomicFile (storage/atomic_file.h).
//
// Thread safety: one object per thread.
#pragma once

#include <cstdio>
#include <memory>
#include <string>

#include "mktree/status.h"
#include "storage/atomic_file.h"

namespace mktree {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

// A read/write scratch file created (and at once unlinked) in the directory of `near_path`, so that big
// spools go to the output's file system rather than a possibly small /tmp.
Result<FilePtr> OpenSpoolFile(const std::string& near_path);

// Appends everything written to `spool` (from its start) to `out`.
Status CopySpool(std::FILE* spool, AtomicFile* out);

}  // namespace mktree
