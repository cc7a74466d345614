// Stage 1 of BuildStore (build_stages.h; docs/design.md §10): reads every scene source in order, numbers
// the objects from 0, chooses the store frame from the first object, trains the store's zstd dictionary on
// the first objects, encodes the objects on worker threads (object_encoder.h) and spills each object's leaf
// entry and record in id order. Only the 32-byte BuildObject of each object stays in RAM. Internal to
// engine/ingest.
//
// Thread safety: runs on the calling thread with the encoder's threads; the progress callback is called on
// the calling thread only.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "engine/ingest/build_stages.h"
#include "engine/store_format/object_codec.h"

namespace mktree {

// Where stage 1 puts its spill files and how it writes them.
struct SpillPlace {
  std::string dir;         // IngestSpillDir
  std::string stem;        // the spills are "<dir>/.<stem>.{geometry,record}-spill.XXXXXX" (spill_file.h)
  FileOps* ops = nullptr;  // null: POSIX
};

// What stage 1 produced: the spilled objects and the dictionary their entries were encoded with (null:
// none), which the store must record.
struct ReadAndSpillOutput {
  SpilledObjects spilled;
  std::shared_ptr<const CodecDictionary> dictionary;
};

// Reads `inputs` into spills at `place`. Fills report->origin, warnings, objects, triangles,
// raw_geometry_bytes, encoded_bytes, dictionary_bytes and dictionary_seconds. An empty scene is no error
// here (report->objects is 0). Errors: the sources', the encoder's and the spills' (naming the file).
Result<ReadAndSpillOutput> ReadAndSpill(const std::vector<SceneOpener>& inputs, const IngestOptions& options,
                                        const SpillPlace& place, IngestReport* report);

// The dictionary ReadAndSpill would train on `inputs` in the frame of `origin` (null: none, or a codec
// without one), trained on the same first objects: a sharded build gives shard 0's to every shard.
Result<std::shared_ptr<const CodecDictionary>> TrainBuildDictionary(const std::vector<SceneOpener>& inputs,
                                                                    const IngestOptions& options,
                                                                    const Vec3d& origin);

// Removes "<dir>/.<stem>.{geometry,record,name}-spill.XXXXXX" (the names stage 1's spills get; "name" was
// the record spill's name before format 4): spills that were still named when their build was killed
// (spill_file.h). REQUIRES: the store's writer lock.
void RemoveStaleSpills(const std::string& dir, const std::string& stem);

}  // namespace mktree
