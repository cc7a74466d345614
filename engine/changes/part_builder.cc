#include "engine/changes/part_builder.h"

#include <filesystem>
#include <limits>

#include "engine/revision/change_folder.h"
#include "engine/shard/manifest.h"

namespace mktree {

namespace {

// The stream renumbered 0, 1, 2, ... with the global ids kept aside.
class RenumberedSource final : public SceneSource {
 public:
  RenumberedSource(const IdOrderedObjects& objects, ObjectId first, std::vector<ObjectId>* ids)
      : objects_(objects), next_(first), ids_(ids) {}
  Result<bool> Next(SceneObject* out) override {
    MKTREE_ASSIGN_OR_RETURN(const bool more, objects_(out));
    if (!more) return false;
    if (!ids_->empty() && out->id <= ids_->back())
      return Status::Internal("object " + std::to_string(out->id) + ": part objects out of id order");
    ids_->push_back(out->id);
    out->id = next_++;
    return true;
  }

 private:
  const IdOrderedObjects& objects_;
  ObjectId next_;
  std::vector<ObjectId>* ids_;
};

}  // namespace

Result<RevisionPart> BuildRevisionPart(const PartBuild& b, const IdOrderedObjects& objects) {
  const std::string store_path = ChangesFile(b.folder, b.name + ".mkt");
  const std::string ids_path = ChangesFile(b.folder, b.name + ".ids");
  struct Discard {
    const std::string &store, &ids;
    bool keep = false;
    ~Discard() {
      if (keep) return;
      std::error_code ec;
      std::filesystem::remove(store, ec);
      std::filesystem::remove(ids, ec);
    }
  } discard{store_path, ids_path};
  std::vector<ObjectId> ids;
  const SceneOpener opener = [&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    ids.clear();
    return std::unique_ptr<SceneSource>(std::make_unique<RenumberedSource>(objects, first, &ids));
  };
  MKTREE_ASSIGN_OR_RETURN(const IngestReport report, BuildStore({opener}, store_path, b.ingest));
  if (ids.size() != report.objects)
    return Status::Internal(store_path + ": id count differs from the store's");
  RevisionPart part;
  part.made_at = b.made_at;
  part.objects = ids.size();
  MKTREE_ASSIGN_OR_RETURN(part.store, FingerprintFile(store_path));
  bool identity = b.identity_ids;
  for (size_t i = 0; identity && i < ids.size(); ++i) identity = ids[i] == i;
  if (!identity) {
    MKTREE_RETURN_IF_ERROR(
        WriteShardIds(ids_path, b.history, static_cast<uint32_t>(b.made_at), ids,
                      b.ingest.store.file_ops ? *b.ingest.store.file_ops : DefaultFileOps()));
    MKTREE_ASSIGN_OR_RETURN(part.ids, FingerprintFile(ids_path));
  }
  discard.keep = true;
  return part;
}

LiveObjectStream::LiveObjectStream(const std::vector<const RevisionPartDb*>& parts)
    : parts_(parts), cursor_(parts.size(), 0) {}

Result<bool> LiveObjectStream::Next(SceneObject* out) {
  size_t best = parts_.size();
  ObjectId best_id = std::numeric_limits<ObjectId>::max();
  for (size_t p = 0; p < parts_.size(); ++p) {
    const RevisionPartDb& part = *parts_[p];
    uint64_t& c = cursor_[p];
    while (c < part.hidden.size() && part.hidden[c]) ++c;
    if (c >= part.hidden.size()) continue;
    const ObjectId id = part.global(static_cast<ObjectId>(c));
    if (best == parts_.size() || id < best_id) {
      best = p;
      best_id = id;
    }
  }
  if (best == parts_.size()) return false;
  const RevisionPartDb& part = *parts_[best];
  const ObjectId local = static_cast<ObjectId>(cursor_[best]++);
  MKTREE_ASSIGN_OR_RETURN(ObjectRecord record, part.db->Object(local));
  MKTREE_ASSIGN_OR_RETURN(Mesh mesh, part.db->ObjectGeometry(local));
  out->id = best_id;
  out->name = std::move(record.name);
  out->source = std::move(record.source);
  out->attributes = std::move(record.attributes);
  out->mesh = std::move(mesh);
  return true;
}

IngestOptions PartIngestOptions(const StoreDatabase& base, unsigned threads) {
  IngestOptions o;
  o.store = base.reader().options();
  o.store.codec.dictionary.reset();
  o.store.file_ops = nullptr;
  o.store.direct_io = false;
  o.origin = base.reader().tree().origin;
  o.threads = threads;
  o.tuning.threads = static_cast<int>(threads);
  return o;
}

}  // namespace mktree
