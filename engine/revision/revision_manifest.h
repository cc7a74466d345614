// A revision of a store that takes changes (docs/changes.md): which stores hold its objects and which ids
// are gone. A revision is a base store (the built store, or the last compaction's) plus the delta stores
// of the changes committed since, oldest first, each an ordinary store whose local ids an id file maps to
// global ids; an object in a later part supersedes the same id in an earlier one, and a removed id is in
// no revision after its removal. Ids are never reused, so "removed" needs no revision of its own.
//
// On disk, one text file per revision, "rev-<12 digits>.rev" in the store's changes folder: one field a
// line, then "checksum <XXH3-64 of every byte before it>". It is written once (atomically) and never
// changed; the files it names are never changed either. Thread safety: plain data and free functions.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/shard/manifest.h"
#include "engine/shard/top_levels.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// Format 2 gives each delta the shard it was routed to; a revision with no routed delta is written in
// format 1, which every mktree that takes changes reads.
inline constexpr uint32_t kRevisionFormat = 2;

// A file of the changes folder, by name, with the size and fingerprint it had when committed
// (FingerprintFile: a file replaced or damaged since is refused).
using RevisionFile = ShardFileInfo;

// A store of a revision: the base or a delta.
struct RevisionPart {
  uint64_t made_at = 0;  // the revision that wrote it
  RevisionFile store;
  RevisionFile ids;  // local id -> global id (increasing); no name: local ids are the global ids
  uint64_t objects = 0;
  // A delta of a sharded store: the shard of the base whose top levels its objects route to (kNoShard: a
  // delta of a store file, or one written before changes were routed). Not for the base.
  uint32_t shard = kNoShard;
};

// An id file of the folder kept for what it lists: the ids a batch removed, or every id it touched.
struct RevisionIdList {
  uint64_t made_at = 0;
  RevisionFile file;
  uint64_t count = 0;
};

struct RevisionManifest {
  uint64_t history = 0;  // random, in every id file of the store's changes: a file of another is refused
  uint64_t revision = 0;
  int64_t time = 0;  // seconds since the epoch
  std::string message;
  uint64_t added = 0, removed = 0, replaced = 0;  // by this revision's batch
  bool compaction = false;
  uint64_t next_id = 0;  // above every id ever given
  uint64_t live = 0;     // live objects
  uint32_t keep = 8;     // revisions the store keeps (the newest manifest's setting applies)
  RevisionPart base;
  std::vector<RevisionPart> deltas;      // oldest first
  std::vector<RevisionIdList> removals;  // ids removed since the base was made
  // Ids each batch touched (added, replaced, removed), of every batch after the oldest revision kept when
  // this one was committed: what an incremental clash since a kept revision needs.
  std::vector<RevisionIdList> touched;
};

// "rev-000000000012.rev"
std::string RevisionFileName(uint64_t revision);
// The revision a file name of RevisionFileName's form names, or false.
bool ParseRevisionFileName(const std::string& name, uint64_t* revision);

std::string EncodeRevisionManifest(const RevisionManifest& m);
// `what` names the file in errors: Corruption "<what> line N: ..." for anything malformed or a checksum
// that does not match, naming the line.
Result<RevisionManifest> DecodeRevisionManifest(const std::string& text, const std::string& what);

}  // namespace mktree
