#include "engine/changes/part_builder.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <list>
#include <unordered_map>

#include "engine/revision/change_folder.h"
#include "engine/shard/manifest.h"
#include "engine/store_format/leaf_reader.h"
#include "engine/store_format/record_codec.h"
#include "storage/file_util.h"
#include "storage/page_cache.h"

namespace mktree {

namespace {

// Increasing ids as runs of consecutive ones: a compaction's ids have a gap per removed object at most, so
// the build's peak holds no 4 bytes an object for them.
class IdRuns {
 public:
  void Clear() { runs_.clear(); }
  bool Add(ObjectId id) {  // false: not above the last
    if (!runs_.empty()) {
      auto& [first, count] = runs_.back();
      const uint64_t next = uint64_t{first} + count;
      if (id < next) return false;
      if (id == next) {
        ++count;
        return true;
      }
    }
    runs_.push_back({id, 1});
    return true;
  }
  uint64_t size() const {
    uint64_t n = 0;
    for (const auto& r : runs_) n += r.second;
    return n;
  }
  bool identity() const { return runs_.empty() || (runs_.size() == 1 && runs_[0].first == 0); }
  std::vector<ObjectId> Expand() const {
    std::vector<ObjectId> ids;
    ids.reserve(size());
    for (const auto& [first, count] : runs_)
      for (uint64_t i = 0; i < count; ++i) ids.push_back(static_cast<ObjectId>(first + i));
    return ids;
  }

 private:
  std::vector<std::pair<ObjectId, uint64_t>> runs_;
};

// The stream renumbered 0, 1, 2, ... with the global ids kept aside.
class RenumberedSource final : public SceneSource {
 public:
  RenumberedSource(const IdOrderedObjects& objects, ObjectId first, IdRuns* ids)
      : objects_(objects), next_(first), ids_(ids) {}
  Result<bool> Next(SceneObject* out) override {
    MKTREE_ASSIGN_OR_RETURN(const bool more, objects_(out));
    if (!more) return false;
    if (!ids_->Add(out->id))
      return Status::Internal("object " + std::to_string(out->id) + ": part objects out of id order");
    out->id = next_++;
    return true;
  }

 private:
  const IdOrderedObjects& objects_;
  ObjectId next_;
  IdRuns* ids_;
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
  IdRuns ids;
  const SceneOpener opener = [&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    ids.Clear();
    return std::unique_ptr<SceneSource>(std::make_unique<RenumberedSource>(objects, first, &ids));
  };
  MKTREE_ASSIGN_OR_RETURN(const IngestReport report, BuildStore({opener}, store_path, b.ingest));
  if (ids.size() != report.objects)
    return Status::Internal(store_path + ": id count differs from the store's");
  RevisionPart part;
  part.made_at = b.made_at;
  part.objects = ids.size();
  MKTREE_ASSIGN_OR_RETURN(part.store, FingerprintFile(store_path));
  if (!(b.identity_ids && ids.identity())) {
    MKTREE_RETURN_IF_ERROR(
        WriteShardIds(ids_path, b.history, static_cast<uint32_t>(b.made_at), ids.Expand(),
                      b.ingest.store.file_ops ? *b.ingest.store.file_ops : DefaultFileOps()));
    MKTREE_ASSIGN_OR_RETURN(part.ids, FingerprintFile(ids_path));
  }
  discard.keep = true;
  return part;
}

// One part's place in the stream, its record cache and its recently parsed leaves.
struct LiveObjectStream::Cursor {
  static constexpr size_t kLeaves = 16;
  static constexpr size_t kRecordPages = 4;  // ids come in increasing order: each record group loads once
  struct Leaf {
    uint32_t leaf = 0;
    PinnedLeaf pinned;
    std::unordered_map<ObjectId, uint32_t> position;  // local id -> entry
  };
  explicit Cursor(const RevisionPartDb& p)
      : part(p),
        record_pages(&p.db->reader().pages(), kRecordPages),
        records(p.db->reader().record_layout(), &record_pages, true) {}

  // The leaf `leaf`, parsed; most recently used first.
  Result<const Leaf*> LeafOf(uint32_t leaf) {
    for (auto it = leaves.begin(); it != leaves.end(); ++it) {
      if (it->leaf != leaf) continue;
      leaves.splice(leaves.begin(), leaves, it);
      return &leaves.front();
    }
    MKTREE_ASSIGN_OR_RETURN(PinnedLeaf pinned, part.db->leaves().Read(leaf, nullptr));
    std::vector<uint64_t>().swap(pinned.seen);  // the read's check bits, a bit per object of the store
    Leaf l;
    l.leaf = leaf;
    l.pinned = std::move(pinned);
    const auto& entries = l.pinned.view.entries();
    for (uint32_t i = 0; i < entries.size(); ++i) l.position[entries[i].id] = i;
    leaves.push_front(std::move(l));
    if (leaves.size() > kLeaves) leaves.pop_back();
    return &leaves.front();
  }

  ~Cursor() {
    if (scratch_fd >= 0) ::close(scratch_fd);
  }

  // Every live object's mesh (or its entry, when Copies), leaf by leaf, into an unnamed file of `dir`;
  // `where` says where each went. A record: three counts (vertices, triangles, shape flags; or kEntry, the
  // entry's bytes, its shape flags), then the doubles and the triangles, or the entry.
  Status Spill(const std::string& dir, FileOps& ops) {
    MKTREE_ASSIGN_OR_RETURN(const storage_internal::UnnamedFile scratch,
                            storage_internal::OpenUnnamedFile(dir, "merge", "a merge's scratch file"));
    scratch_fd = scratch.fd;
    const StoreReader& reader = part.db->reader();
    where.assign(part.hidden.size(), kNowhere);
    std::vector<uint8_t> buf;
    uint64_t at = 0;
    auto flush = [&]() -> Status {
      MKTREE_RETURN_IF_ERROR(storage_internal::PwriteFull(scratch_fd, buf.data(), buf.size(), at, dir, ops));
      at += buf.size();
      buf.clear();
      return Status::Ok();
    };
    const Vec3d& o = reader.tree().origin;
    for (uint32_t leaf = 0; leaf < reader.tree().leaves.size(); ++leaf) {
      MKTREE_ASSIGN_OR_RETURN(PinnedLeaf pinned, part.db->leaves().Read(leaf, nullptr));
      for (const ObjectEntryView& e : pinned.view.entries()) {
        if (part.hidden[e.id]) continue;
        where[e.id] = at + buf.size();
        if (Copies(e)) {
          const uint64_t counts[3] = {kEntry, e.entry_bytes(), e.shape_flags};
          const uint8_t* c = reinterpret_cast<const uint8_t*>(counts);
          buf.insert(buf.end(), c, c + sizeof counts);
          buf.insert(buf.end(), EntryBegin(e), EntryBegin(e) + e.entry_bytes());
          if (buf.size() >= (1u << 20)) MKTREE_RETURN_IF_ERROR(flush());
          continue;
        }
        Mesh mesh;
        MKTREE_RETURN_IF_ERROR(part.db->leaves().DecodeMesh(e, &mesh));
        for (size_t v = 0; v < mesh.vertices.size(); ++v) mesh.vertices[v] += o[v % 3];
        const uint64_t counts[3] = {mesh.vertices.size(), mesh.triangles.size(), e.shape_flags};
        auto put = [&](const void* p, size_t n) {
          buf.insert(buf.end(), static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n);
        };
        put(counts, sizeof counts);
        put(mesh.vertices.data(), 8 * mesh.vertices.size());
        put(mesh.triangles.data(), 4 * mesh.triangles.size());
        if (buf.size() >= (1u << 20)) MKTREE_RETURN_IF_ERROR(flush());
      }
    }
    return flush();
  }

  Status ReadSpilled(ObjectId local, SceneObject* out) {
    const uint64_t at = where[local];
    if (at == kNowhere)
      return Status::Corruption(part.db->reader().path() + ": object " + std::to_string(local) +
                                " is in no leaf");
    uint64_t counts[3];
    const std::string& path = part.db->reader().path();
    MKTREE_RETURN_IF_ERROR(storage_internal::PreadFull(scratch_fd, counts, sizeof counts, at, path));
    out->stored_shape = static_cast<uint8_t>(counts[2]);
    if (counts[0] == kEntry) {
      out->stored_entry.resize(counts[1]);
      return storage_internal::PreadFull(scratch_fd, out->stored_entry.data(), counts[1], at + sizeof counts,
                                         path);
    }
    Mesh* mesh = &out->mesh;
    mesh->vertices.resize(counts[0]);
    mesh->triangles.resize(counts[1]);
    MKTREE_RETURN_IF_ERROR(storage_internal::PreadFull(scratch_fd, mesh->vertices.data(), 8 * counts[0],
                                                       at + sizeof counts, path));
    return storage_internal::PreadFull(scratch_fd, mesh->triangles.data(), 4 * counts[1],
                                       at + sizeof counts + 8 * counts[0], path);
  }

  Status Read(ObjectId local, SceneObject* out) {
    const StoreReader& reader = part.db->reader();
    MKTREE_ASSIGN_OR_RETURN(const StoredRecord* r, records.Get(local, nullptr));  // a group decoded once
    MKTREE_ASSIGN_OR_RETURN(out->source, reader.SourceName(*r));
    out->name = r->name;
    out->attributes = r->attributes;
    out->mesh = Mesh();
    out->stored_entry.clear();
    if (scratch_fd >= 0) return ReadSpilled(local, out);
    const uint32_t leaf = r->leaf;
    MKTREE_ASSIGN_OR_RETURN(const Leaf* l, LeafOf(leaf));
    auto at = l->position.find(local);
    if (at == l->position.end())
      return Status::Corruption(reader.path() + ": object " + std::to_string(local) +
                                ": its record puts it in leaf " + std::to_string(leaf) +
                                ", which does not hold it");
    const ObjectEntryView& entry = l->pinned.view.entry(at->second);
    out->stored_shape = entry.shape_flags;
    if (Copies(entry)) {
      const uint8_t* begin = EntryBegin(entry);
      out->stored_entry.assign(begin, begin + entry.entry_bytes());
      return Status::Ok();
    }
    MKTREE_RETURN_IF_ERROR(part.db->leaves().DecodeMesh(entry, &out->mesh));
    const Vec3d& o = reader.tree().origin;
    for (size_t v = 0; v < out->mesh.vertices.size(); ++v) out->mesh.vertices[v] += o[v % 3];
    return Status::Ok();
  }

  static constexpr uint64_t kNowhere = ~uint64_t{0};
  static constexpr uint64_t kEntry = ~uint64_t{0};  // a spilled record's first count: an entry follows
  // An entry's header is just before its geometry (ParseObjectEntry).
  static const uint8_t* EntryBegin(const ObjectEntryView& e) {
    return e.geometry.data() - kObjectEntryHeaderBytes;
  }
  const RevisionPartDb& part;
  // CopyEntriesFor: entries without a dictionary are copied when the frame is the build's, the others
  // when the dictionary is the build's too.
  bool copy_frame = false, copy_dictionary = false;
  bool Copies(const ObjectEntryView& e) const {
    return copy_frame && (e.codec != Codec::kZstdDict || copy_dictionary);
  }
  uint64_t next = 0;    // the next local id to look at
  int scratch_fd = -1;  // spilled: the meshes, and where each local id's is
  std::vector<uint64_t> where;
  PageCache record_pages;
  RecordReader records;
  std::list<Leaf> leaves;
};

LiveObjectStream::LiveObjectStream(const std::vector<const RevisionPartDb*>& parts, size_t spill_from,
                                   std::string scratch_dir, FileOps& ops)
    : spill_from_(spill_from), scratch_dir_(std::move(scratch_dir)), ops_(ops) {
  for (const RevisionPartDb* p : parts) cursors_.push_back(std::make_unique<Cursor>(*p));
}

LiveObjectStream::~LiveObjectStream() = default;

Result<bool> LiveObjectStream::Next(SceneObject* out) {
  if (!spilled_) {
    spilled_ = true;
    for (size_t p = spill_from_; p < cursors_.size(); ++p)
      MKTREE_RETURN_IF_ERROR(cursors_[p]->Spill(scratch_dir_, ops_));
  }
  for (;;) {
    Cursor* best = nullptr;
    ObjectId best_id = std::numeric_limits<ObjectId>::max();
    for (auto& c : cursors_) {
      const RevisionPartDb& part = c->part;
      while (c->next < part.hidden.size() && part.hidden[c->next]) ++c->next;
      if (c->next >= part.hidden.size()) continue;
      const ObjectId id = part.global(static_cast<ObjectId>(c->next));
      if (!best || id < best_id) {
        best = c.get();
        best_id = id;
      }
    }
    if (!best) return false;
    if (filter_) {
      const ObjectId local = static_cast<ObjectId>(best->next);
      MKTREE_ASSIGN_OR_RETURN(const StoredRecord* r, best->records.Get(local, nullptr));
      const Vec3d& o = best->part.db->reader().tree().origin;
      Box3d world;
      double largest = 1;
      for (int a = 0; a < 3; ++a) {
        world.min[a] = double{r->box.min[a]} + o[a];
        world.max[a] = double{r->box.max[a]} + o[a];
        largest = std::max({largest, std::abs(double{r->box.min[a]}), std::abs(double{r->box.max[a]})});
      }
      // The record box is rounded outward to float32 in the store's frame, and decoded vertices are
      // within a few float32 units of the input's: 2^-16 of the largest coordinate is ample.
      if (!filter_(world, largest * 0x1p-16)) {
        ++best->next;
        continue;
      }
    }
    MKTREE_RETURN_IF_ERROR(best->Read(static_cast<ObjectId>(best->next++), out));
    out->id = best_id;
    return true;
  }
}

void LiveObjectStream::CopyEntriesFor(const CodecDictionary* dictionary, const Vec3d& origin) {
  for (auto& c : cursors_) {
    const StoreReader& reader = c->part.db->reader();
    const CodecDictionary* own = reader.options().codec.dictionary.get();
    const Vec3d& o = reader.tree().origin;
    c->copy_frame = o.x == origin.x && o.y == origin.y && o.z == origin.z;
    c->copy_dictionary =
        c->copy_frame && (own && dictionary ? own->bytes() == dictionary->bytes() : own == dictionary);
  }
}

void LiveObjectStream::Rewind() {
  for (auto& c : cursors_) {
    c->next = 0;
    c->leaves.clear();
  }
}

Box3d StreamedBounds(const SceneObject& o, const Vec3d& origin) {
  if (o.stored_entry.empty()) return o.mesh.Bounds();
  ObjectEntryView e;
  if (!ParseObjectEntry(o.stored_entry.data(), o.stored_entry.size(), &e).ok()) return o.mesh.Bounds();
  Box3d b;
  for (int a = 0; a < 3; ++a) {
    b.min[a] = double{e.box.min[a]} + origin[a];
    b.max[a] = double{e.box.max[a]} + origin[a];
  }
  return b;
}

IngestOptions PartIngestOptions(const StoreDatabase& base, unsigned threads) {
  IngestOptions o;
  o.store = base.reader().options();
  o.store.codec.dictionary.reset();
  o.dictionary = base.reader().options().codec.dictionary;  // no training per part, and copyable entries
  o.store.file_ops = nullptr;
  o.store.direct_io = false;
  o.origin = base.reader().tree().origin;
  o.keep_stored_shape = true;  // a commit's own objects come with stored_shape 0 (ChangeWriter)
  o.threads = threads;
  o.tuning.threads = static_cast<int>(threads);
  return o;
}

}  // namespace mktree
