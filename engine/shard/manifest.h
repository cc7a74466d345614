// The files of a sharded store (docs/shards.md): the manifest (top levels, the scene's frame, and for each
// shard its store's and id file's names, sizes and fingerprints) and each shard's id file (the global id of
// each of the shard store's objects, in the store's id order). A shard store is an ordinary store whose
// objects are numbered 0..n-1 in global id order; the id file maps them back.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "engine/shard/top_levels.h"
#include "mktree/geometry.h"
#include "mktree/status.h"
#include "storage/file_ops.h"

namespace mktree {

inline constexpr char kManifestMagic[8] = {'M', 'K', 'T', 'S', 'H', 'A', 'R', 'D'};
inline constexpr uint32_t kManifestVersion = 1;

struct ShardFileInfo {
  std::string name;  // file name, in the manifest's directory
  uint64_t bytes = 0;
  uint64_t fingerprint = 0;  // ShardFileFingerprint
};

struct ShardEntry {
  ShardFileInfo store;  // an ordinary store (either backend)
  ShardFileInfo ids;    // its id file
  uint64_t objects = 0;
  Box3f box;  // the shard store's root box (store frame): query routing without opening the store
};

struct Manifest {
  uint64_t build_id = 0;  // in every id file of the build: a shard of another build is refused
  uint64_t objects = 0;
  Vec3d origin;  // every shard store's frame
  TopLevels top;
  std::vector<ShardEntry> shards;
};

// Whether the file starts with the manifest's magic (false when it cannot be read).
bool IsManifestFile(const std::string& path);

Status WriteManifest(const std::string& path, const Manifest& m, FileOps& ops = DefaultFileOps());
// Refuses a truncated, damaged or inconsistent manifest with Corruption naming the file.
Result<Manifest> ReadManifest(const std::string& path);

// XXH3-64 of the file's size, its first and its last 64 KiB: a store of another build (different
// metadata, checksummed in its header and trailing sections) or of another size is told apart without
// reading the whole file. IOError naming the file.
Result<ShardFileInfo> FingerprintFile(const std::string& path);

// The id file: magic, version, build id, shard, count, u32 ids (strictly increasing), XXH3-64 of it all.
Status WriteShardIds(const std::string& path, uint64_t build_id, uint32_t shard,
                     const std::vector<ObjectId>& ids, FileOps& ops = DefaultFileOps());
Result<std::vector<ObjectId>> ReadShardIds(const std::string& path, uint64_t build_id, uint32_t shard,
                                           uint64_t total_objects);
// The local id of global id `id` in a shard whose id file gave `ids` (strictly increasing), if it is there.
std::optional<ObjectId> LocalIdOf(const std::vector<ObjectId>& ids, ObjectId id);

// "<manifest>.shard-<i>.mkt" and "<manifest>.shard-<i>.ids": the shards' paths, beside the manifest.
std::string ShardStorePath(const std::string& manifest, uint32_t shard);
std::string ShardIdsPath(const std::string& manifest, uint32_t shard);
// The file `name` of a manifest entry, in the manifest's directory.
std::string ShardFilePath(const std::string& manifest, const std::string& name);

}  // namespace mktree
