#include "engine/coordination/selection_scan.h"

#include <algorithm>
#include <functional>

#include "engine/coordination/selection.h"
#include "engine/query/revision_database.h"
#include "engine/query/sharded_database.h"
#include "engine/query/store_database.h"
#include "engine/store_format/record_codec.h"

namespace mktree::coordination {

std::vector<ObjectId> IdBits::Ids() const {
  std::vector<ObjectId> ids;
  for (size_t w = 0; w < words_.size(); ++w)
    for (uint64_t bits = words_[w]; bits; bits &= bits - 1)
      ids.push_back(static_cast<ObjectId>(w * 64 + static_cast<unsigned>(__builtin_ctzll(bits))));
  return ids;
}

namespace {

// The stores behind `db` as clash parts (global ids, hidden objects); empty for another kind of Database.
std::vector<ClashPart> PartsOf(const Database& db) {
  if (const auto* s = dynamic_cast<const StoreDatabase*>(&db)) return {ClashPart{&s->leaves()}};
  std::vector<ClashPart> parts = RevisionClashParts(db);
  return parts.empty() ? ShardedClashParts(db) : parts;
}

}  // namespace

Status VisitRecords(const Database& db, const std::vector<ObjectId>* only,
                    const std::function<void(ObjectRecord&)>& visit) {
  const std::vector<ClashPart> parts = PartsOf(db);
  ObjectRecord out;
  if (parts.empty()) {
    const bool all_live = db.object_count() == db.id_limit();
    const uint64_t n = only ? only->size() : db.id_limit();
    for (uint64_t i = 0; i < n; ++i) {
      const ObjectId id = only ? (*only)[i] : static_cast<ObjectId>(i);
      auto record = db.Object(id);
      if (!record.ok()) {
        if (!all_live && record.status().code() == Status::Code::kInvalidArgument) continue;
        return record.status();
      }
      visit(*record);
    }
    return Status::Ok();
  }
  for (const ClashPart& part : parts) {
    const StoreReader& reader = part.leaves->reader();
    const Vec3d& origin = reader.tree().origin;
    RecordReader records(reader.record_layout(), nullptr, part.leaves->verify_checksums());
    // The part's local ids to read, increasing: all, or those of `only` it holds.
    std::vector<ObjectId> locals;
    if (only) {
      for (ObjectId g : *only) {
        if (!part.ids) {
          if (g < reader.object_count()) locals.push_back(g);
          continue;
        }
        const auto at = std::lower_bound(part.ids->begin(), part.ids->end(), g);
        if (at != part.ids->end() && *at == g)
          locals.push_back(static_cast<ObjectId>(at - part.ids->begin()));
      }
    }
    const uint64_t n = only ? locals.size() : reader.object_count();
    for (uint64_t i = 0; i < n; ++i) {
      const uint64_t local = only ? locals[i] : i;
      if (part.hidden && (*part.hidden)[local]) continue;
      MKTREE_ASSIGN_OR_RETURN(const StoredRecord* r, records.Get(static_cast<uint32_t>(local), nullptr));
      out.id = part.ids ? (*part.ids)[local] : static_cast<ObjectId>(local);
      out.name = r->name;
      MKTREE_ASSIGN_OR_RETURN(out.source, reader.SourceName(*r));
      out.attributes = r->attributes;
      out.box = Box3d();
      if (!r->box.empty())
        for (int i = 0; i < 3; ++i) {
          out.box.min[i] = origin[i] + r->box.min[i];
          out.box.max[i] = origin[i] + r->box.max[i];
        }
      visit(out);
    }
  }
  return Status::Ok();
}

Status ScanSelections(const Database& db, const ClashTestFile& file, SelectionScan* out) {
  const uint64_t limit = db.id_limit();
  std::vector<SelectionMatcher> a, b;
  bool boxes = false;
  out->tests.assign(file.tests.size(), {});
  for (size_t t = 0; t < file.tests.size(); ++t) {
    const ClashTest& test = file.tests[t];
    a.emplace_back(test.a);
    b.emplace_back(test.b ? *test.b : Selection{});
    out->tests[t].a.Resize(limit);
    if (test.b) out->tests[t].b.Resize(limit);
    boxes |= test.mode == ClashTestMode::kDuplicates;
  }
  if (boxes) out->boxes.assign(limit, Box3d());
  out->live_objects = 0;
  MKTREE_RETURN_IF_ERROR(VisitRecords(db, nullptr, [&](ObjectRecord& record) {
    const ObjectId oid = record.id;
    ++out->live_objects;
    bool any = false;
    for (size_t t = 0; t < file.tests.size(); ++t) {
      TestSelections& s = out->tests[t];
      bool in = false;
      if (a[t].Matches(record)) {
        s.a.Set(oid);
        ++s.count_a;
        in = true;
      }
      if (file.tests[t].b && b[t].Matches(record)) {
        s.b.Set(oid);
        ++s.count_b;
        in = true;
      }
      if (in && (s.sources.empty() || *s.last_source != record.source))
        s.last_source = &*s.sources.insert(record.source).first;  // objects come in runs from one file
      any |= in;
    }
    if (boxes && any) out->boxes[oid] = record.box;
  }));
  for (size_t t = 0; t < file.tests.size(); ++t)
    if (!file.tests[t].b) out->tests[t].count_b = out->tests[t].count_a;
  return Status::Ok();
}

}  // namespace mktree::coordination
