// The changes folder of a store, "<store>.changes" (docs/changes.md): the revision files, the delta and
// base stores and id files they name. What it means to read a revision and to retire one:
//   - a reader holds a revision by a shared flock(2) on its revision file for as long as it reads it;
//   - the writer retires a revision by taking that lock exclusively without waiting and unlinking the
//     file: a held revision is never retired, and a reader that locks a file just unlinked sees it is gone
//     (no link left) and treats the revision as retired.
// Thread safety: free functions; a RevisionHold is immutable once opened.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/revision/revision_manifest.h"
#include "mktree/status.h"

namespace mktree {

// "<store>.changes"
std::string ChangesFolder(const std::string& store_path);
// A file of the folder by name.
std::string ChangesFile(const std::string& folder, const std::string& name);

// The committed revisions in the folder, ascending (none when the folder does not exist).
Result<std::vector<uint64_t>> ListRevisionNumbers(const std::string& folder);

// Reads a revision file without holding it (the writer, which alone retires revisions, and `mktree log`).
Result<RevisionManifest> ReadRevisionFile(const std::string& folder, uint64_t revision);

class RevisionHold {
 public:
  // NotFound "<store>: revision R is not kept (retired, or never committed)" when it is not there.
  static Result<std::unique_ptr<RevisionHold>> Open(const std::string& folder, uint64_t revision);
  ~RevisionHold();
  RevisionHold(const RevisionHold&) = delete;
  RevisionHold& operator=(const RevisionHold&) = delete;
  const RevisionManifest& manifest() const { return manifest_; }

 private:
  RevisionHold() = default;
  int fd_ = -1;
  RevisionManifest manifest_;
};

// Retires `revision` unless a reader holds it: true when its file was removed.
Result<bool> TryRetireRevision(const std::string& folder, uint64_t revision);

// Which revision a store path opens: the store file alone (no changes folder, or one the store file was
// rebuilt over: the store matches no kept revision's base), or a held revision of its changes folder.
struct StoreRevision {
  std::unique_ptr<RevisionHold> hold;  // null: the store file alone, revision 0
};
// `revision`: the one wanted (unset: the newest). NotFound naming the store and the revision when it is not
// kept; Corruption naming the file for a damaged revision file.
Result<StoreRevision> OpenStoreRevision(const std::string& store_path, std::optional<uint64_t> revision);

// Corruption naming both files when a revision file of `revisions` is of another history (another store's,
// copied in) than `held`, revision `held_revision`'s. Files gone meanwhile (retired) are skipped.
Status CheckOneHistory(const std::string& folder, const std::vector<uint64_t>& revisions,
                       uint64_t held_revision, uint64_t held_history);

// Whether the store file is the base (same size and fingerprint) of one of the folder's revisions. Not
// being one means the store was built anew, unless the store file is the same file as a kept base (a hard
// link): then it is damaged, and this is Corruption naming it.
Result<bool> StoreFileIsAKeptBase(const std::string& store_path, const std::string& folder,
                                  const std::vector<uint64_t>& revisions);

}  // namespace mktree
