// ChangeWriter: commits, delta merges, compaction, retirement (see change_writer.h and docs/changes.md).
#include "engine/changes/change_writer.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <unordered_map>

#include "engine/changes/part_builder.h"
#include "engine/core/guarded.h"
#include "engine/ingest/caller_object_check.h"
#include "engine/ingest/scene_inputs.h"
#include "engine/ingest/shard_build.h"
#include "engine/query/ordered_batch.h"  // Prefixed
#include "engine/query/revision_database.h"
#include "engine/revision/change_folder.h"
#include "engine/shard/manifest.h"
#include "engine/shard/top_levels.h"
#include "engine/store_format/record_codec.h"
#include "engine/store_format/store_file.h"
#include "storage/atomic_file.h"
#include "storage/file_util.h"
#include "storage/page_cache.h"

namespace mktree {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Deltas are merged while the one before the newest is at most this many times its size, so that their
// sizes grow geometrically: a query visits O(log changes) of them, an object is rewritten O(log) times.
constexpr uint64_t kMergeRatio = 2;

// The writer's page cache over a revision's parts: it reads records and leaves in order (names, merges,
// compaction), so a few pages do; a reader's default would add its 48 MiB to a compaction's peak.
constexpr uint64_t kWriterCachePages = 64;

// The commit point. On an error the file is removed even when its rename was done (a failed fsync of the
// folder after it), so that an error means that nothing was committed: the writer's head stays, and its
// next commit writes this revision anew.
Status WriteRevisionFile(const std::string& folder, const RevisionManifest& m, FileOps& ops) {
  const std::string text = EncodeRevisionManifest(m);
  const std::string path = ChangesFile(folder, RevisionFileName(m.revision));
  MKTREE_ASSIGN_OR_RETURN(auto file, AtomicFile::Create(path, ops));
  Status st = file->Write(text.data(), text.size());
  if (st.ok()) st = file->Commit();
  if (!st.ok()) ::unlink(path.c_str());
  return st;
}

// Every file name a revision refers to: a sharded base's shard files too (named in its manifest).
Status NamesOf(const std::string& folder, const RevisionManifest& m, std::set<std::string>* names) {
  auto add = [&](const RevisionFile& f) {
    if (!f.name.empty()) names->insert(f.name);
  };
  add(m.base.store);
  add(m.base.ids);
  const std::string base = ChangesFile(folder, m.base.store.name);
  if (IsManifestFile(base)) {
    MKTREE_ASSIGN_OR_RETURN(const Manifest sharded, ReadManifest(base));
    for (const ShardEntry& e : sharded.shards) {
      add(e.store);
      add(e.ids);
    }
  }
  for (const RevisionPart& d : m.deltas) {
    add(d.store);
    add(d.ids);
  }
  for (const RevisionIdList& l : m.removals) add(l.file);
  for (const RevisionIdList& l : m.touched) add(l.file);
  return Status::Ok();
}

// A live object stream read as a scene (a sharded compaction's passes read it so); the stream outlives it.
class StreamSource final : public SceneSource {
 public:
  explicit StreamSource(LiveObjectStream* live) : live_(live) {}
  Result<bool> Next(SceneObject* out) override { return live_->Next(out); }

 private:
  LiveObjectStream* live_;
};

class Writer final : public ChangeWriter {
 public:
  Writer(std::string store, ChangeOptions options, FileOps& ops, std::shared_ptr<void> lock)
      : store_(std::move(store)),
        folder_(ChangesFolder(store_)),
        options_(options),
        ops_(ops),
        lock_(std::move(lock)) {}

  Status Start();
  Result<CommitReport> Commit(const ChangeBatch& batch) override {
    MKTREE_RETURN_IF_ERROR(Usable());
    return Guarded(store_, [&] { return CommitUnguarded(batch); });
  }
  Result<CompactReport> Compact() override {
    MKTREE_RETURN_IF_ERROR(Usable());
    return Guarded(store_, [&] { return CompactUnguarded(); });
  }
  Status SetKeep(uint32_t keep) override {
    if (keep < 1 || keep > 1000000) return Status::InvalidArgument("keep must be from 1 to 1000000");
    keep_ = keep;
    return Status::Ok();
  }
  uint64_t revision() const override { return head_.revision; }

 private:
  // The head's parts are open: an error while opening them again (after a commit, or after a compaction
  // that closed them to lower its peak) leaves a writer that must not go on.
  Status Usable() const {
    for (const RevisionPartDb& p : parts_)
      if (!p.db) return Status::Internal(store_ + ": this writer lost its open revision after an error");
    if (parts_.empty())
      return Status::IOError(store_ +
                             ": this writer could not open its revision again after an error: open "
                             "a new writer");
    return Status::Ok();
  }
  Status Initialize();
  Status OpenHead();
  Result<CommitReport> CommitUnguarded(const ChangeBatch& batch);
  Result<CompactReport> CompactUnguarded();
  // An added or replacing object of the batch, and the id it is written under.
  struct Written {
    ObjectId id;
    const SceneObject* object;
  };
  Status ResolveBatch(const ChangeBatch& batch, std::vector<ObjectId>* removed, std::vector<Written>* written,
                      uint64_t* replaced) const;
  // The objects of ChangeBatch::add_files, read once before anything is written: each checked, counted
  // and routed (`top`: a sharded store's top levels, else null).
  struct AddedFiles {
    std::vector<SceneOpener> openers;
    uint64_t objects = 0;
    std::map<uint32_t, uint64_t> per_shard;  // objects each delta takes (kNoShard: the one of a store file)
    std::vector<std::string> warnings;
  };
  Result<AddedFiles> ScanAddFiles(const ChangeBatch& batch, uint64_t first_id, const TopLevels* top) const;
  Result<std::unordered_map<std::string, std::vector<ObjectId>>> LiveNames(
      const std::set<std::string>& wanted) const;
  Result<RevisionIdList> WriteIdList(const std::string& name, uint64_t made_at, std::vector<ObjectId> ids);
  Status MergeDeltas(RevisionManifest* m);
  Status CommitRevision(RevisionManifest m);
  Result<std::pair<uint64_t, uint64_t>> RetireAndCollect();
  Result<RevisionPart> BuildShardedBase(uint64_t rev);
  void SkipPastUnnamedFiles();
  Status RelinkStore();
  void RemoveBuiltShardFiles();
  PartBuild Part(const std::string& name, uint64_t made_at) const {
    PartBuild b;
    b.folder = folder_;
    b.name = name;
    b.history = head_.history;
    b.made_at = made_at;
    b.ingest = base_ingest_;
    b.ingest.store.file_ops = &ops_;
    b.ingest.spill_file_ops = &ops_;
    b.ingest.input_name = "change batch";
    return b;
  }
  // A part built from stored objects (a merge, a compaction): the entries `live` gives that are valid in
  // the part (every part shares the base's frame and, since parts stopped training their own, its
  // dictionary) are copied, not decoded and encoded again.
  PartBuild CopyingPart(const std::string& name, uint64_t made_at, LiveObjectStream* live) const {
    PartBuild b = Part(name, made_at);
    b.ingest.copy_stored_entries = true;
    live->CopyEntriesFor(b.ingest.dictionary->get(), *b.ingest.origin);
    return b;
  }
  std::string NewPartName(const char* kind, uint64_t revision) {
    return std::string(kind) + "-" + std::to_string(revision) + "-" + std::to_string(++part_seq_);
  }

  std::string store_, folder_;
  bool sharded_ = false;  // the store is a sharded store's manifest
  ChangeOptions options_;
  FileOps& ops_;
  std::shared_ptr<void> lock_;
  RevisionManifest head_;
  std::vector<RevisionPartDb> parts_;  // of head_
  std::optional<uint32_t> keep_;
  uint64_t part_seq_ = 0;
  IngestOptions base_ingest_;      // how parts are built: like the head's base
  uint64_t skip_to_revision_ = 0;  // the next revision is above it (SkipPastUnnamedFiles)
};

Status Writer::Start() {
  MKTREE_RETURN_IF_ERROR(storage_internal::CheckInputFile(store_));
  sharded_ = IsManifestFile(store_);
  MKTREE_ASSIGN_OR_RETURN(std::vector<uint64_t> revisions, ListRevisionNumbers(folder_));
  bool kept = !revisions.empty();
  if (kept) {
    MKTREE_ASSIGN_OR_RETURN(kept, StoreFileIsAKeptBase(store_, folder_, revisions));
  }
  if (!kept) return Initialize();
  MKTREE_ASSIGN_OR_RETURN(head_, ReadRevisionFile(folder_, revisions.back()));
  MKTREE_RETURN_IF_ERROR(CheckOneHistory(folder_, revisions, head_.revision, head_.history));
  MKTREE_RETURN_IF_ERROR(OpenHead());
  MKTREE_RETURN_IF_ERROR(RelinkStore());  // a compaction killed between its commit and the relink
  SkipPastUnnamedFiles();
  return RetireAndCollect().status();
}

// Files of the folder that no kept revision names are a killed writer's, or a revision's whose file was lost
// (deleted by hand): either way their revision numbers and the ids their stores gave are not given again,
// so that a revision number only grows and an id is never reused. Read before they are removed.
void Writer::SkipPastUnnamedFiles() {
  std::error_code ec;
  for (fs::directory_iterator it(folder_, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    // "<kind>-<revision>-<n>.<ext>", the names NewPartName gives.
    const size_t a = name.find('-'), b = a == std::string::npos ? a : name.find('-', a + 1);
    if (b == std::string::npos) continue;
    uint64_t rev = 0;
    const auto r = std::from_chars(name.data() + a + 1, name.data() + b, rev);
    if (r.ec != std::errc() || r.ptr != name.data() + b || rev <= head_.revision) continue;
    skip_to_revision_ = std::max(skip_to_revision_, rev);
    const std::string kind = name.substr(0, a);
    if ((kind == "delta" || kind == "merged" || kind == "base") && name.ends_with(".ids")) {
      auto ids =
          ReadShardIds(it->path().string(), head_.history, static_cast<uint32_t>(rev), uint64_t{1} << 32);
      if (ids.ok() && !ids->empty())
        head_.next_id = std::max<uint64_t>(head_.next_id, uint64_t{ids->back()} + 1);
    }
  }
}

// The first change of a store: the folder, the store file linked in as the base of revision 0, and
// revision 0's file. A folder of a store rebuilt since, or one a killed writer left without any revision,
// is replaced whole.
Status Writer::Initialize() {
  // The store first: a store that does not open keeps the folder it has (nothing is set aside for it).
  uint64_t objects = 0;
  std::optional<Manifest> sharded;
  if (sharded_) {
    MKTREE_ASSIGN_OR_RETURN(sharded, ReadManifest(store_));
    objects = sharded->objects;
  } else {
    MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(store_));
    objects = reader->object_count();
  }
  std::error_code ec;
  if (fs::exists(folder_, ec)) {
    const std::string stale = folder_ + ".stale." + std::to_string(::getpid());
    fs::rename(folder_, stale, ec);
    if (ec)
      return Status::IOError(folder_ + ": cannot set aside the changes of an older store: " + ec.message());
    fs::remove_all(stale, ec);
  }
  if (!fs::create_directory(folder_, ec) && ec)
    return Status::IOError(folder_ + ": cannot create the changes folder: " + ec.message());
  RevisionManifest m;
  m.history = NewBuildId();
  m.revision = 0;
  m.time = std::time(nullptr);
  m.message = "built";
  m.next_id = m.live = objects;
  m.base.made_at = 0;
  m.base.objects = objects;
  const std::string base_name = "base-0.mkt";
  // A sharded store's shard files are linked in beside its manifest, under the names it gives them: every
  // base of the folder finds its shards beside it.
  std::vector<std::pair<std::string, std::string>> links{{store_, ChangesFile(folder_, base_name)}};
  if (sharded) {
    for (const ShardEntry& e : sharded->shards)
      for (const ShardFileInfo* f : {&e.store, &e.ids})
        links.push_back({ShardFilePath(store_, f->name), ChangesFile(folder_, f->name)});
  }
  for (const auto& [from, to] : links) {
    if (::link(from.c_str(), to.c_str()) != 0)
      return Status::IOError(to + ": cannot link " + from +
                             " into the store's changes folder: " + storage_internal::ErrnoText(errno) +
                             " (the folder must be on the store's file system)");
  }
  MKTREE_ASSIGN_OR_RETURN(m.base.store, FingerprintFile(ChangesFile(folder_, base_name)));
  MKTREE_RETURN_IF_ERROR(storage_internal::SyncParentDir(ChangesFile(folder_, base_name), ops_));
  if (Status st = storage_internal::SyncParentDir(folder_, ops_); !st.ok())
    return Status::IOError(store_ + ": making its changes folder durable: " + st.message());
  MKTREE_RETURN_IF_ERROR(WriteRevisionFile(folder_, m, ops_));
  head_ = m;
  return OpenHead();
}

Status Writer::OpenHead() {
  OpenOptions o;
  o.cache_pages = kWriterCachePages;
  std::vector<RevisionPartDb> reuse = std::move(parts_);
  parts_.clear();
  MKTREE_ASSIGN_OR_RETURN(parts_, OpenRevisionParts(store_, head_, o, &reuse, false));
  base_ingest_ = PartIngestOptions(*parts_[0].db, options_.threads);
  return Status::Ok();
}

// The live ids of each wanted name: one pass over the live objects' records.
Result<std::unordered_map<std::string, std::vector<ObjectId>>> Writer::LiveNames(
    const std::set<std::string>& wanted) const {
  std::unordered_map<std::string, std::vector<ObjectId>> out;
  if (wanted.empty()) return out;
  for (const RevisionPartDb& part : parts_) {
    // In id order through a RecordReader: each record group decoded once (ObjectName decodes one per id).
    const StoreReader& reader = part.db->reader();
    PageCache pages(&reader.pages(), kWriterCachePages);
    RecordReader records(reader.record_layout(), &pages, true);
    for (uint64_t i = 0; i < part.hidden.size(); ++i) {
      if (part.hidden[i]) continue;
      MKTREE_ASSIGN_OR_RETURN(const StoredRecord* r, records.Get(static_cast<ObjectId>(i), nullptr));
      if (wanted.count(r->name)) out[r->name].push_back(part.global(static_cast<ObjectId>(i)));
    }
  }
  return out;
}

// The batch against the head: ids removed, objects written (added with new ids, replacing with theirs),
// in increasing id. Nothing is written here.
Status Writer::ResolveBatch(const ChangeBatch& batch, std::vector<ObjectId>* removed,
                            std::vector<Written>* written, uint64_t* replaced) const {
  std::set<std::string> names(batch.remove_names.begin(), batch.remove_names.end());
  for (const SceneObject& o : batch.replace_by_name) names.insert(o.name);
  MKTREE_ASSIGN_OR_RETURN(const auto by_name, LiveNames(names));
  std::set<ObjectId> used;
  auto claim = [&](ObjectId id, const std::string& what) -> Status {
    if (!FindLive(parts_, id))
      return Status::InvalidArgument(store_ + ": " + what + ": no object " + std::to_string(id) +
                                     " at revision " + std::to_string(head_.revision) +
                                     " (removed, or never added)");
    if (!used.insert(id).second)
      return Status::InvalidArgument(store_ + ": " + what + ": object " + std::to_string(id) +
                                     " is changed twice in one batch");
    return Status::Ok();
  };
  for (ObjectId id : batch.remove) {
    MKTREE_RETURN_IF_ERROR(claim(id, "remove"));
    removed->push_back(id);
  }
  for (const std::string& name : batch.remove_names) {
    auto it = by_name.find(name);
    if (it == by_name.end())
      return Status::InvalidArgument(store_ + ": remove: no object named '" + name + "' at revision " +
                                     std::to_string(head_.revision));
    for (ObjectId id : it->second) {
      MKTREE_RETURN_IF_ERROR(claim(id, "remove '" + name + "'"));
      removed->push_back(id);
    }
  }
  auto write = [&](const SceneObject& o, ObjectId id, const std::string& what) -> Status {
    MKTREE_RETURN_IF_ERROR(CheckCallerObject(o, store_ + ": " + what));
    written->push_back({id, &o});
    return Status::Ok();
  };
  for (const SceneObject& o : batch.replace) {
    const std::string what = "replace object " + std::to_string(o.id) + " '" + o.name + "'";
    MKTREE_RETURN_IF_ERROR(claim(o.id, what));
    MKTREE_RETURN_IF_ERROR(write(o, o.id, what));
  }
  for (const SceneObject& o : batch.replace_by_name) {
    const std::string what = "replace '" + o.name + "'";
    auto it = by_name.find(o.name);
    if (it == by_name.end())
      return Status::InvalidArgument(store_ + ": " + what + ": no object of that name at revision " +
                                     std::to_string(head_.revision));
    if (it->second.size() != 1)
      return Status::InvalidArgument(store_ + ": " + what + ": " + std::to_string(it->second.size()) +
                                     " objects have that name (a replace by name needs exactly one)");
    MKTREE_RETURN_IF_ERROR(claim(it->second[0], what));
    MKTREE_RETURN_IF_ERROR(write(o, it->second[0], what));
  }
  *replaced = written->size();
  if (head_.next_id + batch.add.size() > uint64_t{1} << 32)
    return Status::InvalidArgument(store_ + ": the batch would pass 2^32 object ids");
  for (size_t i = 0; i < batch.add.size(); ++i) {
    const SceneObject& o = batch.add[i];
    MKTREE_RETURN_IF_ERROR(write(o, static_cast<ObjectId>(head_.next_id + i),
                                 "add object " + std::to_string(i) + " '" + o.name + "'"));
  }
  std::sort(written->begin(), written->end(), [](const Written& a, const Written& b) { return a.id < b.id; });
  std::sort(removed->begin(), removed->end());
  return Status::Ok();
}

Result<Writer::AddedFiles> Writer::ScanAddFiles(const ChangeBatch& batch, uint64_t first_id,
                                                const TopLevels* top) const {
  AddedFiles f;
  SceneReadOptions read;
  read.spill_dir = folder_;  // a reader's scratch file: removed by the next writer if it is left
  for (const std::string& input : batch.add_files) {
    MKTREE_ASSIGN_OR_RETURN(SceneOpener opener, OpenerForInput(input, read));
    f.openers.push_back(std::move(opener));
  }
  if (f.openers.empty()) return f;
  SceneInputs inputs(f.openers);
  SceneObject o;
  for (;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, inputs.Next(&o));
    if (!more) break;
    if (first_id + f.objects >= uint64_t{1} << 32)
      return Status::InvalidArgument(store_ + ": the batch would pass 2^32 object ids");
    MKTREE_RETURN_IF_ERROR(CheckCallerObject(o, store_ + ": add " + (o.source.empty() ? "" : o.source + " ") +
                                                    "object " + std::to_string(f.objects) + " '" + o.name +
                                                    "'"));
    ++f.per_shard[top ? top->ShardOf(o.mesh.Bounds()) : kNoShard];
    ++f.objects;
  }
  f.warnings = inputs.TakeWarnings();
  return f;
}

Result<RevisionIdList> Writer::WriteIdList(const std::string& name, uint64_t made_at,
                                           std::vector<ObjectId> ids) {
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  RevisionIdList l;
  l.made_at = made_at;
  l.count = ids.size();
  const std::string path = ChangesFile(folder_, name);
  MKTREE_RETURN_IF_ERROR(WriteShardIds(path, head_.history, static_cast<uint32_t>(made_at), ids, ops_));
  MKTREE_ASSIGN_OR_RETURN(l.file, FingerprintFile(path));
  return l;
}

Result<CommitReport> Writer::CommitUnguarded(const ChangeBatch& batch) {
  const auto start = Clock::now();
  std::vector<ObjectId> removed;
  std::vector<Written> written;
  uint64_t replaced = 0;
  MKTREE_RETURN_IF_ERROR(ResolveBatch(batch, &removed, &written, &replaced));
  // A sharded store routes each written object by its box through the base's top levels, as a build
  // routes it: one delta per shard the batch touches, so that a delta's box is its shard's (a query
  // outside it reads none of its pages) and a rank of mktree-mpi owns the deltas of its shards.
  std::optional<TopLevels> top;
  if (sharded_) {
    MKTREE_ASSIGN_OR_RETURN(Manifest base, ReadManifest(ChangesFile(folder_, head_.base.store.name)));
    top = std::move(base.top);
  }
  const uint64_t files_first = head_.next_id + batch.add.size();  // ids of add_files' objects from here
  auto scanned = ScanAddFiles(batch, files_first, top ? &*top : nullptr);
  if (!scanned.ok()) {  // a reader's error names the file and line; the store is named too
    const Status& st = scanned.status();
    if (st.message().rfind(store_ + ": ", 0) == 0) return st;
    return Prefixed(st, store_ + ": add: ");
  }
  const AddedFiles& files = *scanned;
  const uint64_t added = batch.add.size() + files.objects;
  const uint64_t rev = std::max(head_.revision, skip_to_revision_) + 1;
  RevisionManifest m = head_;
  m.revision = rev;
  m.time = std::time(nullptr);
  m.message = batch.message;
  m.compaction = false;
  m.added = added;
  m.removed = removed.size();
  m.replaced = replaced;
  m.next_id = head_.next_id + added;
  m.live = head_.live + m.added - m.removed;
  if (keep_) m.keep = *keep_;
  CommitReport report;
  report.warnings = files.warnings;
  for (uint64_t i = 0; i < added; ++i) report.added_ids.push_back(static_cast<ObjectId>(head_.next_id + i));
  std::vector<uint32_t> shard_of(written.size(), kNoShard);
  if (top)
    for (size_t i = 0; i < written.size(); ++i) shard_of[i] = top->ShardOf(written[i].object->mesh.Bounds());
  std::set<uint32_t> shards(shard_of.begin(), shard_of.end());
  for (const auto& [shard, count] : files.per_shard) shards.insert(shard);
  for (const uint32_t shard : shards) {
    // The batch's objects in increasing id: the caller's (sorted), then add_files' streamed, whose ids are
    // above every other.
    size_t at = 0;
    std::optional<SceneInputs> stream;
    uint64_t streamed = 0;  // of add_files' objects, those routed to this shard
    const auto scanned_here = files.per_shard.find(shard);
    const uint64_t routed_here = scanned_here == files.per_shard.end() ? 0 : scanned_here->second;
    IdOrderedObjects next = [&](SceneObject* out) -> Result<bool> {
      while (at < written.size() && shard_of[at] != shard) ++at;
      if (at < written.size()) {
        *out = *written[at].object;  // the one copy the build takes
        out->id = written[at++].id;
        out->stored_shape = 0;  // judged on the caller's coordinates
        out->stored_entry.clear();
        return true;
      }
      if (files.openers.empty()) return false;
      if (!stream) stream.emplace(files.openers);
      for (;;) {
        MKTREE_ASSIGN_OR_RETURN(const bool more, stream->Next(out));
        if (!more) {
          // The inputs are read twice: one that changed in between is refused, not half taken.
          if (stream->objects_read() != files.objects || streamed != routed_here)
            return Status::IOError(store_ + ": the files added changed while the commit read them");
          return false;
        }
        if (top && top->ShardOf(out->mesh.Bounds()) != shard) continue;
        ++streamed;
        out->id = static_cast<ObjectId>(files_first + stream->objects_read() - 1);
        out->stored_shape = 0;
        out->stored_entry.clear();
        return true;
      }
    };
    MKTREE_ASSIGN_OR_RETURN(RevisionPart delta,
                            BuildRevisionPart(Part(NewPartName("delta", rev), rev), next));
    delta.shard = shard;
    m.deltas.push_back(delta);
  }
  std::vector<ObjectId> touched = removed;
  for (const Written& w : written) touched.push_back(w.id);
  for (uint64_t i = 0; i < files.objects; ++i) touched.push_back(static_cast<ObjectId>(files_first + i));
  if (!removed.empty()) {
    MKTREE_ASSIGN_OR_RETURN(RevisionIdList l,
                            WriteIdList(NewPartName("removed", rev) + ".ids", rev, removed));
    m.removals.push_back(l);
  }
  if (!touched.empty()) {
    MKTREE_ASSIGN_OR_RETURN(RevisionIdList l,
                            WriteIdList(NewPartName("touched", rev) + ".ids", rev, touched));
    m.touched.push_back(l);
  }
  MKTREE_RETURN_IF_ERROR(MergeDeltas(&m));
  MKTREE_RETURN_IF_ERROR(CommitRevision(std::move(m)));
  report.revision = rev;
  report.added = added;
  report.removed = removed.size();
  report.replaced = replaced;
  report.objects = head_.live;
  uint64_t beside = 0;
  for (const RevisionPart& d : head_.deltas) beside += d.objects;
  for (const RevisionIdList& r : head_.removals) beside += r.count;
  if (options_.compact_threshold > 0 &&
      static_cast<double>(beside) >
          options_.compact_threshold * static_cast<double>(std::max<uint64_t>(head_.live, 1))) {
    // The commit is durable whatever happens here: a failed compaction is reported, not returned.
    if (head_.live == 0) {
      report.compaction_error = "not compacted: no live object";
    } else if (auto c = CompactUnguarded(); c.ok()) {
      report.compacted = c->folded > 0;
    } else {
      report.compaction_error = c.status().ToString();
    }
  }
  report.seconds = SecondsSince(start);
  return report;
}

// Merges the newest two deltas of a shard (of the store: unsharded) while the older is at most kMergeRatio
// times the newer's size; live objects only are carried over, into a delta placed last. That keeps every
// id's newest copy newest: an object the merge carries is hidden in no part after the older delta, so no
// part after the newer holds its id; one that a part between them supersedes is hidden, so not carried.
// m's parts are opened to read them.
Status Writer::MergeDeltas(RevisionManifest* m) {
  std::set<uint32_t> shards;
  for (const RevisionPart& d : m->deltas) shards.insert(d.shard);
  for (const uint32_t shard : shards) {
    for (;;) {
      std::vector<size_t> of;  // the shard's deltas, oldest first
      for (size_t i = 0; i < m->deltas.size(); ++i)
        if (m->deltas[i].shard == shard) of.push_back(i);
      if (of.size() < 2) break;
      const size_t older = of[of.size() - 2], newer = of.back();
      if (m->deltas[older].objects > kMergeRatio * m->deltas[newer].objects) break;
      OpenOptions o;
      o.cache_pages = kWriterCachePages;
      MKTREE_ASSIGN_OR_RETURN(std::vector<RevisionPartDb> parts,
                              OpenRevisionParts(store_, *m, o, &parts_, false));
      RevisionPartDb& a = parts[BasePartCount(parts) + older];
      RevisionPartDb& b = parts[BasePartCount(parts) + newer];
      LiveObjectStream live({&a, &b}, 0, folder_, ops_);
      IdOrderedObjects next = [&](SceneObject* out) { return live.Next(out); };
      const uint64_t live_count =
          a.db->object_count() - a.hidden_count + b.db->object_count() - b.hidden_count;
      m->deltas.erase(m->deltas.begin() + static_cast<ptrdiff_t>(newer));
      m->deltas.erase(m->deltas.begin() + static_cast<ptrdiff_t>(older));
      if (live_count > 0) {
        const PartBuild build = CopyingPart(NewPartName("merged", m->revision), m->revision, &live);
        MKTREE_ASSIGN_OR_RETURN(RevisionPart merged, BuildRevisionPart(build, next));
        merged.shard = shard;
        m->deltas.push_back(merged);
      }
      for (RevisionPartDb& p : parts) parts_.push_back(std::move(p));  // open stores, for the next opening
    }
  }
  return Status::Ok();
}

// The commit point: the revision file, written atomically. Then the head moves, old revisions retire and
// files no kept revision names are removed.
Status Writer::CommitRevision(RevisionManifest m) {
  MKTREE_RETURN_IF_ERROR(WriteRevisionFile(folder_, m, ops_));
  head_ = std::move(m);
  MKTREE_RETURN_IF_ERROR(OpenHead());
  return RetireAndCollect().status();
}

Result<CompactReport> Writer::CompactUnguarded() {
  const auto start = Clock::now();
  CompactReport report;
  const bool keep_changed = keep_ && *keep_ != head_.keep;
  if (head_.deltas.empty() && head_.removals.empty() && !keep_changed) {
    MKTREE_RETURN_IF_ERROR(RelinkStore());  // one that failed after the last compaction's commit
    report.revision = head_.revision;
    report.objects = head_.live;
    report.seconds = SecondsSince(start);
    return report;
  }
  const uint64_t rev = std::max(head_.revision, skip_to_revision_) + 1;
  RevisionManifest m = head_;
  m.revision = rev;
  m.time = std::time(nullptr);
  m.message = "compaction";
  m.compaction = true;
  m.added = m.removed = m.replaced = 0;
  if (keep_) m.keep = *keep_;
  if (!head_.deltas.empty() || !head_.removals.empty()) {
    if (head_.live == 0)
      return Status::Unsupported(store_ +
                                 ": compaction of a store with no live object (remove fewer, or build anew)");
    if (sharded_) {
      MKTREE_ASSIGN_OR_RETURN(m.base, BuildShardedBase(rev));
    } else {
      std::vector<const RevisionPartDb*> all;
      for (const RevisionPartDb& p : parts_) all.push_back(&p);
      std::optional<LiveObjectStream> live(std::in_place, all, BasePartCount(parts_), folder_, ops_);
      IdOrderedObjects next = [&](SceneObject* out) { return live->Next(out); };
      PartBuild b = CopyingPart(NewPartName("base", rev), rev, &*live);
      b.identity_ids = true;
      // Once every object is read, the parts are closed before the tree is built (the build's peak), which
      // then holds no more than a fresh build's; they are opened again below, or at the new head.
      b.ingest.expected_objects = head_.live;
      b.ingest.after_read = [&] {
        live.reset();
        parts_.clear();
      };
      auto built = BuildRevisionPart(b, next);
      if (!built.ok()) {
        if (parts_.empty()) (void)OpenHead();  // Usable() says so if that failed too
        return built.status();
      }
      m.base = std::move(*built);
    }
    report.folded = head_.deltas.size() + head_.removals.size();
    m.deltas.clear();
    m.removals.clear();
  }
  if (Status st = WriteRevisionFile(folder_, m, ops_); !st.ok()) {
    if (parts_.empty()) (void)OpenHead();  // closed by the build; the head is still the old revision
    return st;
  }
  head_ = std::move(m);
  MKTREE_RETURN_IF_ERROR(OpenHead());
  MKTREE_RETURN_IF_ERROR(RelinkStore());
  MKTREE_ASSIGN_OR_RETURN(const auto retired, RetireAndCollect());
  report.revision = rev;
  report.objects = head_.live;
  report.retired = retired.first;
  report.bytes_freed = retired.second;
  report.seconds = SecondsSince(start);
  return report;
}

// A sharded store's compaction: a sharded build of the live objects into the folder, as `mktree build
// --shards` would make it (top levels chosen from a sample of their boxes, the same shard count unless
// the live objects are too few to give every shard one; the base's frame), each object keeping its id.
// The manifest is written last; on an error nothing of it stays.
Result<RevisionPart> Writer::BuildShardedBase(uint64_t rev) {
  MKTREE_ASSIGN_OR_RETURN(const Manifest old, ReadManifest(ChangesFile(folder_, head_.base.store.name)));
  std::vector<const RevisionPartDb*> all;
  for (const RevisionPartDb& p : parts_) all.push_back(&p);
  const size_t spill_from = BasePartCount(parts_);
  const std::string manifest_path = ChangesFile(folder_, NewPartName("base", rev) + ".mkt");
  Manifest nm;
  nm.build_id = NewBuildId();
  nm.objects = head_.live;
  nm.origin = old.origin;
  struct Discard {
    const std::string& path;
    size_t shards = 0;
    bool keep = false;
    ~Discard() {
      if (keep) return;
      std::error_code ec;
      fs::remove(path, ec);
      for (uint32_t s = 0; s < shards; ++s) {
        DiscardShard(path, s);
        fs::remove(ShardStorePath(path, s), ec);
        fs::remove(ShardIdsPath(path, s), ec);
      }
    }
  } discard{manifest_path, old.shards.size()};
  // One stream for every pass: the deltas are read into its scratch file once. The first pass samples
  // every live object's bounds; each shard's pass then reads only the objects whose record box may
  // route to it. Entries under the shards' dictionary (shard 0's, which every part since has shared) are
  // copied, and routed by their stored box; the others (the shards of a build trained their own) are
  // decoded and encoded again, routed by their mesh's bounds: either way, the same box in every pass.
  LiveObjectStream live(all, spill_from, folder_, ops_);
  IngestOptions ingest = base_ingest_;
  ingest.copy_stored_entries = true;
  live.CopyEntriesFor(ingest.dictionary->get(), old.origin);
  const ObjectBounds bounds = [&](const SceneObject& o) { return StreamedBounds(o, old.origin); };
  {
    ShardSample sample;
    SceneObject o;
    for (;;) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, live.Next(&o));
      if (!more) break;
      sample.Add(o.id, bounds(o));
    }
    const std::vector<ShardSample::Item> items = std::move(sample).Items();
    Result<TopLevels> top = Status::Internal("no shard count tried");
    for (uint32_t k = static_cast<uint32_t>(old.shards.size()); k >= 1; k = k / 2) {
      top = ChooseTopLevels(items, k);
      if (top.ok() || k == 1) break;
    }
    if (!top.ok()) return top.status();
    nm.top = std::move(*top);
  }
  ingest.store.file_ops = &ops_;
  ingest.spill_file_ops = &ops_;
  ingest.input_name = "compaction";
  uint64_t built = 0;
  for (uint32_t s = 0; s < nm.top.shard_count; ++s) {
    live.SetFilter([&, s](const Box3d& box, double slack) { return nm.top.CanRouteTo(box, slack, s); });
    IngestReport report;
    MKTREE_ASSIGN_OR_RETURN(ShardEntry e, BuildShardFrom(
                                              [&]() -> Result<std::unique_ptr<SceneSource>> {
                                                live.Rewind();
                                                return ShardObjectsOf(std::make_unique<StreamSource>(&live),
                                                                      nm.top, s, bounds);
                                              },
                                              manifest_path, nm, s, ingest, &report));
    built += e.objects;
    nm.shards.push_back(std::move(e));
  }
  if (built != nm.objects)  // an object the record filter skipped in its own shard's pass: never commit that
    return Status::Internal(manifest_path + ": the shards hold " + std::to_string(built) + " objects of " +
                            std::to_string(nm.objects) + " live");
  for (uint32_t s = 0; s < nm.top.shard_count; ++s) MKTREE_RETURN_IF_ERROR(PublishShard(manifest_path, s));
  MKTREE_RETURN_IF_ERROR(WriteManifest(manifest_path, nm, ops_));
  RevisionPart base;
  base.made_at = rev;
  base.objects = nm.objects;
  MKTREE_ASSIGN_OR_RETURN(base.store, FingerprintFile(manifest_path));
  discard.keep = true;
  return base;
}

// The store file becomes (a hard link of) the newest base, so that the store's name holds the newest
// objects' pages and an old base's pages are freed once no kept revision names it. The temporary link has
// one name, removed first, so that the link a writer killed before its rename left is removed too (the
// writer lock keeps every other writer out).
Status Writer::RelinkStore() {
  const std::string temp = store_ + ".relink";
  ::unlink(temp.c_str());
  MKTREE_ASSIGN_OR_RETURN(const RevisionFile now, FingerprintFile(store_));
  if (now.bytes == head_.base.store.bytes && now.fingerprint == head_.base.store.fingerprint) {
    RemoveBuiltShardFiles();  // those a writer killed after the relink left
    return Status::Ok();
  }
  if (::link(ChangesFile(folder_, head_.base.store.name).c_str(), temp.c_str()) != 0)
    return Status::IOError(temp + ": cannot link the compacted base: " + storage_internal::ErrnoText(errno));
  bool renamed = false;
  Status st = RenameOverTarget(temp, store_, ops_, "the compacted store " + store_, &renamed);
  if (!renamed) ::unlink(temp.c_str());
  if (st.ok()) RemoveBuiltShardFiles();
  return st;
}

// A sharded store's build left its shard files beside its manifest, "<store>.shard-N.mkt" and ".ids"; the
// first change links them into the folder as revision 0's. Once the store file is a compaction's manifest
// (whose shards are in the folder) they are no longer the store's, and go, so that their pages are freed
// with revision 0's links. Only while this writer holds the store's locks: no sharded build of the path is
// writing them, and one that wrote them since would have made the folder another store's.
void Writer::RemoveBuiltShardFiles() {
  if (!sharded_ || head_.base.store.name == "base-0.mkt") return;
  const fs::path store(store_);
  const std::string stem = store.filename().string() + ".shard-";
  std::error_code ec;
  std::vector<fs::path> remove;
  for (fs::directory_iterator it(store.has_parent_path() ? store.parent_path() : fs::path("."), ec), end;
       !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(stem, 0) != 0) continue;
    const size_t dot = name.find('.', stem.size());
    const std::string digits = name.substr(stem.size(), dot == std::string::npos ? 0 : dot - stem.size());
    const std::string ext = dot == std::string::npos ? "" : name.substr(dot);
    if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    if (ext == ".mkt" || ext == ".ids") remove.push_back(it->path());
  }
  for (const fs::path& p : remove) fs::remove(p, ec);
}

// Retires the revisions older than the newest `keep` that no reader holds, then removes every file of the
// folder that no kept revision names (the leftovers of killed writers included). Returns the revisions
// retired and the bytes of the files removed. While the store file is not the head's base (its relink
// failed after a compaction's commit point) nothing is retired: a store file that is the base of no kept
// revision opens as a store without changes, and the next writer would start its changes anew.
Result<std::pair<uint64_t, uint64_t>> Writer::RetireAndCollect() {
  MKTREE_ASSIGN_OR_RETURN(std::vector<uint64_t> revisions, ListRevisionNumbers(folder_));
  uint64_t retired = 0, freed = 0;
  MKTREE_ASSIGN_OR_RETURN(const RevisionFile store_file, FingerprintFile(store_));
  const bool relinked =
      store_file.bytes == head_.base.store.bytes && store_file.fingerprint == head_.base.store.fingerprint;
  const uint64_t keep = relinked ? head_.keep : std::numeric_limits<uint64_t>::max();
  std::set<std::string> names;
  for (uint64_t r : revisions) {
    if (r > head_.revision) {
      // A revision file above the head: a writer killed after its commit point can only be the head, so
      // this is impossible unless the head was read before a later commit; keep it.
      continue;
    }
    if (head_.revision - r >= keep) {
      MKTREE_ASSIGN_OR_RETURN(const bool gone, TryRetireRevision(folder_, r));
      if (gone) {
        ++retired;
        continue;
      }
    }
    auto m = ReadRevisionFile(folder_, r);
    if (!m.ok()) {
      if (m.status().code() == Status::Code::kNotFound) continue;
      return m.status();
    }
    MKTREE_RETURN_IF_ERROR(NamesOf(folder_, *m, &names));
    names.insert(RevisionFileName(r));
  }
  std::error_code ec;
  std::vector<fs::path> remove;
  for (fs::directory_iterator it(folder_, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    uint64_t r = 0;
    if (ParseRevisionFileName(name, &r) && r > head_.revision) continue;
    if (!names.count(name)) remove.push_back(it->path());
  }
  if (ec) return Status::IOError(folder_ + ": " + ec.message());
  for (const fs::path& p : remove) {
    std::error_code size_ec;
    const uint64_t bytes = fs::is_regular_file(p, size_ec) ? fs::file_size(p, size_ec) : 0;
    if (fs::remove_all(p, size_ec) > 0 && !size_ec) freed += bytes;
  }
  // The touched lists the next commit carries: those after the oldest revision still kept.
  MKTREE_ASSIGN_OR_RETURN(revisions, ListRevisionNumbers(folder_));
  if (!revisions.empty()) {
    const uint64_t oldest = revisions.front();
    std::erase_if(head_.touched, [&](const RevisionIdList& l) { return l.made_at <= oldest; });
  }
  return std::pair{retired, freed};
}

}  // namespace

Result<std::unique_ptr<ChangeWriter>> OpenChangeWriter(const std::string& store_path,
                                                       const ChangeOptions& options, FileOps& ops) {
  return Guarded(store_path, [&]() -> Result<std::unique_ptr<ChangeWriter>> {
    if (!(options.compact_threshold >= 0)) return Status::InvalidArgument("compact_threshold must be >= 0");
    MKTREE_ASSIGN_OR_RETURN(std::shared_ptr<void> lock, StoreWriter::HoldLock(store_path));
    if (IsManifestFile(store_path)) {  // and the lock of sharded builds of the path
      MKTREE_ASSIGN_OR_RETURN(std::unique_ptr<ShardBuildLock> build, ShardBuildLock::Acquire(store_path));
      lock = std::make_shared<std::pair<std::shared_ptr<void>, std::unique_ptr<ShardBuildLock>>>(
          std::move(lock), std::move(build));
    }
    auto w = std::make_unique<Writer>(store_path, options, ops, std::move(lock));
    MKTREE_RETURN_IF_ERROR(w->Start());
    return std::unique_ptr<ChangeWriter>(std::move(w));
  });
}

Result<std::unique_ptr<ChangeWriter>> ChangeWriter::Open(const std::string& store_path,
                                                         const ChangeOptions& options) {
  return OpenChangeWriter(store_path, options, DefaultFileOps());
}

Result<std::vector<RevisionInfo>> ListRevisions(const std::string& store_path) {
  return Guarded(store_path, [&]() -> Result<std::vector<RevisionInfo>> {
    const std::string folder = ChangesFolder(store_path);
    MKTREE_ASSIGN_OR_RETURN(std::vector<uint64_t> revisions, ListRevisionNumbers(folder));
    bool kept = !revisions.empty();
    if (kept) {
      MKTREE_ASSIGN_OR_RETURN(kept, StoreFileIsAKeptBase(store_path, folder, revisions));
    }
    std::vector<RevisionInfo> out;
    if (!kept) {
      RevisionInfo info;
      if (IsManifestFile(store_path)) {
        MKTREE_ASSIGN_OR_RETURN(const Manifest m, ReadManifest(store_path));
        info.objects = m.objects;
      } else {
        MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(store_path));
        info.objects = reader->object_count();
      }
      struct stat st;
      if (::stat(store_path.c_str(), &st) == 0) info.time = st.st_mtime;
      info.message = "built";
      out.push_back(info);
      return out;
    }
    uint64_t history = 0;
    for (uint64_t r : revisions) {
      auto m = ReadRevisionFile(folder, r);
      if (!m.ok()) {
        if (m.status().code() == Status::Code::kNotFound) continue;  // retired meanwhile
        return m.status();
      }
      if (out.empty()) history = m->history;
      if (m->history != history)
        return Status::Corruption(ChangesFile(folder, RevisionFileName(out.front().revision)) + " and " +
                                  ChangesFile(folder, RevisionFileName(r)) +
                                  ": revision files of different stores (one was copied in from another)");
      RevisionInfo info;
      info.revision = m->revision;
      info.time = m->time;
      info.added = m->added;
      info.removed = m->removed;
      info.replaced = m->replaced;
      info.objects = m->live;
      info.compaction = m->compaction;
      info.message = m->message;
      out.push_back(info);
    }
    return out;
  });
}

}  // namespace mktree
