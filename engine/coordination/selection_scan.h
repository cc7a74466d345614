// The selection scan of a clash-test run: one pass over the store's object records (Database::Object,
// in id order, so each record page is read once through the page cache) that evaluates every test's
// selections into one bit per object and per selection, and notes the source models selected. All the
// tests of a run share it. Thread safety: one thread.
#pragma once

#include <cstdint>
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
  std::set<std::string> sources;  // of the objects in a or b
};

struct SelectionScan {
  std::vector<TestSelections> tests;  // in the file's order
  uint64_t live_objects = 0;
  std::vector<Box3d> boxes;  // by id, the world boxes of selected objects, when a duplicates test needs them
};

// Scans the records of `db` for the selections of `tests`. Ids that are not live at the Database's
// revision are skipped; a damaged record page is an error naming the store.
Status ScanSelections(const Database& db, const ClashTestFile& tests, SelectionScan* out);

}  // namespace mktree::coordination
