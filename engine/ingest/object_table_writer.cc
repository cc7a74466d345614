#include "engine/ingest/object_table_writer.h"

#include <cstring>

#include "engine/store_format/record_codec.h"

namespace mktree {

std::vector<uint32_t> LeafOfObjects(const BuildResult& built, uint64_t objects) {
  std::vector<uint32_t> leaf_of(objects, kNoIndex);
  const uint32_t leaf_count = static_cast<uint32_t>(built.tree.leaves.size());
  for (uint32_t leaf = 0; leaf < leaf_count; ++leaf)
    for (uint64_t i = built.leaf_offsets[leaf]; i < built.leaf_offsets[leaf + 1]; ++i)
      leaf_of[built.leaf_objects[i]] = leaf;
  return leaf_of;
}

uint64_t LeafPageCount(const MKTree& tree) {
  return tree.leaves.empty() ? 0 : uint64_t{tree.leaves.back().first_page} + tree.leaves.back().page_count;
}

ObjectTableWriter::ObjectTableWriter(StoreWriter& writer, const SpillFile& records,
                                     const std::vector<std::string>& sources, std::vector<uint32_t> leaf_of)
    : writer_(writer), records_(records), sources_(sources), leaf_of_(std::move(leaf_of)) {}

ObjectTableWriter::~ObjectTableWriter() {
  stop_ = true;
  if (table_.valid()) table_.wait();
}

Status ObjectTableWriter::Start(uint64_t leaf_pages) {
  MKTREE_RETURN_IF_ERROR(writer_.BeginObjects(leaf_pages));
  table_ = std::async(std::launch::async, [this] { return WriteTable(); });
  return Status::Ok();
}

Status ObjectTableWriter::Finish() {
  if (!table_.valid()) return Status::Internal("the object table was not started");
  Status st = table_.get();
  std::vector<uint32_t>().swap(leaf_of_);
  return st;
}

Status ObjectTableWriter::WriteTable() {
  StoredRecord record;
  std::vector<uint8_t> bytes;
  SpillCursor cursor(records_);
  const uint64_t objects = leaf_of_.size();
  for (ObjectId id = 0; id < objects && !stop_.load(std::memory_order_relaxed); ++id) {
    if (leaf_of_[id] == kNoIndex) return Status::Internal("object " + std::to_string(id) + " is in no leaf");
    uint32_t len = 0;
    MKTREE_RETURN_IF_ERROR(cursor.Read(sizeof len, &len));
    bytes.resize(4 + uint64_t{len});
    std::memcpy(bytes.data(), &len, 4);
    MKTREE_RETURN_IF_ERROR(cursor.Read(len, bytes.data() + 4));
    uint64_t used = 0;
    if (Status st = ParseRecord(bytes.data(), bytes.size(), &used, &record);
        !st.ok() || record.source >= sources_.size())
      return Status::Internal(records_.path() + ": object " + std::to_string(id) +
                              ": spilled record unreadable");
    MKTREE_RETURN_IF_ERROR(writer_.AppendObject(id, leaf_of_[id], record.box, record.name,
                                                sources_[record.source], record.attributes));
  }
  return Status::Ok();
}

}  // namespace mktree
