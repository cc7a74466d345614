// Stage 4 of BuildStore (build_stages.h; docs/design.md §10): the object table and record pages, in id
// order, each object's record streamed from the record spill and its leaf taken from the tree. The record
// pages start at the leaf pages' total, which the tree fixes (StoreWriter::BeginObjects), so the table is
// written on a thread of its own while stage 3 writes the leaf pages. Internal to engine/ingest.
//
// Thread safety: Start, Finish and the destructor are called from one thread; between Start and Finish the
// table's thread uses the writer's AppendObject and reads the record spill, which nothing else may write.
#pragma once

#include <atomic>
#include <cstdint>
#include <future>
#include <string>
#include <vector>

#include "engine/ingest/build_stages.h"
#include "engine/store_format/store_file.h"
#include "engine/tree/mktree_builder.h"

namespace mktree {

// leaf_of[id]: the leaf of object id (kNoIndex: in none) in `built`, for objects 0..objects-1.
std::vector<uint32_t> LeafOfObjects(const BuildResult& built, uint64_t objects);
// The number of leaf pages of `tree`: the last leaf's end.
uint64_t LeafPageCount(const MKTree& tree);

class ObjectTableWriter {
 public:
  // `records` holds the records (EncodeRecord) of objects 0..leaf_of.size()-1 in id order from offset 0;
  // `sources` the names their source numbers index. Both must outlive this.
  ObjectTableWriter(StoreWriter& writer, const SpillFile& records, const std::vector<std::string>& sources,
                    std::vector<uint32_t> leaf_of);
  // Stops the table's thread, if it runs, and waits for it.
  ~ObjectTableWriter();
  ObjectTableWriter(const ObjectTableWriter&) = delete;
  ObjectTableWriter& operator=(const ObjectTableWriter&) = delete;

  // Declares the leaf pages (StoreWriter::BeginObjects) and starts the table's thread.
  Status Start(uint64_t leaf_pages);
  // Waits for the table's thread; its error if it failed (an object in no leaf, an unreadable record, the
  // writer's). Frees leaf_of.
  Status Finish();

 private:
  Status WriteTable();

  StoreWriter& writer_;
  const SpillFile& records_;
  const std::vector<std::string>& sources_;
  std::vector<uint32_t> leaf_of_;
  std::atomic<bool> stop_{false};
  std::future<Status> table_;
};

}  // namespace mktree
