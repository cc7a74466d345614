// PageCache: an LRU cache of leaf pages between queries and a PageStore. A miss is one page read from
// the store, i.e. one disk access (docs/design.md §8.3).
//
// - Capacity is in pages. A pinned page (a live PageHandle) is never evicted; while pages are pinned the
//   cache may hold more than `capacity` pages, and evicts down to capacity as they are unpinned.
//   Capacity 0: every lookup of an unpinned page is a miss; a page is held only while pinned.
// - Eviction is deterministic: the least recently unpinned page goes first. The order is a queue of
//   (page, unpin stamp) entries rather than a linked list of frames, so that a hit touches no other
//   frame; entries of pages pinned again since go stale and are skipped or dropped.
// - Counters: lookups == hits + misses always; bytes_read == misses * page_bytes. A lookup that waits for
//   another thread's in-flight read of the same page counts as a hit (it costs no disk access): concurrent
//   misses on one page read it once.
// - Each cached copy carries a `verified` flag for its reader (e.g. "checksum checked"): it is cleared
//   whenever the page is read from the store, so a reader verifies a page once per load, not per pin.
// - Each cached copy may carry one attachment: a reader's decoded form of the page (e.g. a leaf's entries
//   as arrays). It is dropped with the copy (eviction, Clear, a failed load), so it lives exactly as long
//   as the bytes it was decoded from, and a reload starts without one. Each load has a number (load_id),
//   unique within the cache, so that a reader decoding several pages can tell that none was reloaded since.
// - Memory: the cached pages and their attachments, plus 16 bytes per page of the store (the page table: a
//   lookup is one index) and at most 32 bytes per cached page for the LRU order.
// Thread safety: all methods may be called from many threads at once. Store reads run outside the cache's
// lock, so misses on different pages proceed in parallel (as far as the store allows).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "mktree/query_stats.h"
#include "mktree/status.h"
#include "storage/page_store.h"

namespace mktree {

class PageCache;
struct PageFrame;  // one cached page; private to page_cache.cc

// A reference to a callable that outlives the call it is passed to: no copy, no allocation.
template <typename Signature>
class CallbackRef;
template <typename R, typename... Args>
class CallbackRef<R(Args...)> {
 public:
  template <typename F>
  requires(!std::is_same_v<std::remove_cvref_t<F>, CallbackRef>)
      CallbackRef(F&& f)  // NOLINT(google-explicit-constructor): passed as a lambda
      : object_(const_cast<void*>(static_cast<const void*>(&f))), call_([](void* o, Args... a) -> R {
          return (*static_cast<std::remove_reference_t<F>*>(o))(std::forward<Args>(a)...);
        }) {}
  R operator()(Args... a) const { return call_(object_, std::forward<Args>(a)...); }

 private:
  void* object_;
  R (*call_)(void*, Args...);
};

// What a reader attaches to a cached page (PageHandle::Attach). Deleted by the cache when the page's copy
// leaves it, never while the page is pinned.
class PageAttachment {
 public:
  virtual ~PageAttachment() = default;
};

// Pins one cached page while alive. Move-only; unpins in its destructor.
class PageHandle {
 public:
  PageHandle() = default;
  PageHandle(PageHandle&& o) noexcept;
  PageHandle& operator=(PageHandle&& o) noexcept;
  PageHandle(const PageHandle&) = delete;
  PageHandle& operator=(const PageHandle&) = delete;
  ~PageHandle();

  const uint8_t* data() const;
  uint64_t page() const;
  explicit operator bool() const { return frame_ != nullptr; }
  void Release();  // unpin now

  // Whether a reader has marked this copy of the page verified since it was read from the store. Any
  // number of threads may read and mark the same page at once.
  bool verified() const;
  // REQUIRES: the page's bytes passed the reader's checks.
  void MarkVerified();

  // This copy's load number: differs after every read of the page from the store.
  uint64_t load_id() const;
  // The attachment of this copy of the page, or null. Valid while the page is pinned.
  const PageAttachment* attachment() const;
  // Attaches `a` to this copy unless it has one already; returns the copy's attachment (`a`, or the one
  // another thread attached first, `a` being deleted then). Any number of threads may call it at once.
  const PageAttachment* Attach(std::unique_ptr<PageAttachment> a);

 private:
  friend class PageCache;
  PageHandle(PageCache* cache, PageFrame* frame) : cache_(cache), frame_(frame) {}
  PageCache* cache_ = nullptr;
  PageFrame* frame_ = nullptr;
};

class PageCache {
 public:
  // REQUIRES: `store` outlives the cache and every handle it hands out; the cache outlives its handles.
  PageCache(const PageStore* store, size_t capacity_pages);
  ~PageCache();
  PageCache(const PageCache&) = delete;
  PageCache& operator=(const PageCache&) = delete;

  // Returns the page pinned. On a miss reads it from the store. Adds to *stats (if non-null):
  // pages_touched always; cache_hits on a hit; pages_read and bytes_read on a miss.
  Result<PageHandle> Pin(uint64_t page, QueryStats* stats);
  // Pins pages [first, first + count) if every one is cached and loaded (and, with `verified`, marked
  // verified), appending their handles to *out in order and counting each as Pin counts a hit; else pins
  // and counts nothing and returns false. One lock for the lot: the warm path of a leaf read.
  bool PinCached(uint64_t first, uint64_t count, bool verified, QueryStats* stats,
                 std::vector<PageHandle>* out);
  // Pins pages[0], pages[1], ... in order as long as each is cached and loaded (with `verified`, marked
  // verified; with `attached`, carrying an attachment), appending their handles to *out and counting each
  // as Pin counts a hit; returns how many it pinned (the first that fails the test is not counted). One
  // lock for the lot, the frames prefetched first.
  size_t PinCachedPages(std::span<const uint64_t> pages, bool verified, bool attached, QueryStats* stats,
                        std::vector<PageHandle>* out);
  // Pages [first, first + count) that a reader reads together (a leaf's).
  struct PageRun {
    uint64_t first = 0;
    uint64_t count = 0;
  };
  static constexpr size_t kMaxVisitedRuns = 16;
  static constexpr size_t kMaxRunPages = 64;
  // The warm path of reading a few runs without pinning them: from runs[0] on, up to kMaxVisitedRuns runs of
  // at most kMaxRunPages pages, as long as every page of a run is cached and loaded (with `verified`,
  // marked verified), its first page carries an attachment and accept(attachment, load ids of the run's
  // later pages) says it is current; then calls use(their attachments) once, with the cache's lock held,
  // and counts each page of those runs as Pin counts a hit. Counters, statistics and the LRU order are
  // those of pinning the runs' pages in order and then unpinning them in the same order. `use` must not
  // call into the cache; the attachments are valid only during it. Returns how many runs it visited; 0
  // (nothing counted, `use` not called) when the first run fails.
  size_t VisitCachedRuns(std::span<const PageRun> runs, bool verified,
                         CallbackRef<bool(const PageAttachment*, std::span<const uint64_t>)> accept,
                         CallbackRef<void(std::span<const PageAttachment* const>)> use, QueryStats* stats);
  // Unpins `handles` (this cache's, or empty) in order under one lock, as their Release() one after
  // another would, leaving them empty.
  void Release(std::span<PageHandle> handles);
  // Drops every unpinned page (for cold queries). Counters are kept.
  void Clear();

  struct Counters {
    uint64_t lookups = 0, hits = 0, misses = 0, bytes_read = 0;
  };
  Counters counters() const;
  void ResetCounters();
  size_t capacity() const { return capacity_; }
  size_t resident_pages() const;  // pages held now, pinned or not
  size_t pinned_pages() const;
  const PageStore& store() const { return *store_; }

 private:
  friend class PageHandle;
  struct LruEntry {
    uint64_t page;
    uint64_t stamp;
  };
  // A hit on cached page p (frame f) pinned into `out`; under mu_.
  void PinHitLocked(uint64_t p, PageFrame* f, QueryStats* stats, std::vector<PageHandle>* out);
  void Unpin(PageFrame* f);
  void UnpinLocked(PageFrame* f);
  PageFrame* NewFrameLocked(uint64_t page);
  void FreeFrameLocked(PageFrame* f);
  // The frame `e` stands for if it is still that page's unpinned copy of that unpin, else null.
  PageFrame* LruFrameLocked(const LruEntry& e) const;
  void CompactLruLocked();
  void EvictLocked();

  const PageStore* store_;
  const size_t capacity_;
  mutable std::mutex mu_;
  std::condition_variable loaded_;
  // The page table, indexed by page (the store's page count, grown if the store grows): the resident
  // frames, owned; a frame whose load failed leaves it at once.
  struct Slot {
    PageFrame* frame = nullptr;
    uint64_t unpinned_at = 0;  // the stamp of the frame's last unpin while it is unpinned, else 0
  };
  std::vector<Slot> table_;
  size_t resident_ = 0;
  // One entry per unpin, oldest first: the victim is the first entry whose page is still resident,
  // unpinned, and unpinned last at that stamp.
  std::deque<LruEntry> lru_;
  uint64_t stamps_ = 0;
  // Frames (with their page buffers) kept from evictions for the next misses: a miss in a full cache
  // then allocates nothing.
  std::vector<PageFrame*> spare_;
  size_t pinned_ = 0;
  uint64_t loads_ = 0;  // load_id of the last load
  Counters counters_;
};

}  // namespace mktree
