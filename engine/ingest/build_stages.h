// The stages of BuildStore (store_builder.h; docs/design.md §10), each taking what the stage before it
// produced:
//   1. read and spill (read_and_spill.h): scene sources -> SpilledObjects, the objects' leaf entries and
//      records spilled in id order and their BuildObjects in RAM;
//   2. the tree: BuildMKTree (engine/tree/mktree_builder.h) over the BuildObjects -> BuildResult;
//   3. the leaf pages (leaf_page_writer.h): the tree and the spilled entries -> the leaf pages, through the
//      store's PageStore, and the tree's leaf filter;
//   4. the records (object_table_writer.h): the spilled records and each object's leaf -> the object table,
//      written while stage 3 runs; then StoreWriter::Commit.
// Stages 2 to 4 know nothing of scene files: they take objects numbered 0..n-1 whose entries and records
// lie in spill files in id order (SpilledObjects), wherever those came from (compaction will spill an
// existing store's objects). Internal to engine/ingest.
//
// Thread safety: a stage runs on the calling thread, which it may share with threads of its own; it owns
// nothing between calls but what it returns.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/ingest/spill_file.h"
#include "engine/ingest/store_builder.h"
#include "engine/tree/object_record.h"

namespace mktree {

// Objects 0..n-1 as the later stages take them.
struct SpilledObjects {
  // Leaf entries (engine/store_format/leaf_codec.h), back to back in id order; flushed.
  std::unique_ptr<SpillFile> entries;
  // Records (EncodeRecord, engine/store_format/record_codec.h) in id order; flushed. The driver parks the
  // entry sizes after them while the tree is built (ParkEntrySizes).
  std::unique_ptr<SpillFile> records;
  std::vector<std::string> sources;  // the source files the records' source numbers index
  std::vector<BuildObject> objects;  // id (= index), box in the store frame, entry size
};

// Calls options.progress when there is one.
inline void ReportProgress(const IngestOptions& options, IngestStage stage, uint64_t done, uint64_t total) {
  if (options.progress) options.progress(stage, done, total);
}

// The entries' sizes, parked at the end of the record spill (past the records a SpillCursor reads) while
// the tree is built: 4 bytes an object out of RAM at that stage's peak. Returns where they start.
Result<uint64_t> ParkEntrySizes(const std::vector<BuildObject>& objects, SpillFile* records);
// Reads back the `count` sizes ParkEntrySizes wrote at `at`, by id.
Result<std::vector<uint32_t>> ReadParkedEntrySizes(const SpillFile& records, uint64_t at, uint64_t count);

}  // namespace mktree
