#include "storage/page_cache.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <memory>

namespace mktree {

namespace {
struct FreeDeleter {
  void operator()(uint8_t* p) const { std::free(p); }
};
using PageBuffer = std::unique_ptr<uint8_t, FreeDeleter>;
// Page buffers are 4096-aligned so that an O_DIRECT store can read straight into them.
PageBuffer AllocatePage(uint64_t bytes) {
  const uint64_t rounded = (bytes + 4095) / 4096 * 4096;
  return PageBuffer(static_cast<uint8_t*>(std::aligned_alloc(4096, rounded)));
}
// Spare frames kept past this many are freed: in steady state each miss takes one and its eviction gives
// one back, and Clear() should still return the memory of the pages it drops.
constexpr size_t kMaxSpareFrames = 8;
}  // namespace

// A frame lives in the table from its miss until its eviction; a frame whose read failed leaves the
// table at once and is freed by the last thread that held it. Every field but `verified` is guarded by
// the cache's mutex; `data` is written only by the loading thread before `loading` is cleared.
struct PageFrame {
  uint64_t page = 0;
  const uint8_t* bytes = nullptr;  // the page: `data`, or the store's mapping of it
  PageBuffer data;                 // allocated on the first miss the store cannot map
  int pins = 0;
  bool loading = true;
  bool failed = false;
  Status load_status;
  std::atomic<bool> verified{false};
  uint64_t load_id = 0;                              // set before the frame is handed out
  std::atomic<PageAttachment*> attachment{nullptr};  // owned; cleared only while unpinned, under the lock
  ~PageFrame() { delete attachment.load(std::memory_order_relaxed); }
  void DropAttachment() { delete attachment.exchange(nullptr, std::memory_order_acq_rel); }
};

PageHandle::PageHandle(PageHandle&& o) noexcept : cache_(o.cache_), frame_(o.frame_) {
  o.cache_ = nullptr;
  o.frame_ = nullptr;
}
PageHandle& PageHandle::operator=(PageHandle&& o) noexcept {
  if (this != &o) {
    Release();
    cache_ = o.cache_;
    frame_ = o.frame_;
    o.cache_ = nullptr;
    o.frame_ = nullptr;
  }
  return *this;
}
PageHandle::~PageHandle() { Release(); }
void PageHandle::Release() {
  if (frame_) cache_->Unpin(frame_);
  frame_ = nullptr;
  cache_ = nullptr;
}
const uint8_t* PageHandle::data() const { return frame_->bytes; }
uint64_t PageHandle::page() const { return frame_->page; }
bool PageHandle::verified() const { return frame_->verified.load(std::memory_order_acquire); }
void PageHandle::MarkVerified() { frame_->verified.store(true, std::memory_order_release); }
uint64_t PageHandle::load_id() const { return frame_->load_id; }
const PageAttachment* PageHandle::attachment() const {
  return frame_->attachment.load(std::memory_order_acquire);
}
const PageAttachment* PageHandle::Attach(std::unique_ptr<PageAttachment> a) {
  PageAttachment* expected = nullptr;
  if (frame_->attachment.compare_exchange_strong(expected, a.get(), std::memory_order_acq_rel,
                                                 std::memory_order_acquire))
    return a.release();
  return expected;  // `a` is deleted on return
}

PageCache::PageCache(const PageStore* store, size_t capacity_pages)
    : store_(store), capacity_(capacity_pages), table_(store->page_count()) {}

PageCache::~PageCache() {
  for (const Slot& s : table_) delete s.frame;
  for (PageFrame* f : spare_) delete f;
}

PageFrame* PageCache::NewFrameLocked(uint64_t page) {
  PageFrame* f;
  if (spare_.empty()) {
    f = new PageFrame;
  } else {
    f = spare_.back();
    spare_.pop_back();
  }
  f->page = page;
  f->pins = 1;
  f->loading = true;
  f->failed = false;
  f->load_status = Status::Ok();
  f->verified.store(false, std::memory_order_relaxed);
  f->DropAttachment();
  f->load_id = ++loads_;
  return f;
}

void PageCache::FreeFrameLocked(PageFrame* f) {
  f->DropAttachment();
  if (spare_.size() < kMaxSpareFrames)
    spare_.push_back(f);
  else
    delete f;
}

PageFrame* PageCache::LruFrameLocked(const LruEntry& e) const {
  // A slot's stamp is that of its frame's last unpin while the frame is unpinned, else 0.
  const Slot* s = e.page < table_.size() ? &table_[e.page] : nullptr;
  return s != nullptr && s->unpinned_at == e.stamp ? s->frame : nullptr;
}

void PageCache::CompactLruLocked() {
  // Unpinned resident frames have one live entry each; the rest are stale. Dropping them in place keeps
  // the order and costs O(1) per unpin over time.
  if (lru_.size() < 2 * (resident_ - std::min(resident_, pinned_)) + 64) return;
  std::erase_if(lru_, [this](const LruEntry& e) { return LruFrameLocked(e) == nullptr; });
}

Result<PageHandle> PageCache::Pin(uint64_t page, QueryStats* stats) {
  std::unique_lock<std::mutex> lock(mu_);
  ++counters_.lookups;
  if (stats) ++stats->pages_touched;
  if (page >= table_.size() && page < store_->page_count()) table_.resize(store_->page_count());
  if (PageFrame* f = page < table_.size() ? table_[page].frame : nullptr) {
    ++counters_.hits;
    if (stats) ++stats->cache_hits;
    if (f->pins++ == 0) {  // its LRU entry goes stale: it gets a new one when unpinned
      ++pinned_;
      table_[page].unpinned_at = 0;
    }
    loaded_.wait(lock, [&] { return !f->loading; });
    if (f->failed) {
      Status st = f->load_status;
      if (--f->pins == 0) {
        --pinned_;
        FreeFrameLocked(f);
      }
      return st;
    }
    return PageHandle(this, f);
  }

  ++counters_.misses;
  counters_.bytes_read += store_->page_bytes();
  if (stats) {
    ++stats->pages_read;
    stats->bytes_read += store_->page_bytes();
  }
  // Past the store's end: a miss that every backend refuses with this error; nothing to cache.
  if (page >= table_.size()) return PageOutOfRange(store_->name(), page, store_->page_count());
  PageFrame* f = NewFrameLocked(page);
  ++pinned_;
  table_[page] = {f, 0};
  ++resident_;
  EvictLocked();  // keep resident <= max(capacity, pinned)
  lock.unlock();

  // Read outside the lock so that other lookups (and misses on other pages) are not held up. A mapped
  // store needs no read: the miss still counts, as the page must come from the store (and be verified).
  Status st;
  if (const uint8_t* mapped = store_->MappedPage(page)) {
    f->bytes = mapped;
  } else {
    if (!f->data) f->data = AllocatePage(store_->page_bytes());
    f->bytes = f->data.get();
    st = store_->ReadPage(page, f->data.get());
  }

  lock.lock();
  f->loading = false;
  loaded_.notify_all();
  if (st.ok()) return PageHandle(this, f);
  // Waiters (woken once the lock is released) see the error; the frame leaves the table so that a later
  // lookup retries the read.
  f->failed = true;
  f->load_status = st;
  table_[page] = {};
  --resident_;
  if (--f->pins == 0) {
    --pinned_;
    FreeFrameLocked(f);
  }
  return st;
}

void PageCache::Unpin(PageFrame* f) {
  // Handles exist only for loaded frames, which stay in the table while pinned.
  std::lock_guard<std::mutex> lock(mu_);
  UnpinLocked(f);
  EvictLocked();
}

void PageCache::UnpinLocked(PageFrame* f) {
  if (--f->pins > 0) return;
  --pinned_;
  table_[f->page].unpinned_at = ++stamps_;
  lru_.push_back({f->page, stamps_});
}

void PageCache::EvictLocked() {
  while (resident_ > capacity_ && !lru_.empty()) {
    const LruEntry e = lru_.front();
    lru_.pop_front();
    PageFrame* victim = LruFrameLocked(e);
    if (victim == nullptr) continue;  // stale: pinned again since, or gone
    table_[victim->page] = {};
    --resident_;
    FreeFrameLocked(victim);
  }
  CompactLruLocked();
}

bool PageCache::PinCached(uint64_t first, uint64_t count, bool verified, QueryStats* stats,
                          std::vector<PageHandle>* out) {
  std::lock_guard<std::mutex> lock(mu_);
  if (first > table_.size() || count > table_.size() - first) return false;
  for (uint64_t p = first; p < first + count; ++p) {
    const PageFrame* f = table_[p].frame;
    if (f == nullptr || f->loading || (verified && !f->verified.load(std::memory_order_acquire)))
      return false;
  }
  for (uint64_t p = first; p < first + count; ++p) {
    PageFrame* f = table_[p].frame;
    PinHitLocked(p, f, stats, out);
  }
  return true;
}

void PageCache::PinHitLocked(uint64_t p, PageFrame* f, QueryStats* stats, std::vector<PageHandle>* out) {
  ++counters_.lookups;
  ++counters_.hits;
  if (stats) {
    ++stats->pages_touched;
    ++stats->cache_hits;
  }
  if (f->pins++ == 0) {
    ++pinned_;
    table_[p].unpinned_at = 0;
  }
  out->push_back(PageHandle(this, f));
}

size_t PageCache::PinCachedPages(std::span<const uint64_t> pages, bool verified, bool attached,
                                 QueryStats* stats, std::vector<PageHandle>* out) {
  std::lock_guard<std::mutex> lock(mu_);
  // The frames, then what the caller reads next (their attachments), are loaded side by side rather than
  // one miss after another.
  for (uint64_t p : pages)
    if (p < table_.size() && table_[p].frame != nullptr) __builtin_prefetch(table_[p].frame);
  for (uint64_t p : pages)
    if (p < table_.size() && table_[p].frame != nullptr)
      __builtin_prefetch(table_[p].frame->attachment.load(std::memory_order_relaxed));
  size_t n = 0;
  for (uint64_t p : pages) {
    PageFrame* f = p < table_.size() ? table_[p].frame : nullptr;
    if (f == nullptr || f->loading || (verified && !f->verified.load(std::memory_order_acquire)) ||
        (attached && f->attachment.load(std::memory_order_acquire) == nullptr))
      break;
    PinHitLocked(p, f, stats, out);
    ++n;
  }
  return n;
}

size_t PageCache::VisitCachedRuns(std::span<const PageRun> runs, bool verified,
                                  CallbackRef<bool(const PageAttachment*, std::span<const uint64_t>)> accept,
                                  CallbackRef<void(std::span<const PageAttachment* const>)> use,
                                  QueryStats* stats) {
  const PageAttachment* attached[kMaxVisitedRuns];
  uint64_t later[kMaxRunPages];
  const size_t m = std::min(runs.size(), kMaxVisitedRuns);
  std::lock_guard<std::mutex> lock(mu_);
  for (size_t k = 0; k < m; ++k)
    if (runs[k].first < table_.size() && table_[runs[k].first].frame != nullptr)
      __builtin_prefetch(table_[runs[k].first].frame);
  size_t n = 0;
  for (; n < m; ++n) {
    const PageRun& r = runs[n];
    if (r.count == 0 || r.count > kMaxRunPages || r.first >= table_.size() ||
        r.count > table_.size() - r.first)
      break;
    bool cached = true;
    for (uint64_t k = 0; cached && k < r.count; ++k) {
      const PageFrame* f = table_[r.first + k].frame;
      cached = f != nullptr && !f->loading && (!verified || f->verified.load(std::memory_order_acquire));
      if (cached && k > 0) later[k - 1] = f->load_id;
    }
    if (!cached) break;
    const PageAttachment* a = table_[r.first].frame->attachment.load(std::memory_order_acquire);
    if (a == nullptr || !accept(a, std::span<const uint64_t>(later, r.count - 1))) break;
    attached[n] = a;
  }
  if (n == 0) return 0;
  use(std::span<const PageAttachment* const>(attached, n));
  // Pinning and unpinning again leaves a page pinned by others as it was and gives an unpinned one the
  // next unpin stamp, in the order of the unpins.
  for (size_t k = 0; k < n; ++k) {
    const PageRun& r = runs[k];
    counters_.lookups += r.count;
    counters_.hits += r.count;
    if (stats) {
      stats->pages_touched += r.count;
      stats->cache_hits += r.count;
    }
    for (uint64_t p = r.first; p < r.first + r.count; ++p) {
      if (table_[p].frame->pins > 0) continue;
      table_[p].unpinned_at = ++stamps_;
      lru_.push_back({p, stamps_});
    }
  }
  EvictLocked();
  return n;
}

void PageCache::Release(std::span<PageHandle> handles) {
  if (handles.empty()) return;
  std::lock_guard<std::mutex> lock(mu_);
  for (PageHandle& h : handles) {
    if (h.frame_ == nullptr) continue;
    UnpinLocked(h.frame_);
    h.frame_ = nullptr;
    h.cache_ = nullptr;
    // Evicting after each unpin keeps the victims those of unpinning one handle at a time.
    EvictLocked();
  }
}

void PageCache::Clear() {
  std::lock_guard<std::mutex> lock(mu_);
  for (const LruEntry& e : lru_) {
    PageFrame* f = LruFrameLocked(e);
    if (f == nullptr) continue;
    table_[f->page] = {};
    --resident_;
    FreeFrameLocked(f);
  }
  lru_.clear();
}

PageCache::Counters PageCache::counters() const {
  std::lock_guard<std::mutex> lock(mu_);
  return counters_;
}
void PageCache::ResetCounters() {
  std::lock_guard<std::mutex> lock(mu_);
  counters_ = Counters();
}
size_t PageCache::resident_pages() const {
  std::lock_guard<std::mutex> lock(mu_);
  return resident_;
}
size_t PageCache::pinned_pages() const {
  std::lock_guard<std::mutex> lock(mu_);
  return pinned_;
}

}  // namespace mktree
