// The encoding half of ingest, a pipeline of three stages on their own threads: the calling thread reads
// objects into batches, one worker per core computes each object's edge check (CheckEdges) and leaf entry
// (EncodeObjectEntry), and a drain thread hands the results to the sink in input order, so the spill is
// written in id order exactly as a single-threaded loop would write it.
//
// Memory stays bounded: a fixed pool of batches circulates (each closes at kBatchObjects objects or
// kBatchRawBytes of raw geometry), and the reader waits when none is free.
#pragma once

#include <cstdint>
#include <functional>
#include <span>

#include "engine/store_format/object_codec.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// What the encoder learnt of one object.
struct EncodedObject {
  Box3f box;                       // the entry's AABB, in the store frame
  std::span<const uint8_t> entry;  // the leaf entry; valid only during the sink call
};

struct EncoderOptions {
  CodecOptions codec;
  // Encoding threads: 1 runs every stage on the calling thread (no other thread); n > 1 starts n
  // encoders and a drain thread besides the reading caller; 0 means one per core.
  uint32_t threads = 0;
  Vec3d origin;                    // the store frame's origin (engine/store_format/object_codec.h)
  bool keep_stored_shape = false;  // IngestOptions::keep_stored_shape
  // IngestOptions::copy_stored_entries: an object's stored entry is copied under its id, not encoded.
  bool copy_stored_entries = false;
};

// Fills *obj with the next object; false at the end of the input. Called on the calling thread only.
using ObjectReader = std::function<Result<bool>(SceneObject* obj)>;
// Receives each object with its encoding, in the order read. Called on one thread at a time (with more
// than one thread, a drain thread that runs while `read` runs on the calling thread: the two must not
// share unguarded state); every call has returned when EncodeObjects returns.
using EncodedSink = std::function<Status(const SceneObject& obj, const EncodedObject& encoded)>;

// Reads every object, encodes it and passes it to `sink`, in order. Stops at the first error, which is
// the one a sequential loop would meet first (an object's encoding error before a later read error).
// Errors: InvalidArgument for an object EncodeObjectEntry refuses (no vertices, non-finite or out-of-range
// coordinates, geometry over 4 GiB); otherwise what `read` or `sink` returned.
Status EncodeObjects(const EncoderOptions& options, const ObjectReader& read, const EncodedSink& sink);

// The number of threads EncodeObjects uses for options.threads (0 -> the number of cores).
uint32_t EncoderThreads(uint32_t requested);

}  // namespace mktree
