// The selection scan of a clash-test run: one pass over the store's object records (each store's record
// pages in order, straight from the file and not through the page cache, as the clash's focus reads
// them) that evaluates every test's selections into one bit per object and per selection, and notes the
// source models selected. All the tests of a run share it. Thread safety: one thread.
#pragma once

#include <cstdint>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "mktree/clash_tests.h"
#include "mktree/database.h"

namespace mktree::coordination {

// One bit per object id.
class IdBits {
 public:
  void Resize(uint64_t n) { words_.assign((n + 63) / 64, 0); }
  void Set(ObjectId id) { words_[id >> 6] |= uint64_t{1} << (id & 63); }
  bool Get(ObjectId id) const { return (words_[id >> 6] >> (id & 63)) & 1; }
  // The ids set, increasing.
  std::vector<ObjectId> Ids() const;

 private:
  std::vector<uint64_t> words_;
};

struct TestSelections {
  IdBits a, b;  // b: the test's selection b (unused for a test of A against itself)
  uint64_t count_a = 0, count_b = 0;
  std::set<std::string> sources;             // of the objects in a or b
  const std::string* last_source = nullptr;  // in sources: the last one inserted
};

struct SelectionScan {
  std::vector<TestSelections> tests;  // in the file's order
  uint64_t live_objects = 0;
  std::vector<Box3d> boxes;  // by id, the world boxes of selected objects, when a duplicates test needs them
};

// Visits the records of the live objects of `db` among `only` (ids increasing; null: every object), in
// no particular order: each store's record pages in order, straight from the file (a RecordReader keeps
// the group it parsed, where Database::Object parses one per call); a Database of another kind through
// Database::Object. A damaged record page is an error naming the store and the page.
Status VisitRecords(const Database& db, const std::vector<ObjectId>* only,
                    const std::function<void(ObjectRecord&)>& visit);

// Scans the records of `db` (a store, a revision of one or a sharded store; another Database through
// Database::Object) for the selections of `tests`. Objects that are not live at the Database's revision
// are skipped; a damaged record page is an error naming the store and the page.
Status ScanSelections(const Database& db, const ClashTestFile& tests, SelectionScan* out);

}  // namespace mktree::coordination
