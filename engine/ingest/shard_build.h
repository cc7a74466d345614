// The sharded build (docs/shards.md), single process: one pass over the inputs samples the objects' boxes
// and chooses the top levels (engine/shard/top_levels.h); then each shard is an ordinary store built by
// BuildStore from the objects routed to it (one more pass over the inputs per shard, keeping the objects
// of that shard), in the scene's frame, with its id file (every shard encodes with one zstd dictionary,
// trained on shard 0's first objects before any shard is built); the manifest is written last. Shards and id
// files are built under "<name>.new" and renamed into place just before the manifest is committed, so that a
// failed build leaves neither a manifest nor a shard file of its own, and the previous sharded store at
// the path stays until the renames.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "engine/ingest/store_builder.h"
#include "engine/shard/manifest.h"

namespace mktree {

struct ShardedBuildReport {
  Manifest manifest;
  std::vector<IngestReport> shards;
  uint64_t sample_objects = 0;
  uint64_t store_bytes = 0;  // the shard stores' and id files' bytes
  double sample_seconds = 0, total_seconds = 0;
  std::vector<std::string> warnings;
};

// The steps of BuildShardedStore, for a driver that spreads the shards over processes (tools/mpi):
// 1. One pass over the inputs: the objects whose ids `mine` accepts go into the sample (all when null);
//    the scene's object count and its first object's box are counted from every object.
struct ShardScan {
  ShardSample sample;
  uint64_t objects = 0;
  Box3d first;  // the box of object 0 (the scene's frame comes from it)
  std::vector<std::string> warnings;
};
Result<ShardScan> ScanForShards(const std::vector<SceneOpener>& inputs,
                                const std::function<bool(ObjectId)>& mine, const IngestOptions& options);
// The same over a reader's part of the scene (every object it gives is sampled; `first` is the box of the
// first object it gives, the scene's when the part starts at id 0).
Result<ShardScan> ScanPart(SceneSource* part, const IngestOptions& options);
// Every input in order as one source, numbered globally from 0 (as BuildStore numbers them).
std::unique_ptr<SceneSource> ChainInputs(const std::vector<SceneOpener>& inputs);
// The objects of `all` that route to shard `shard` of `top`, in order (`top` must outlive it), each by
// `bounds` of it (unset: its mesh's bounds).
using ObjectBounds = std::function<Box3d(const SceneObject&)>;
std::unique_ptr<SceneSource> ShardObjectsOf(std::unique_ptr<SceneSource> all, const TopLevels& top,
                                            uint32_t shard, ObjectBounds bounds = nullptr);
// 2. Shard s of m (top levels, origin and build id set) under its staging names; the entry names the
//    final files. On error nothing of it is left.
Result<ShardEntry> BuildShard(const std::vector<SceneOpener>& inputs, const std::string& manifest_path,
                              const Manifest& m, uint32_t s, const IngestOptions& options,
                              IngestReport* report);
// The same from a source of exactly shard s's objects with their global ids, increasing; `objects` may be
// called more than once (each call starts over).
using ShardObjects = std::function<Result<std::unique_ptr<SceneSource>>()>;
Result<ShardEntry> BuildShardFrom(const ShardObjects& objects, const std::string& manifest_path,
                                  const Manifest& m, uint32_t s, const IngestOptions& options,
                                  IngestReport* report);
// The dictionary every shard of m encodes with, so that the parts of the store share one (null: none): the
// one shard 0's own build would train, on its first objects in m's frame. From the inputs, or from a
// source of shard 0's objects (as BuildShardFrom's).
Result<std::shared_ptr<const CodecDictionary>> TrainShardDictionary(const std::vector<SceneOpener>& inputs,
                                                                    const Manifest& m,
                                                                    const IngestOptions& options);
Result<std::shared_ptr<const CodecDictionary>> TrainShardDictionary(const ShardObjects& shard0,
                                                                    const Manifest& m,
                                                                    const IngestOptions& options);
// 3. Shard s's staged files renamed into place, or removed.
Status PublishShard(const std::string& manifest_path, uint32_t s);
void DiscardShard(const std::string& manifest_path, uint32_t s);
// The lock of a sharded build of one manifest path, held for the whole build (in mktree-mpi by rank 0): an
// flock(2) on "<manifest>.build-lock", which the kernel drops when the holder dies; the file is removed on
// release. Acquire fails with IOError naming the manifest while a live build holds it.
class ShardBuildLock {
 public:
  static Result<std::unique_ptr<ShardBuildLock>> Acquire(const std::string& manifest_path);
  ~ShardBuildLock();
  ShardBuildLock(const ShardBuildLock&) = delete;
  ShardBuildLock& operator=(const ShardBuildLock&) = delete;

 private:
  ShardBuildLock(std::string path, int fd) : path_(std::move(path)), fd_(fd) {}
  std::string path_;
  int fd_;
};
// With the lock held, so that they can only be a dead build's: removes the staging files killed builds of
// manifest_path left, "<manifest>.shard-N.mkt.new" and ".ids.new", their temporaries (".tmp.PID") and
// store locks (".lock"), and exchanged objects "<manifest>.shard-N.mkt.from-R.new". Regular files only
// (and links); returns how many it removed.
size_t RemoveShardLeftovers(const std::string& manifest_path);
// Any 64-bit value that differs between builds.
uint64_t NewBuildId();

Result<ShardedBuildReport> BuildShardedStore(const std::vector<SceneOpener>& inputs,
                                             const std::string& manifest_path, const IngestOptions& options,
                                             uint32_t shards);

}  // namespace mktree
