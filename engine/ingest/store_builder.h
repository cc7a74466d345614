// Ingest: streams scene objects into a finished store with bounded memory (docs/design.md §10).
//
// Each object's edge check (closed? even edge use?) is computed here once and stored in its entry, so
// that exact queries do not repeat it.
// Only per-object records (BuildObject: id, AABB, entry size; 32 bytes) and the tree stay
// in RAM. Each object is encoded once, alone (so leaf sizes are exact), and appended to a spill file;
// records (box, source, name, attributes) go to a second spill file. Once the tree is known, leaf pages are
// assembled from the spill in leaf order, the object table and record pages are streamed from the record
// spill, and the store is committed atomically
// (temporary name, fsync, rename). On any error the temporary store and the spill files are removed.
// The store's writer (and with it the writer lock, docs/cli.md) is taken before anything else: a second
// build of the same store fails at once, and the leftovers of killed builds are removed before this one
// writes. The build runs as named stages (read and spill, the tree, the leaf pages, the records):
// build_stages.h.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/scene/scene_source.h"
#include "engine/store_format/store_file.h"
#include "engine/tree/mktree_builder.h"
#include "engine/tree/tree_stats.h"
#include "mktree/status.h"

namespace mktree {

// Opens one input, numbering its objects from `first_id` (several inputs continue one numbering).
using SceneOpener = std::function<Result<std::unique_ptr<SceneSource>>(ObjectId first_id)>;

enum class IngestStage { kRead, kBuildTree, kWritePages, kWriteTable };
const char* IngestStageName(IngestStage stage);

// Called now and then during each stage; `total` is 0 when unknown (reading a stream).
using IngestProgress = std::function<void(IngestStage stage, uint64_t done, uint64_t total)>;

struct IngestOptions {
  StoreOptions store;     // backend, codec, build parameters
  BuildTuning tuning;     // tree quality knobs that are not persisted (split policy, threads)
  std::string spill_dir;  // where the spill files go; empty: next to the output store
  uint32_t threads =
      0;  // threads encoding objects (edge check, codec), the caller's included; 0: one per core
  IngestProgress progress;  // optional
  // What the inputs are called in errors that concern the input as a whole (an empty scene); empty: the
  // error names the store.
  std::string input_name;
  // The store frame's origin; unset: ChooseStoreOrigin of the first object. The shards of a sharded store
  // share the scene's frame, so that their float32 boxes are the unsharded store's.
  std::optional<Vec3d> origin;
  // The spill files' writes and reads (the object and record spills; the tree build's list spill unless
  // tuning.spill_file_ops is set); null: POSIX. Tests inject faults through it (storage/file_ops.h); it
  // must outlive the build. The store's own writes go through store.file_ops.
  FileOps* spill_file_ops = nullptr;
  // The objects are a store's, re-encoded (a merge of changes, a compaction): SceneObject::stored_shape,
  // when known, is their shape, as judged on the input they were first stored from.
  bool keep_stored_shape = false;
  // The dictionary to encode with, which the store keeps, instead of one trained on the input (a null one
  // inside: none). The parts of a changed store share their base's, so that a merge or a compaction can
  // copy their entries.
  std::optional<std::shared_ptr<const CodecDictionary>> dictionary;
  // A merge of changes or a compaction: an object that carries its stored leaf entry
  // (SceneObject::stored_entry), encoded in this build's frame (`origin`, required) under `dictionary`
  // (required), is copied with its id patched, not encoded again. Off: stored entries are ignored.
  bool copy_stored_entries = false;
  // Called once every input object is spilled, before the tree is built: a compaction closes the stores
  // it read from there, so that the build's peak (the tree) does not hold them too. Unset: nothing.
  std::function<void()> after_read;
  // How many objects the inputs hold, when the caller knows (a compaction): their records' array is sized
  // once, not grown by doubling (which holds the old array beside the new one). 0: unknown.
  uint64_t expected_objects = 0;
};

struct IngestReport {
  uint64_t objects = 0;
  Vec3d origin;                       // the store frame's origin (ChooseStoreOrigin)
  std::vector<std::string> warnings;  // the readers' and the build's, one line each
  uint64_t triangles = 0;
  uint64_t raw_geometry_bytes = 0;  // Mesh::RawGeometryBytes summed
  uint64_t encoded_bytes = 0;       // leaf entry bytes summed (after the codec)
  uint64_t dictionary_bytes = 0;    // the store's zstd dictionary (0: none, object_codec.h)
  double dictionary_seconds = 0;    // reading ahead the sample and training it
  uint64_t pages = 0;
  uint64_t store_bytes = 0;  // size of the finished file
  double read_seconds = 0, build_seconds = 0, write_seconds = 0, total_seconds = 0;
  TreeStats tree_stats;
};

// The store frame's origin for a scene whose first object has bounds `first`: per axis 0 while the
// object's centre lies within 2^16 of 0 (float32's spacing there is at most 2^-7 of a unit, and scenes
// modelled near 0 keep their coordinates), otherwise the centre rounded to an integer. Boxes are
// kept in float32 relative to it, so UTM-sized coordinates keep float32's precision of the scene's
// extent, not of its distance from 0; vertices are in each object's local frame regardless.
Vec3d ChooseStoreOrigin(const Box3d& first);

// Where a build of `store_path` puts its spill files: `requested` (IngestOptions::spill_dir), or else the
// store's folder.
std::string IngestSpillDir(const std::string& store_path, const std::string& requested);

// Reads every input in order, builds the MKtree and writes the store at `store_path`.
// An empty scene (no object with geometry) is an InvalidArgument error; nothing is left behind.
Result<IngestReport> BuildStore(const std::vector<SceneOpener>& inputs, const std::string& store_path,
                                const IngestOptions& options);

}  // namespace mktree
