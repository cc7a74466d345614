// The sharded build (docs/shards.md), single process: one pass over the inputs samples the objects' boxes
// and chooses the top levels (engine/shard/top_levels.h); then each shard is an ordinary store built by
// BuildStore from the objects routed to it (one more pass over the inputs per shard, keeping the objects
// of that shard), in the scene's frame, with its id file; the manifest is written last. Shards and id files
// are built under "<name>.new" and renamed into place just before the manifest is committed, so that a
// failed build leaves neither a manifest nor a shard file of its own, and the previous sharded store at
// the path stays until the renames.
#pragma once

#include <cstdint>
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

Result<ShardedBuildReport> BuildShardedStore(const std::vector<SceneOpener>& inputs,
                                             const std::string& manifest_path, const IngestOptions& options,
                                             uint32_t shards);

}  // namespace mktree
