// The stores a change writer adds to its folder: a delta (a batch's added and replacing objects), a merge
// of deltas, or a compaction's new base. Each is an ordinary store built by the same ingest as
// `mktree build` (same page size, codec and frame as the base), its objects numbered 0..n-1 in increasing
// global id, and an id file mapping them back (engine/revision/revision_manifest.h).
// Thread safety: free functions and a single-threaded stream.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "engine/ingest/store_builder.h"
#include "engine/query/revision_database.h"
#include "engine/revision/revision_manifest.h"
#include "mktree/scene.h"
#include "mktree/status.h"
#include "storage/file_ops.h"

namespace mktree {

// The objects of a part, in strictly increasing global id (SceneObject::id is the global id).
using IdOrderedObjects = std::function<Result<bool>(SceneObject* next)>;

struct PartBuild {
  std::string folder;  // the changes folder
  std::string name;    // "<name>.mkt" and "<name>.ids" are written there
  uint64_t history = 0;
  uint64_t made_at = 0;
  bool identity_ids = false;  // no id file when the ids are 0..n-1 (a base without gaps)
  IngestOptions ingest;       // the base's store options and frame
};

// Builds the part; its files are durable when it returns. Errors name the object (its global id) or the
// file. Nothing is left behind on an error.
Result<RevisionPart> BuildRevisionPart(const PartBuild& build, const IdOrderedObjects& objects);

// The live objects of `parts` (those not hidden) in increasing global id, read from their stores: world
// coordinates, name, source and attributes as stored. Records are read in id order (a group decoded once).
// Geometry: parts from `spill_from` on (deltas, whose ids are scattered over space) are first read leaf by
// leaf into an unnamed scratch file in `scratch_dir` (8 bytes an object in RAM for where each one went),
// so that each leaf is read once whatever the id order; the parts before it (a base, whose ids follow
// space as most scenes' do) are read in id order with the 16 leaves last parsed kept pinned.
class LiveObjectStream {
 public:
  // The scratch file's writes and reads go through `ops` (it must outlive the stream).
  LiveObjectStream(const std::vector<const RevisionPartDb*>& parts, size_t spill_from,
                   std::string scratch_dir, FileOps& ops = DefaultFileOps());
  ~LiveObjectStream();
  Result<bool> Next(SceneObject* out);
  // From the first live object again; the deltas' scratch files are kept (not read again from their stores).
  void Rewind();
  // Objects whose stored record box (world coordinates, rounded outward to float32 in the store's frame)
  // `keep` rejects, given a slack that covers that rounding and the decoded vertices', are skipped without
  // decoding their geometry. Null: every live object.
  using RecordFilter = std::function<bool(const Box3d& record_box, double slack)>;
  void SetFilter(RecordFilter keep) { filter_ = std::move(keep); }
  // For a build in the frame `origin` under `dictionary` (null: none) that copies stored entries
  // (IngestOptions::copy_stored_entries): each object whose entry is valid there (its part has that frame,
  // and the entry needs no dictionary or its part's is the same) comes as that entry
  // (SceneObject::stored_entry, an empty mesh), not decoded. Call before the first Next.
  void CopyEntriesFor(const CodecDictionary* dictionary, const Vec3d& origin);

 private:
  struct Cursor;
  std::vector<std::unique_ptr<Cursor>> cursors_;
  size_t spill_from_;
  std::string scratch_dir_;
  FileOps& ops_;
  bool spilled_ = false;
  RecordFilter filter_;
};

// The world bounds an object of a LiveObjectStream is routed by: its mesh's, or for a stored entry (no
// mesh) the entry's box (float32, rounded outward in the frame of `origin`) in world coordinates.
Box3d StreamedBounds(const SceneObject& o, const Vec3d& origin);

// The ingest options that build a part like the store `base`: its backend, codec and dictionary (every
// part of a changed store encodes with the base's, so that merges and compactions copy entries), page
// size, split parameters and frame.
IngestOptions PartIngestOptions(const StoreDatabase& base, unsigned threads);

}  // namespace mktree
