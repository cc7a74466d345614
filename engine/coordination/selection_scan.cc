#include "engine/coordination/selection_scan.h"

#include <algorithm>

#include "engine/coordination/selection.h"

namespace mktree::coordination {

std::vector<ObjectId> IdBits::Ids() const {
  std::vector<ObjectId> ids;
  for (size_t w = 0; w < words_.size(); ++w)
    for (uint64_t bits = words_[w]; bits; bits &= bits - 1)
      ids.push_back(static_cast<ObjectId>(w * 64 + static_cast<unsigned>(__builtin_ctzll(bits))));
  return ids;
}

Status ScanSelections(const Database& db, const ClashTestFile& file, SelectionScan* out) {
  const uint64_t limit = db.id_limit();
  // A store that has taken no change has every id below its limit live; with changes, Object refuses
  // removed ids (InvalidArgument) and they are skipped.
  const bool all_live = db.object_count() == limit;
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
  for (uint64_t id = 0; id < limit; ++id) {
    const ObjectId oid = static_cast<ObjectId>(id);
    auto record = db.Object(oid);
    if (!record.ok()) {
      if (!all_live && record.status().code() == Status::Code::kInvalidArgument) continue;
      return record.status();
    }
    ++out->live_objects;
    bool any = false;
    for (size_t t = 0; t < file.tests.size(); ++t) {
      TestSelections& s = out->tests[t];
      bool in = false;
      if (a[t].Matches(*record)) {
        s.a.Set(oid);
        ++s.count_a;
        in = true;
      }
      if (file.tests[t].b && b[t].Matches(*record)) {
        s.b.Set(oid);
        ++s.count_b;
        in = true;
      }
      if (in) s.sources.insert(record->source);
      any |= in;
    }
    if (boxes && any) out->boxes[id] = record->box;
  }
  for (size_t t = 0; t < file.tests.size(); ++t)
    if (!file.tests[t].b) out->tests[t].count_b = out->tests[t].count_a;
  return Status::Ok();
}

}  // namespace mktree::coordination
