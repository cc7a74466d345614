#include "engine/store_format/record_codec.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "storage/byte_io.h"
#include "storage/page_codec.h"
#include "storage/page_format.h"

namespace mktree {

using storage_internal::Get;
using storage_internal::Put;

namespace {

void PutU32(std::vector<uint8_t>* out, uint32_t v) {
  const size_t n = out->size();
  out->resize(n + 4);
  Put<uint32_t>(out->data() + n, v);
}
void PutBytes(std::vector<uint8_t>* out, std::string_view s) {
  PutU32(out, static_cast<uint32_t>(s.size()));
  out->insert(out->end(), s.begin(), s.end());
}

}  // namespace

Status EncodeRecord(const Box3f& box, uint32_t source, uint32_t leaf, std::string_view name,
                    std::span<const ObjectAttribute> attributes, std::vector<uint8_t>* out) {
  uint64_t bytes = kRecordFixedBytes - 4 + name.size();
  for (const ObjectAttribute& a : attributes) bytes += 8 + a.key.size() + a.value.size();
  if (bytes > UINT32_MAX || attributes.size() > UINT32_MAX)
    return Status::InvalidArgument("object record of " + std::to_string(bytes) +
                                   " bytes: name and attributes must take under 4 GiB");
  out->reserve(out->size() + 4 + bytes);
  PutU32(out, static_cast<uint32_t>(bytes));
  for (int i = 0; i < 3; ++i) {
    const size_t n = out->size();
    out->resize(n + 4);
    Put<float>(out->data() + n, box.min[i]);
  }
  for (int i = 0; i < 3; ++i) {
    const size_t n = out->size();
    out->resize(n + 4);
    Put<float>(out->data() + n, box.max[i]);
  }
  PutU32(out, source);
  PutU32(out, leaf);
  PutBytes(out, name);
  PutU32(out, static_cast<uint32_t>(attributes.size()));
  for (const ObjectAttribute& a : attributes) {
    PutBytes(out, a.key);
    PutBytes(out, a.value);
  }
  return Status::Ok();
}

Status ParseRecord(const uint8_t* data, uint64_t n, uint64_t* used, StoredRecord* out) {
  if (n < 4) return Status::Corruption("object record cut short");
  const uint64_t bytes = Get<uint32_t>(data);
  if (bytes > n - 4 || bytes < kRecordFixedBytes - 4)
    return Status::Corruption("object record of " + std::to_string(bytes) + " bytes does not fit");
  const uint8_t* p = data + 4;
  const uint8_t* end = p + bytes;
  for (int i = 0; i < 3; ++i) out->box.min[i] = Get<float>(p + 4 * i);
  for (int i = 0; i < 3; ++i) out->box.max[i] = Get<float>(p + 12 + 4 * i);
  p += 24;
  for (int i = 0; i < 3; ++i)
    if (std::isnan(out->box.min[i]) || std::isnan(out->box.max[i]))
      return Status::Corruption("object record box is not a number");
  out->source = Get<uint32_t>(p);
  out->leaf = Get<uint32_t>(p + 4);
  p += 8;
  // Each length is checked against what is left of the record before anything is sized by it.
  auto take = [&](std::string* s) -> bool {
    if (end - p < 4) return false;
    const uint64_t len = Get<uint32_t>(p);
    p += 4;
    if (len > static_cast<uint64_t>(end - p)) return false;
    s->assign(reinterpret_cast<const char*>(p), len);
    p += len;
    return true;
  };
  if (!take(&out->name)) return Status::Corruption("object record name runs past the record");
  if (end - p < 4) return Status::Corruption("object record cut short");
  const uint64_t count = Get<uint32_t>(p);
  p += 4;
  if (count > static_cast<uint64_t>(end - p) / 8)
    return Status::Corruption("object record claims " + std::to_string(count) + " attributes");
  out->attributes.resize(count);
  for (ObjectAttribute& a : out->attributes)
    if (!take(&a.key) || !take(&a.value))
      return Status::Corruption("object record attribute runs past the record");
  if (p != end) return Status::Corruption("object record has trailing bytes");
  *used = 4 + bytes;
  return Status::Ok();
}

std::vector<uint8_t> EncodeSources(const std::vector<std::string>& sources) {
  std::vector<uint8_t> out;
  PutU32(&out, static_cast<uint32_t>(sources.size()));
  for (const std::string& s : sources) PutBytes(&out, s);
  return out;
}

Status DecodeSources(std::span<const uint8_t> in, std::vector<std::string>* sources) {
  sources->clear();
  if (in.size() < 4) return Status::Corruption("sources table cut short");
  const uint64_t count = Get<uint32_t>(in.data());
  uint64_t at = 4;
  if (count > (in.size() - at) / 4) return Status::Corruption("sources table claims too many sources");
  sources->reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    if (in.size() - at < 4) return Status::Corruption("sources table cut short");
    const uint64_t len = Get<uint32_t>(in.data() + at);
    at += 4;
    if (len > in.size() - at)
      return Status::Corruption("source " + std::to_string(i) + " runs past the table");
    sources->emplace_back(reinterpret_cast<const char*>(in.data() + at), len);
    at += len;
  }
  if (at != in.size()) return Status::Corruption("sources table has trailing bytes");
  return Status::Ok();
}

std::vector<uint8_t> EncodeRecordDirectory(const std::vector<uint32_t>& directory) {
  std::vector<uint8_t> out(4 * directory.size());
  for (size_t i = 0; i < directory.size(); ++i) Put<uint32_t>(out.data() + 4 * i, directory[i]);
  return out;
}

Status DecodeRecordDirectory(std::span<const uint8_t> in, std::vector<uint32_t>* directory) {
  if (in.size() % 4 != 0) return Status::Corruption("record directory is not whole u32s");
  directory->resize(in.size() / 4);
  for (size_t i = 0; i < directory->size(); ++i) (*directory)[i] = Get<uint32_t>(in.data() + 4 * i);
  return Status::Ok();
}

Status ValidateRecordDirectory(std::span<const uint32_t> d, uint64_t object_count, const std::string& what) {
  auto bad = [&](const std::string& m) { return Status::Corruption(what + ": record directory: " + m); };
  if (object_count == 0) return d.empty() ? Status::Ok() : bad("record pages in a store of no object");
  if (d.empty()) return bad("no record page for " + std::to_string(object_count) + " objects");
  if (d[0] != 0) return bad("page 0 starts at object " + std::to_string(d[0]));
  for (size_t i = 1; i < d.size(); ++i)
    if (d[i] < d[i - 1] || d[i] >= object_count)
      return bad("page " + std::to_string(i) + " starts at object " + std::to_string(d[i]));
  return Status::Ok();
}

Status RecordPager::Add(uint32_t id, std::span<const uint8_t> record) {
  const uint64_t capacity = PagePayloadCapacity(mem_page_);
  if (group_count_ > 0 && group_.size() + record.size() > capacity) MKTREE_RETURN_IF_ERROR(Flush());
  if (group_count_ == 0) {
    group_.assign(kRecordGroupHeaderBytes, 0);
    group_first_ = id;
  }
  group_.insert(group_.end(), record.begin(), record.end());
  ++group_count_;
  // A record too large for one page spans pages alone.
  if (group_.size() > capacity) return Flush();
  return Status::Ok();
}

Status RecordPager::Finish() { return group_count_ > 0 ? Flush() : Status::Ok(); }

Status RecordPager::Flush() {
  const uint64_t capacity = PagePayloadCapacity(mem_page_);
  Put<uint32_t>(group_.data(), group_count_);
  const uint64_t pages = (group_.size() + capacity - 1) / capacity;
  if (pages > UINT32_MAX) return Status::InvalidArgument("object record spans too many pages");
  page_.resize(mem_page_);
  for (uint64_t k = 0; k < pages; ++k) {
    const uint64_t from = k * capacity;
    const uint64_t n = std::min<uint64_t>(capacity, group_.size() - from);
    std::memset(page_.data(), 0, mem_page_);
    std::memcpy(page_.data() + kPageHeaderBytes, group_.data() + from, n);
    PageHeader h;
    h.leaf_index = group_first_;
    h.page_in_leaf = static_cast<uint32_t>(k);
    h.page_count = static_cast<uint32_t>(pages);
    h.payload_bytes = static_cast<uint32_t>(n);
    SealPage(h, page_.data(), mem_page_, kRecordPageMagic);
    MKTREE_RETURN_IF_ERROR(write_(page_.data()));
    directory_.push_back(group_first_);
  }
  group_.clear();
  group_count_ = 0;
  return Status::Ok();
}

Status RecordReader::LoadGroup(uint64_t g0, uint64_t pages, QueryStats* stats) {
  const RecordLayout& l = layout_;
  const uint32_t first = l.directory[g0];
  const uint64_t end_id = g0 + pages < l.directory.size() ? l.directory[g0 + pages] : l.object_count;
  const uint64_t capacity = PagePayloadCapacity(l.mem_page);
  loaded_ = false;
  payload_.clear();
  for (uint64_t k = 0; k < pages; ++k) {
    const uint64_t index = l.first_page + g0 + k;
    auto fail = [&](const std::string& m) {
      return Status::Corruption(l.store_name + ": page " + std::to_string(index) + " (object records from " +
                                std::to_string(first) + "): " + m);
    };
    const uint8_t* data = nullptr;
    PageHandle handle;
    if (cache_) {
      auto h = cache_->Pin(index, stats);
      if (!h.ok()) return h.status();
      handle = std::move(*h);
      data = handle.data();
    } else {
      page_.resize(l.mem_page);
      MKTREE_RETURN_IF_ERROR(l.store->ReadPage(index, page_.data()));
      data = page_.data();
    }
    const bool check_sum = verify_ && !(cache_ && handle.verified());
    auto header = CheckPage(data, l.mem_page, check_sum, l.store_name, index, kRecordPageMagic);
    if (!header.ok()) return header.status();
    if (check_sum && cache_) handle.MarkVerified();
    if (header->leaf_index != first)
      return fail("says it starts at object " + std::to_string(header->leaf_index));
    if (header->page_in_leaf != k || header->page_count != pages)
      return fail("says it is page " + std::to_string(header->page_in_leaf) + " of " +
                  std::to_string(header->page_count) + " where the directory makes it " + std::to_string(k) +
                  " of " + std::to_string(pages));
    if (header->payload_bytes == 0 || (k + 1 < pages && header->payload_bytes != capacity))
      return fail("payload of " + std::to_string(header->payload_bytes) + " bytes");
    payload_.insert(payload_.end(), data + kPageHeaderBytes, data + kPageHeaderBytes + header->payload_bytes);
  }
  auto fail = [&](const std::string& m) {
    return Status::Corruption(l.store_name + ": page " + std::to_string(l.first_page + g0) +
                              " (object records from " + std::to_string(first) + "): " + m);
  };
  if (payload_.size() < kRecordGroupHeaderBytes) return fail("group header cut short");
  const uint64_t count = storage_internal::Get<uint32_t>(payload_.data());
  if (count != end_id - first || storage_internal::Get<uint32_t>(payload_.data() + 4) != 0)
    return fail("holds " + std::to_string(count) + " records where the directory says " +
                std::to_string(end_id - first));
  if (pages > 1 && count != 1) return fail("a record group over several pages holds more than one record");
  if (count > (payload_.size() - kRecordGroupHeaderBytes) / kRecordFixedBytes)
    return fail(std::to_string(count) + " records do not fit in its payload");
  records_.resize(count);
  uint64_t at = kRecordGroupHeaderBytes;
  for (uint64_t i = 0; i < count; ++i) {
    uint64_t used = 0;
    Status st = ParseRecord(payload_.data() + at, payload_.size() - at, &used, &records_[i]);
    if (!st.ok()) return fail("object " + std::to_string(first + i) + ": " + st.message());
    if (records_[i].leaf >= l.leaf_count)
      return fail("object " + std::to_string(first + i) + ": in leaf " + std::to_string(records_[i].leaf) +
                  " of " + std::to_string(l.leaf_count));
    at += used;
  }
  if (at != payload_.size()) return fail("trailing bytes after its records");
  first_ = first;
  loaded_ = true;
  return Status::Ok();
}

Result<const StoredRecord*> RecordReader::Get(uint32_t id, QueryStats* stats) {
  const RecordLayout& l = layout_;
  if (id >= l.object_count)
    return Status::InvalidArgument(l.store_name + ": object " + std::to_string(id) + " out of range (" +
                                   std::to_string(l.object_count) + " objects)");
  if (loaded_ && id >= first_ && id - first_ < records_.size()) return &records_[id - first_];
  const auto& d = l.directory;
  // The last page starting at or before id; its group is every page starting at the same id.
  const auto p = std::upper_bound(d.begin(), d.end(), id) - 1;
  const auto g0 = std::lower_bound(d.begin(), p + 1, *p);
  const auto g1 = std::upper_bound(p, d.end(), *p);
  MKTREE_RETURN_IF_ERROR(
      LoadGroup(static_cast<uint64_t>(g0 - d.begin()), static_cast<uint64_t>(g1 - g0), stats));
  return &records_[id - first_];
}

}  // namespace mktree
