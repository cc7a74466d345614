// mktree's change API: a store takes batches of changes, each committed atomically and durably as a new
// revision, while readers keep answering the revision they opened (docs/changes.md, DESIGN.md §8).
//
//   auto w = mktree::ChangeWriter::Open("ship.mkt");           // one writer at a time, never waits
//   if (!w.ok()) { ... w.status().ToString() ... }
//   mktree::ChangeBatch batch;
//   batch.add.push_back(pump);                                 // gets a new id, never one used before
//   batch.remove.push_back(17);                                // by id
//   batch.replace.push_back(rerouted_pipe);                    // rerouted_pipe.id: the object it replaces
//   batch.message = "re-route line 7";
//   auto done = (*w)->Commit(batch);                           // all or nothing: done->revision
//
//   auto db = mktree::Database::Open("ship.mkt");              // the newest revision
//   auto old = mktree::Database::Open("ship.mkt", {.revision = 3});
//
// A store is the file given to `mktree build` plus, once it has taken a change, the folder beside it
// "<store>.changes" (revisions, the stores of changed objects, ids). Copy or move them together.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "mktree/clash.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

class Database;

// One batch: applied all or nothing as one new revision. Each object id may appear once in the whole
// batch (as removed or replaced); an unknown or removed id, a name of no live object, a replace name
// that is not unique, or an added or replacing object with no triangle, an index out of range or a
// non-finite coordinate is InvalidArgument naming it, and nothing is committed.
struct ChangeBatch {
  // New objects; ids are given at commit, above every id the store ever used, in this order.
  std::vector<SceneObject> add;
  // More new objects, after those of `add`, in order: the objects of inputs as BuildFromFiles takes them
  // (scene files, "tanker:N[:SEED]"), streamed as the commit needs them, never all in memory. They are read
  // once to check and count them before anything is written, then once to build (a sharded store: once
  // per shard they reach). A bad input is an error naming the file (and line) and nothing is committed.
  std::vector<std::string> add_files;
  // Objects removed by id, and every live object of each of these names.
  std::vector<ObjectId> remove;
  std::vector<std::string> remove_names;
  // New geometry, name, source and attributes for the object SceneObject::id, which keeps its id.
  std::vector<SceneObject> replace;
  // The same, the object replaced being the one live object of the replacing object's name.
  std::vector<SceneObject> replace_by_name;
  std::string message;  // kept in the revision's log entry
};

struct CommitReport {
  uint64_t revision = 0;
  uint64_t added = 0, removed = 0, replaced = 0;
  std::vector<ObjectId> added_ids;    // the ids of ChangeBatch::add, then of add_files, in their order
  uint64_t objects = 0;               // live objects after the commit
  bool compacted = false;             // the commit passed the threshold and compaction ran after it
  std::vector<std::string> warnings;  // the readers' of add_files, as a build reports them
  // Why that compaction failed (the commit stands; the changes stay beside the base); empty: it did not.
  std::string compaction_error;
  double seconds = 0;
};

struct CompactReport {
  uint64_t revision = 0;     // the revision compaction wrote (the same objects as the one before it)
  uint64_t objects = 0;      // live objects folded into the new base
  uint64_t folded = 0;       // change stores folded (0: nothing to do, no revision written)
  uint64_t retired = 0;      // revisions retired and files removed after it
  uint64_t bytes_freed = 0;  // of the files removed
  double seconds = 0;
};

// One kept revision of a store (ListRevisions, `mktree log`).
struct RevisionInfo {
  uint64_t revision = 0;
  int64_t time = 0;  // seconds since the Unix epoch, when it was committed
  uint64_t added = 0, removed = 0, replaced = 0;
  uint64_t objects = 0;  // live objects
  bool compaction = false;
  std::string message;
};

struct ChangeOptions {
  // Compaction runs after a commit once the changed objects kept beside the base (added and replaced,
  // and removed ids) pass this share of the live objects; 0 turns it off (Compact still works).
  double compact_threshold = 0.25;
  // Threads of the builds a commit and a compaction run (0: one per core).
  unsigned threads = 0;
};

// The one writer of a store. Open takes the store's writer lock (the one `mktree build` takes): a second
// writer, in this process or another, gets IOError at once. A writer killed at any step leaves the store
// at its last committed revision; the next Open removes what it left.
class ChangeWriter {
 public:
  static Result<std::unique_ptr<ChangeWriter>> Open(const std::string& store_path,
                                                    const ChangeOptions& options = {});
  virtual ~ChangeWriter() = default;

  virtual Result<CommitReport> Commit(const ChangeBatch& batch) = 0;
  // Folds every change into a new base store, streamed like a build; readers keep their revisions.
  virtual Result<CompactReport> Compact() = 0;
  // How many of the newest revisions the store keeps (at least 1; 8 until set); older ones are retired
  // at the next commit or compaction unless a reader holds them open.
  virtual Status SetKeep(uint32_t keep) = 0;
  virtual uint64_t revision() const = 0;  // the newest committed
};

// The kept revisions, oldest first. A store without changes has one, revision 0.
Result<std::vector<RevisionInfo>> ListRevisions(const std::string& store_path);

// Incremental clash (docs/changes.md): the pairs of `now` that were not pairs of `then`, and the pairs
// (by id) of `then` that are not pairs of `now`, found by clashing only the objects changed between the
// two revisions against the rest. `then` must be an older revision of the same store than `now`.
enum class ClashChange { kNew, kResolved };
using ClashChangeVisitor = std::function<void(const ClashPair& pair, ClashChange change)>;
Status ClashSince(const Database& now, const Database& then, const ClashOptions& options,
                  const ClashChangeVisitor& visit, ClashStats* stats);

}  // namespace mktree
