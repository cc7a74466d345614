#include "storage/memory_page_store.h"

#include <cstring>

namespace mktree {

Status MemoryPageStore::ReadPage(uint64_t index, uint8_t* out) const {
  if (index >= count_) return PageOutOfRange(name_, index, count_);
  std::memcpy(out, data_.data() + index * page_bytes_, page_bytes_);
  return Status::Ok();
}

Status MemoryPageStore::WritePage(uint64_t index, const uint8_t* data) {
  if (index > count_)
    return Status::InvalidArgument(name_ + ": page " + std::to_string(index) + " written out of order");
  if (index == count_) {
    data_.resize((count_ + 1) * page_bytes_);
    ++count_;
  }
  std::memcpy(data_.data() + index * page_bytes_, data, page_bytes_);
  return Status::Ok();
}

Status FaultyPageStore::ReadPage(uint64_t index, uint8_t* out) const {
  const uint64_t n = ++reads_;
  if (fail_at_ != 0 && n == fail_at_)
    return Status::IOError(name() + ": page " + std::to_string(index) + ": injected read failure");
  MKTREE_RETURN_IF_ERROR(base_->ReadPage(index, out));
  if (index == flip_page_ && flip_offset_ < page_bytes()) out[flip_offset_] ^= flip_mask_;
  if (index == short_page_ && short_bytes_ < page_bytes())
    std::memset(out + short_bytes_, 0, page_bytes() - short_bytes_);
  return Status::Ok();
}

}  // namespace mktree
