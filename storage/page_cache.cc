#include "storage/page_cache.h"

#include <cstdlib>
#include <vector>

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
}  // namespace

struct PageCache::Frame {
  uint64_t page = 0;
  PageBuffer data;
  int pins = 0;
  bool loading = true;
  Status load_status;
  std::list<Frame*>::iterator lru_pos;
  bool in_lru = false;
};

// PageHandle stores its frame type-erased so that the Frame type stays private to the cache.
PageHandle::PageHandle(PageCache* cache, std::shared_ptr<void> frame) : cache_(cache), frame_(std::move(frame)) {}
PageHandle::PageHandle(PageHandle&& o) noexcept : cache_(o.cache_), frame_(std::move(o.frame_)) { o.cache_ = nullptr; }
PageHandle& PageHandle::operator=(PageHandle&& o) noexcept {
  if (this != &o) {
    Release();
    cache_ = o.cache_;
    frame_ = std::move(o.frame_);
    o.cache_ = nullptr;
  }
  return *this;
}
PageHandle::~PageHandle() { Release(); }
void PageHandle::Release() {
  if (frame_) cache_->Unpin(std::static_pointer_cast<PageCache::Frame>(frame_));
  frame_.reset();
  cache_ = nullptr;
}
const uint8_t* PageHandle::data() const { return static_cast<PageCache::Frame*>(frame_.get())->data.get(); }
uint64_t PageHandle::page() const { return static_cast<PageCache::Frame*>(frame_.get())->page; }

PageCache::PageCache(const PageStore* store, size_t capacity_pages) : store_(store), capacity_(capacity_pages) {}
PageCache::~PageCache() = default;

Result<PageHandle> PageCache::Pin(uint64_t page, QueryStats* stats) {
  std::unique_lock<std::mutex> lock(mu_);
  ++counters_.lookups;
  if (stats) ++stats->pages_touched;
  auto it = frames_.find(page);
  if (it != frames_.end()) {
    std::shared_ptr<Frame> f = it->second;
    ++counters_.hits;
    if (stats) ++stats->cache_hits;
    if (f->in_lru) {
      lru_.erase(f->lru_pos);
      f->in_lru = false;
    }
    if (f->pins++ == 0) ++pinned_;
    loaded_.wait(lock, [&] { return !f->loading; });
    if (!f->load_status.ok()) {
      Status st = f->load_status;
      if (--f->pins == 0) --pinned_;
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
  auto f = std::make_shared<Frame>();
  f->page = page;
  f->pins = 1;
  ++pinned_;
  frames_.emplace(page, f);
  EvictLocked();  // keep resident <= max(capacity, pinned)
  lock.unlock();

  // Read outside the lock so that other lookups (and misses on other pages) are not held up.
  PageBuffer buf = AllocatePage(store_->page_bytes());
  Status st = store_->ReadPage(page, buf.get());

  lock.lock();
  f->loading = false;
  if (st.ok()) {
    f->data = std::move(buf);
  } else {
    // Waiters see the error; the frame leaves the table so that a later lookup retries the read.
    f->load_status = st;
    frames_.erase(page);
    if (--f->pins == 0) --pinned_;
  }
  loaded_.notify_all();
  if (!st.ok()) return st;
  return PageHandle(this, f);
}

void PageCache::Unpin(const std::shared_ptr<Frame>& f) {
  std::lock_guard<std::mutex> lock(mu_);
  if (--f->pins > 0) return;
  --pinned_;
  if (!f->load_status.ok()) return;  // failed frames are already out of the table
  lru_.push_front(f.get());
  f->lru_pos = lru_.begin();
  f->in_lru = true;
  EvictLocked();
}

void PageCache::EvictLocked() {
  while (frames_.size() > capacity_ && !lru_.empty()) {
    Frame* victim = lru_.back();
    lru_.pop_back();
    victim->in_lru = false;
    frames_.erase(victim->page);
  }
}

void PageCache::Clear() {
  std::lock_guard<std::mutex> lock(mu_);
  for (Frame* f : lru_) {
    f->in_lru = false;
    frames_.erase(f->page);
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
  return frames_.size();
}
size_t PageCache::pinned_pages() const {
  std::lock_guard<std::mutex> lock(mu_);
  return pinned_;
}

}  // namespace mktree
