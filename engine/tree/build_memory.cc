#include "engine/tree/build_memory.h"

#include "engine/tree/build_state.h"

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace mktree::build {

void TrimHeap() {
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}

void DoneRanges::Init(uint32_t n, std::array<BuildVector<uint32_t>, 6>* lists, ListSpill* spill) {
  if (size_t{n} * sizeof(uint32_t) < BuildAllocator<uint32_t>::kMapBytes) return;
  lists_ = lists;
  spill_ = spill;
  n_ = n;
  const uint32_t chunks = (n + kChunk - 1) / kChunk;
  done_ = std::make_unique<std::atomic<uint32_t>[]>(chunks);
  for (uint32_t c = 0; c < chunks; ++c) done_[c].store(0, std::memory_order_relaxed);
}

void DoneRanges::LeafDone(uint32_t lo, uint32_t hi) {
  if (done_ == nullptr) return;
  for (uint32_t c = lo / kChunk; c * kChunk < hi; ++c) {
    const uint32_t start = c * kChunk, end = std::min(n_, start + kChunk);
    const uint32_t here = std::min(hi, end) - std::max(lo, start);
    if (done_[c].fetch_add(here, std::memory_order_acq_rel) + here != end - start) continue;
    if (spill_ != nullptr) spill_->StoreAt(0, kDoneList0, start, end);
#ifdef __linux__
    // Whole pages only: a chunk starts on a page (the lists are mapped), the last one ends in the
    // mapping's last page, which holds nothing else.
    constexpr size_t kPage = 4096;
    const size_t bytes = (size_t{end - start} * sizeof(uint32_t) + kPage - 1) / kPage * kPage;
    for (int l = 1; l < 6; ++l) madvise((*lists_)[l].data() + start, bytes, MADV_DONTNEED);
#endif
  }
}

}  // namespace mktree::build
