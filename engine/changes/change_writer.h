// The change writer (mktree/changes.h, docs/changes.md): the steps of a commit and of a compaction over a
// store's changes folder, each durable before the next, the revision file last, so that a crash at any
// point leaves the store at its last committed revision; the next writer removes what a dead one left.
// Thread safety: one thread uses a ChangeWriter; readers anywhere never wait for it.
#pragma once

#include <memory>
#include <string>

#include "mktree/changes.h"
#include "storage/file_ops.h"

namespace mktree {

// ChangeWriter::Open with every write, fsync and rename of the writer's own files (revision and id files,
// the store's relink) through `ops`; the stores it builds go through it too. Tests inject faults here.
Result<std::unique_ptr<ChangeWriter>> OpenChangeWriter(const std::string& store_path,
                                                       const ChangeOptions& options, FileOps& ops);

}  // namespace mktree
