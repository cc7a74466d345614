#include "engine/query/shard_open.h"

#include <utility>

#include "engine/query/store_database.h"
#include "engine/store_format/store_file.h"

namespace mktree {

Result<ManifestShard> OpenManifestShard(const std::string& manifest_path, const Manifest& m, uint32_t s,
                                        const OpenOptions& shard_options, uint64_t id_limit,
                                        bool keep_leaf_filter) {
  const ShardEntry& e = m.shards[s];
  const std::string store_path = ShardFilePath(manifest_path, e.store.name);
  const std::string ids_path = ShardFilePath(manifest_path, e.ids.name);
  const std::string of = " (shard " + std::to_string(s) + " of " + manifest_path + ")";
  for (const auto& [path, info] : {std::pair{store_path, e.store}, std::pair{ids_path, e.ids}}) {
    auto fp = FingerprintFile(path);
    if (!fp.ok()) return fp.status();
    if (fp->bytes != info.bytes)
      return Status::Corruption(path + ": " + std::to_string(fp->bytes) + " bytes, the manifest says " +
                                std::to_string(info.bytes) + of);
    if (fp->fingerprint != info.fingerprint)
      return Status::Corruption(path + ": not the file the manifest was built with (checksum)" + of);
  }
  ReadOptions ro;
  ro.direct_io = shard_options.direct_io;
  ro.keep_leaf_filter = keep_leaf_filter;
  MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(store_path, ro));
  if (reader->object_count() != e.objects || reader->tree().empty() ||
      !(reader->tree().nodes[0].box == e.box))
    return Status::Corruption(store_path + ": objects or bounds differ from the manifest's" + of);
  const Vec3d& o = reader->tree().origin;
  if (o.x != m.origin.x || o.y != m.origin.y || o.z != m.origin.z)
    return Status::Corruption(store_path + ": its frame is not the manifest's" + of);
  ManifestShard shard;
  MKTREE_ASSIGN_OR_RETURN(shard.ids, ReadShardIds(ids_path, m.build_id, s, id_limit ? id_limit : m.objects));
  if (shard.ids.size() != e.objects)
    return Status::Corruption(ids_path + ": " + std::to_string(shard.ids.size()) + " ids for " +
                              std::to_string(e.objects) + " objects" + of);
  shard.db = OpenStoreDatabase(std::move(reader), shard_options);
  return shard;
}

}  // namespace mktree
