// The Database over one revision of a store with changes: the parts' answers merged, hidden objects
// skipped, local ids mapped to global ones (see revision_database.h).
#include "engine/query/revision_database.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "engine/clash/clash_engine.h"
#include "engine/clash/pair_rules.h"
#include "engine/core/guarded.h"
#include "engine/query/nearest_search.h"
#include "engine/query/ordered_batch.h"
#include "engine/query/part_queries.h"
#include "engine/query/ray_search.h"
#include "engine/query/shard_open.h"
#include "engine/query/sharded_database.h"
#include "engine/store_format/store_file.h"

namespace mktree {

namespace {

Status CheckFile(const std::string& folder, const RevisionFile& want, const std::string& what) {
  const std::string path = ChangesFile(folder, want.name);
  auto got = FingerprintFile(path);
  if (!got.ok()) {
    if (got.status().code() == Status::Code::kNotFound)
      return Status::Corruption(path + ": missing (" + what + " of the revision)");
    return got.status();
  }
  if (got->bytes != want.bytes || got->fingerprint != want.fingerprint)
    return Status::Corruption(path + ": not the file the revision was committed with (" + what +
                              "; replaced, truncated or damaged)");
  return Status::Ok();
}

// Ids of an id file of the folder (a part's map, or a removal list), checked against the manifest.
Result<std::vector<ObjectId>> ReadIdFile(const std::string& folder, const RevisionManifest& m,
                                         const RevisionFile& file, uint64_t made_at, uint64_t count,
                                         const std::string& what) {
  MKTREE_RETURN_IF_ERROR(CheckFile(folder, file, what));
  const std::string path = ChangesFile(folder, file.name);
  MKTREE_ASSIGN_OR_RETURN(std::vector<ObjectId> ids,
                          ReadShardIds(path, m.history, static_cast<uint32_t>(made_at), m.next_id));
  if (ids.size() != count)
    return Status::Corruption(path + ": " + std::to_string(ids.size()) + " ids, the revision says " +
                              std::to_string(count));
  return ids;
}

// Marks hidden[i] for the part's ids found in `gone` (sorted): a merge walk, as both are increasing.
uint64_t MarkHidden(RevisionPartDb* part, const std::vector<ObjectId>& gone) {
  const uint64_t n = part->db->object_count();
  part->hidden.assign(n, false);
  uint64_t hidden = 0;
  size_t g = 0;
  for (uint64_t i = 0; i < n && g < gone.size(); ++i) {
    const ObjectId id = part->global(static_cast<ObjectId>(i));
    while (g < gone.size() && gone[g] < id) ++g;
    if (g < gone.size() && gone[g] == id) {
      part->hidden[i] = true;
      ++hidden;
    }
  }
  return hidden;
}

class RevisionDatabase final : public Database {
 public:
  RevisionDatabase(std::string path, std::unique_ptr<RevisionHold> hold, std::vector<RevisionPartDb> parts)
      : path_(std::move(path)), hold_(std::move(hold)), parts_(std::move(parts)) {
    const RevisionManifest& m = hold_->manifest();
    stats_json_ = "{\"revision\": " + std::to_string(m.revision) +
                  ", \"live_objects\": " + std::to_string(m.live) +
                  ", \"deltas\": " + std::to_string(m.deltas.size()) + ", \"parts\": [";
    double pages = 0;
    bool any_bounds = false;
    for (size_t p = 0; p < parts_.size(); ++p) {
      const StoreDatabase& db = *parts_[p].db;
      stats_json_ += (p ? ", " : "") + db.stats_json();
      const double opp = db.objects_per_page();
      if (opp > 0) pages += static_cast<double>(db.object_count()) / opp;
      if (db.object_count() > 0) bounds_ = any_bounds ? UnionBox(bounds_, db.bounds()) : db.bounds();
      any_bounds = any_bounds || db.object_count() > 0;
      clash_parts_.push_back(ClashPart{&db.leaves(), parts_[p].ids.empty() ? nullptr : &parts_[p].ids,
                                       parts_[p].hidden_count ? &parts_[p].hidden : nullptr});
    }
    stats_json_ += "]}";
    objects_per_page_ = pages > 0 ? static_cast<double>(m.live) / pages : 0;
  }

  uint64_t revision() const override { return hold_->manifest().revision; }
  const std::vector<ClashPart>& clash_parts() const { return clash_parts_; }
  std::vector<SearchPart> SearchParts() const {
    std::vector<SearchPart> out;
    for (const RevisionPartDb& p : parts_)
      out.push_back({p.db.get(), p.ids.empty() ? nullptr : &p.ids, p.hidden_count ? &p.hidden : nullptr});
    return out;
  }
  const RevisionManifest& manifest() const { return hold_->manifest(); }
  Status FocusedClash(const MultiClashScope& scope, const ClashOptions& o, const ClashVisitor& visit,
                      ClashStats* stats) const {
    return Guarded(path_, [&] { return RunMultiClash(clash_parts_, scope, o, visit, stats); });
  }
  uint64_t id_limit() const override { return hold_->manifest().next_id; }

  Result<bool> VisitUntil(const Query& q, const StoppableVisitor& visit, QueryStats* stats) const override {
    QueryStats total;
    if (!FiniteQuery(q))
      return Status::InvalidArgument(q.kind == Query::Kind::kPoint
                                         ? "point query with a non-finite coordinate"
                                         : "box query with a non-finite coordinate "
                                           "or min > max");
    uint64_t emitted = 0;
    bool more = false, stopped = false;
    for (const RevisionPartDb& part : parts_) {
      Query pq = q;
      pq.limit = Query::kNoLimit;
      QueryStats st;
      MKTREE_ASSIGN_OR_RETURN(const bool whole, part.db->VisitUntil(
                                                    pq,
                                                    [&](ObjectId local) {
                                                      if (part.hidden[local]) return true;
                                                      if (emitted == q.limit) {
                                                        more = true;
                                                        return false;
                                                      }
                                                      ++emitted;
                                                      if (!visit(part.global(local))) {
                                                        stopped = true;
                                                        return false;
                                                      }
                                                      return true;
                                                    },
                                                    &st));
      total += st;
      if (!whole) break;
    }
    total.hits = emitted;
    if (stats) *stats = total;
    return !more && !stopped;
  }

  Status RunBatchStreamed(const QuerySource& source, const BatchOptions& options,
                          const ResultVisitor& deliver) const override;

  // One best-first search over every part's tree, hidden objects left out.
  Result<std::unique_ptr<NearestCursor>> OpenNearest(const DistanceQuery& q) const override {
    return OpenNearestSearch(SearchParts(), q, path_);
  }
  Result<bool> VisitRay(const RayQuery& q, const RayVisitor& visit, QueryStats* stats) const override {
    return RunRaySearch(SearchParts(), q, path_, visit, stats);
  }

  // One sweep over all the parts' leaves, hidden objects left out (ClashPart::hidden).
  Status SelfClash(const ClashOptions& o, const ClashVisitor& visit, ClashStats* stats) const override {
    return Guarded(path_, [&] { return RunMultiClash(clash_parts_, nullptr, o, visit, stats); });
  }
  Status Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform, const ClashOptions& o,
                 const ClashVisitor& visit, ClashStats* stats) const override;
  void ClearCache() override {
    for (auto& p : parts_) p.db->ClearCache();
  }
  const std::string& path() const override { return path_; }
  uint64_t object_count() const override { return hold_->manifest().live; }
  Result<ObjectRecord> Object(ObjectId id, QueryStats* stats) const override {
    MKTREE_ASSIGN_OR_RETURN(const auto at, Locate(id));
    MKTREE_ASSIGN_OR_RETURN(ObjectRecord r, parts_[at.first].db->Object(at.second, stats));
    r.id = id;
    return r;
  }
  Result<Mesh> ObjectGeometry(ObjectId id, QueryStats* stats) const override {
    MKTREE_ASSIGN_OR_RETURN(const auto at, Locate(id));
    return parts_[at.first].db->ObjectGeometry(at.second, stats);
  }
  Result<std::string> ObjectName(ObjectId id) const override {
    MKTREE_ASSIGN_OR_RETURN(const auto at, Locate(id));
    return parts_[at.first].db->ObjectName(at.second);
  }
  Box3d bounds() const override { return bounds_; }
  double objects_per_page() const override { return objects_per_page_; }
  const std::string& stats_json() const override { return stats_json_; }

 private:
  // The part where `id` is live, and its local id there.
  Result<std::pair<size_t, ObjectId>> Locate(ObjectId id) const {
    if (auto at = FindLive(parts_, id)) return *at;
    return Status::InvalidArgument(path_ + ": no object " + std::to_string(id) + " at revision " +
                                   std::to_string(revision()) + " (removed, or never added)");
  }

  std::string path_;
  std::unique_ptr<RevisionHold> hold_;
  std::vector<RevisionPartDb> parts_;
  std::vector<ClashPart> clash_parts_;
  Box3d bounds_;
  std::string stats_json_;
  double objects_per_page_ = 0;
};

Status RevisionDatabase::Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform,
                                 const ClashOptions& o, const ClashVisitor& visit, ClashStats* stats) const {
  return Guarded(path_, [&]() -> Status {
    const auto start = std::chrono::steady_clock::now();
    ClashStats local;
    ClashStats& total = stats ? *stats : local;
    total = ClashStats();
    MKTREE_RETURN_IF_ERROR(clash::CheckOptions(o));
    MKTREE_RETURN_IF_ERROR(CheckCollideMesh(mesh, transform));
    for (const ClashPart& part : clash_parts_) {
      ClashOptions so = o;
      so.max_pairs = std::numeric_limits<uint64_t>::max();
      ClashStats st;
      PartPairCap cap(total, o.max_pairs);
      MKTREE_RETURN_IF_ERROR(RunCollide(
          part, mesh, transform, so,
          [&](const ClashPair& p) {
            if (cap.Take() && visit) visit(p);
          },
          &st));
      cap.Fill(&st);
      AddClashStats(&total, st);
    }
    total.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return Status::Ok();
  });
}

Status RevisionDatabase::RunBatchStreamed(const QuerySource& source, const BatchOptions& options,
                                          const ResultVisitor& deliver) const {
  return Guarded(path_, [&]() -> Status {
    // One query: each part runs it as a batch of one (cold: on its own empty cache); hidden ids dropped.
    return RunQueriesOneByOne(path_, source, options, deliver, [&](const Query& q, QueryResult* r) -> Status {
      BatchOptions one = options;
      one.ids = true;  // hidden ids must be seen to be dropped
      uint64_t emitted = 0;
      for (const RevisionPartDb& part : parts_) {
        Query pq = q;
        // A part with hidden objects may answer more ids than it counts: it runs without the limit.
        pq.limit =
            part.hidden_count ? Query::kNoLimit : (q.limit == Query::kNoLimit ? q.limit : q.limit - emitted);
        MKTREE_RETURN_IF_ERROR(RunOneOnStore(*part.db, pq, one, [&](const QueryResult& pr) {
          r->stats += pr.stats;
          for (ObjectId local : pr.hits) {
            if (part.hidden[local]) continue;
            if (emitted == q.limit) {
              r->truncated = true;
              break;
            }
            ++emitted;
            if (options.ids) r->hits.push_back(part.global(local));
          }
          if (pr.truncated) r->truncated = true;
        }));
        if (r->truncated) break;
      }
      r->stats.hits = emitted;
      std::sort(r->hits.begin(), r->hits.end());
      return Status::Ok();
    });
  });
}

}  // namespace

size_t BasePartCount(const std::vector<RevisionPartDb>& parts) {
  size_t n = 0;
  while (n < parts.size() && parts[n].base) ++n;
  return n;
}

Result<std::vector<RevisionPartDb>> OpenRevisionParts(const std::string& store_path,
                                                      const RevisionManifest& m, const OpenOptions& options,
                                                      std::vector<RevisionPartDb>* reuse,
                                                      bool keep_leaf_filters,
                                                      const std::vector<uint8_t>* open) {
  const std::string folder = ChangesFolder(store_path);
  const std::string base_path = ChangesFile(folder, m.base.store.name);
  MKTREE_RETURN_IF_ERROR(CheckFile(folder, m.base.store, "its base store"));
  std::optional<Manifest> sharded;
  if (IsManifestFile(base_path)) {
    MKTREE_ASSIGN_OR_RETURN(sharded, ReadManifest(base_path));
    if (sharded->objects != m.base.objects)
      return Status::Corruption(base_path + ": " + std::to_string(sharded->objects) +
                                " objects, the revision says " + std::to_string(m.base.objects));
  }
  for (const RevisionPart& d : m.deltas)
    if (d.shard != kNoShard && (!sharded || d.shard >= sharded->shards.size()))
      return Status::Corruption(
          ChangesFile(folder, RevisionFileName(m.revision)) + ": delta " + d.store.name +
          " is routed to shard " + std::to_string(d.shard) + ", its base " +
          (sharded ? "has " + std::to_string(sharded->shards.size()) + " shards" : "is not sharded"));
  const uint64_t k = RevisionPartCount(m, sharded ? sharded->shards.size() : 0);
  if (open && open->size() != k)
    return Status::InvalidArgument(store_path + ": parts to open given for " + std::to_string(open->size()) +
                                   " parts, revision " + std::to_string(m.revision) + " has " +
                                   std::to_string(k));
  auto opened = [&](size_t index) { return !open || (*open)[index]; };
  OpenOptions part_options = options;
  part_options.cache_pages = (options.cache_pages + k - 1) / k;
  part_options.revision.reset();
  std::vector<RevisionPartDb> parts;
  auto reused = [&](const std::string& path) {
    if (!reuse) return false;
    auto it = std::find_if(reuse->begin(), reuse->end(),
                           [&](const RevisionPartDb& r) { return r.db && r.db->path() == path; });
    if (it == reuse->end()) return false;
    parts.push_back(std::move(*it));
    reuse->erase(it);
    return true;
  };
  if (sharded) {
    // Its shards, with the ids the sharded build or the compaction gave them (below next_id).
    for (uint32_t s = 0; s < sharded->shards.size(); ++s) {
      if (!opened(s)) continue;
      if (reused(ShardFilePath(base_path, sharded->shards[s].store.name))) {
        parts.back().index = s;
        continue;
      }
      MKTREE_ASSIGN_OR_RETURN(ManifestShard shard, OpenManifestShard(base_path, *sharded, s, part_options,
                                                                     m.next_id, keep_leaf_filters));
      RevisionPartDb part;
      part.db = std::move(shard.db);
      part.ids = std::move(shard.ids);
      part.base = true;
      part.index = s;
      parts.push_back(std::move(part));
    }
  }
  std::vector<const RevisionPart*> described;
  if (!sharded) described.push_back(&m.base);
  for (const RevisionPart& d : m.deltas) described.push_back(&d);
  const size_t first_described = k - described.size();
  // The ids of each delta left closed, by index: they hide what the parts before it hold.
  std::vector<std::pair<uint32_t, std::vector<ObjectId>>> closed_ids;
  for (size_t at = 0; at < described.size(); ++at) {
    const RevisionPart* d = described[at];
    const uint32_t index = static_cast<uint32_t>(first_described + at);
    const std::string what =
        d == &m.base ? "its base store" : "the changes of revision " + std::to_string(d->made_at);
    if (!opened(index)) {
      if (d == &m.base) continue;
      MKTREE_ASSIGN_OR_RETURN(std::vector<ObjectId> ids,
                              ReadIdFile(folder, m, d->ids, d->made_at, d->objects, what + "'s ids"));
      closed_ids.emplace_back(index, std::move(ids));
      continue;
    }
    const std::string path = ChangesFile(folder, d->store.name);
    if (reused(path)) {
      parts.back().index = index;
      continue;
    }
    RevisionPartDb part;
    part.base = d == &m.base;
    part.index = index;
    if (!part.base) MKTREE_RETURN_IF_ERROR(CheckFile(folder, d->store, what));
    ReadOptions ro;
    ro.direct_io = options.direct_io;
    ro.keep_leaf_filter = keep_leaf_filters;
    MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(path, ro));
    part.db = OpenStoreDatabase(std::move(reader), part_options);
    if (part.db->object_count() != d->objects)
      return Status::Corruption(path + ": " + std::to_string(part.db->object_count()) +
                                " objects, the revision says " + std::to_string(d->objects));
    if (!d->ids.name.empty()) {
      MKTREE_ASSIGN_OR_RETURN(part.ids,
                              ReadIdFile(folder, m, d->ids, d->made_at, d->objects, what + "'s ids"));
    } else if (d->objects > m.next_id) {
      return Status::Corruption(path + ": more objects than the revision has ids");
    }
    parts.push_back(std::move(part));
  }
  // Hidden: removed ids, and in each part the ids of the parts after it.
  std::vector<ObjectId> gone;
  for (const RevisionIdList& r : m.removals) {
    MKTREE_ASSIGN_OR_RETURN(std::vector<ObjectId> ids,
                            ReadIdFile(folder, m, r.file, r.made_at, r.count,
                                       "the ids removed at revision " + std::to_string(r.made_at)));
    gone.insert(gone.end(), ids.begin(), ids.end());
  }
  std::sort(gone.begin(), gone.end());
  auto hide = [&gone](const std::vector<ObjectId>& ids) {
    std::vector<ObjectId> merged;
    merged.reserve(gone.size() + ids.size());
    std::set_union(gone.begin(), gone.end(), ids.begin(), ids.end(), std::back_inserter(merged));
    gone = std::move(merged);
  };
  uint64_t live = 0;
  // Newest first: each part hides what the ones before it hold of the same ids.
  auto closed = closed_ids.rbegin();
  for (size_t p = parts.size(); p-- > 0;) {
    for (; closed != closed_ids.rend() && closed->first > parts[p].index; ++closed) hide(closed->second);
    parts[p].hidden_count = MarkHidden(&parts[p], gone);
    live += parts[p].db->object_count() - parts[p].hidden_count;
    if (parts[p].base) continue;  // base parts hold disjoint ids: none hides anything in another
    // Only a base has identity ids (no id file): a delta always has its id file.
    hide(parts[p].ids);
  }
  if (open) return parts;  // the live count is over every part
  if (live != m.live)
    return Status::Corruption(ChangesFile(folder, RevisionFileName(m.revision)) + ": " +
                              std::to_string(live) + " live objects in its stores, the revision says " +
                              std::to_string(m.live));
  return parts;
}

std::optional<std::pair<size_t, ObjectId>> FindLive(const std::vector<RevisionPartDb>& parts, ObjectId id) {
  for (size_t p = parts.size(); p-- > 0;) {  // the newest part holding the id has its live version
    const RevisionPartDb& part = parts[p];
    std::optional<ObjectId> local;
    if (part.ids.empty()) {
      if (id < part.db->object_count()) local = id;
    } else {
      local = LocalIdOf(part.ids, id);
    }
    if (!local) continue;
    if (part.hidden[*local]) return std::nullopt;  // removed (a superseded copy is found after the live one)
    return std::pair{p, *local};
  }
  return std::nullopt;
}

const RevisionManifest* RevisionManifestOf(const Database& db) {
  const auto* r = dynamic_cast<const RevisionDatabase*>(&db);
  return r ? &r->manifest() : nullptr;
}

Result<std::vector<ObjectId>> TouchedSince(const Database& db, uint64_t since) {
  const RevisionManifest* m = RevisionManifestOf(db);
  if (!m) return Status::InvalidArgument(db.path() + ": the store has taken no change");
  const std::string folder = ChangesFolder(db.path());
  std::vector<ObjectId> out;
  for (const RevisionIdList& t : m->touched) {
    if (t.made_at <= since || t.made_at > m->revision) continue;
    MKTREE_ASSIGN_OR_RETURN(std::vector<ObjectId> ids,
                            ReadIdFile(folder, *m, t.file, t.made_at, t.count,
                                       "the ids touched at revision " + std::to_string(t.made_at)));
    out.insert(out.end(), ids.begin(), ids.end());
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

Status FocusedSelfClash(const Database& db, const std::vector<ObjectId>& focus, const ClashOptions& options,
                        const ClashVisitor& visit, ClashStats* stats, const std::vector<ObjectId>* partner) {
  const MultiClashScope scope{nullptr, &focus, partner};
  if (const auto* r = dynamic_cast<const RevisionDatabase*>(&db))
    return r->FocusedClash(scope, options, visit, stats);
  if (const auto* s = dynamic_cast<const StoreDatabase*>(&db))
    return Guarded(db.path(),
                   [&] { return RunMultiClash({ClashPart{&s->leaves()}}, scope, options, visit, stats); });
  if (db.shard_count() > 0) return ShardedScopedClash(db, scope, options, visit, stats);
  return Status::Unsupported(db.path() +
                             ": a focused clash needs a store, a revision of one or a sharded store");
}

std::vector<ClashPart> RevisionClashParts(const Database& db) {
  const auto* r = dynamic_cast<const RevisionDatabase*>(&db);
  return r ? r->clash_parts() : std::vector<ClashPart>();
}

Result<std::unique_ptr<Database>> OpenRevisionDatabase(const std::string& store_path,
                                                       std::unique_ptr<RevisionHold> hold,
                                                       const OpenOptions& options) {
  MKTREE_ASSIGN_OR_RETURN(std::vector<RevisionPartDb> parts,
                          OpenRevisionParts(store_path, hold->manifest(), options));
  return std::unique_ptr<Database>(
      std::make_unique<RevisionDatabase>(store_path, std::move(hold), std::move(parts)));
}

}  // namespace mktree
