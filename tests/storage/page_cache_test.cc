// PageCache: counters (hits + misses == lookups), LRU order, pinning, capacities 0 and 1, concurrency,
// and faults from the store (read errors, flipped bytes, short reads) surfacing as errors.
#include "storage/page_cache.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <random>
#include <thread>

#include "engine/store_format/leaf_reader.h"
#include "storage/memory_page_store.h"
#include "store_format/store_test_util.h"

namespace mktree {
namespace {

constexpr uint64_t kPage = 4096;

// A store whose page i is filled with byte (i % 251), and that counts reads.
class CountingStore : public MemoryPageStore {
 public:
  explicit CountingStore(uint64_t pages) : MemoryPageStore(kPage, "counting") {
    std::vector<uint8_t> p(kPage);
    for (uint64_t i = 0; i < pages; ++i) {
      std::fill(p.begin(), p.end(), static_cast<uint8_t>(i % 251));
      EXPECT_TRUE(WritePage(i, p.data()).ok());
    }
  }
  Status ReadPage(uint64_t index, uint8_t* out) const override {
    ++reads;
    if (slow) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    return MemoryPageStore::ReadPage(index, out);
  }
  mutable std::atomic<uint64_t> reads{0};
  bool slow = false;
};

void ExpectInvariants(const PageCache& c) {
  const auto k = c.counters();
  EXPECT_EQ(k.hits + k.misses, k.lookups);
  EXPECT_EQ(k.bytes_read, k.misses * kPage);
}

bool Resident(PageCache& c, uint64_t page) {
  // Pin and see whether it was a hit, without disturbing the counters' invariant.
  QueryStats s;
  auto h = c.Pin(page, &s);
  EXPECT_TRUE(h.ok());
  return s.cache_hits == 1;
}

TEST(PageCacheTest, HitsMissesAndStats) {
  CountingStore store(10);
  PageCache cache(&store, 4);
  QueryStats s;
  {
    auto a = cache.Pin(3, &s);
    ASSERT_TRUE(a.ok());
    EXPECT_EQ(a->data()[0], 3);
    EXPECT_EQ(a->data()[kPage - 1], 3);
    EXPECT_EQ(a->page(), 3u);
  }
  { ASSERT_TRUE(cache.Pin(3, &s).ok()); }
  { ASSERT_TRUE(cache.Pin(4, &s).ok()); }
  EXPECT_EQ(s.pages_touched, 3u);
  EXPECT_EQ(s.pages_read, 2u);
  EXPECT_EQ(s.cache_hits, 1u);
  EXPECT_EQ(s.bytes_read, 2 * kPage);
  EXPECT_EQ(s.cache_hits + s.pages_read, s.pages_touched);
  const auto k = cache.counters();
  EXPECT_EQ(k.lookups, 3u);
  EXPECT_EQ(k.hits, 1u);
  EXPECT_EQ(k.misses, 2u);
  EXPECT_EQ(store.reads.load(), 2u);
  ExpectInvariants(cache);
  EXPECT_TRUE(cache.Pin(1, nullptr).ok());  // stats optional
  ExpectInvariants(cache);
}

TEST(PageCacheTest, EvictsLeastRecentlyUsedDeterministically) {
  CountingStore store(10);
  PageCache cache(&store, 3);
  for (uint64_t p : {0, 1, 2}) ASSERT_TRUE(cache.Pin(p, nullptr).ok());
  ASSERT_TRUE(cache.Pin(0, nullptr).ok());  // 0 becomes most recent: order (old->new) 1, 2, 0
  ASSERT_TRUE(cache.Pin(3, nullptr).ok());  // evicts 1
  EXPECT_EQ(cache.resident_pages(), 3u);
  EXPECT_TRUE(Resident(cache, 2));   // order now 0, 3, 2
  EXPECT_TRUE(Resident(cache, 0));   // 3, 2, 0
  EXPECT_TRUE(Resident(cache, 3));   // 2, 0, 3
  EXPECT_FALSE(Resident(cache, 1));  // miss: evicts 2 -> 0, 3, 1
  EXPECT_FALSE(Resident(cache, 2));  // evicts 0 -> 3, 1, 2
  EXPECT_TRUE(Resident(cache, 3));
  EXPECT_FALSE(Resident(cache, 0));
  ExpectInvariants(cache);

  // The same sequence on a fresh cache produces the same counters (no randomness).
  PageCache again(&store, 3);
  for (uint64_t p : {0, 1, 2, 0, 3, 2, 0, 3, 1, 2, 3, 0}) ASSERT_TRUE(again.Pin(p, nullptr).ok());
  EXPECT_EQ(again.counters().hits, cache.counters().hits);
  EXPECT_EQ(again.counters().misses, cache.counters().misses);
}

TEST(PageCacheTest, PinnedPagesAreNeverEvicted) {
  CountingStore store(10);
  PageCache cache(&store, 2);
  auto a = cache.Pin(0, nullptr);
  auto b = cache.Pin(1, nullptr);
  auto c = cache.Pin(2, nullptr);  // over capacity while pinned
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ(cache.resident_pages(), 3u);
  EXPECT_EQ(cache.pinned_pages(), 3u);
  {
    auto a2 = cache.Pin(0, nullptr);  // a second pin of the same page is a hit
    ASSERT_TRUE(a2.ok());
    EXPECT_EQ(a2->data(), a->data());
  }
  EXPECT_EQ(cache.pinned_pages(), 3u);
  EXPECT_EQ(a->data()[0], 0);
  cache.Clear();  // drops nothing pinned
  EXPECT_EQ(cache.resident_pages(), 3u);
  a.value().Release();  // unpinned and over capacity: evicted at once
  EXPECT_EQ(cache.resident_pages(), 2u);
  EXPECT_EQ(b->data()[5], 1);
  EXPECT_EQ(c->data()[5], 2);
  PageHandle moved = std::move(b.value());
  EXPECT_FALSE(b.value());
  EXPECT_EQ(moved.data()[0], 1);
  moved = PageHandle();  // move-assign releases
  EXPECT_EQ(cache.pinned_pages(), 1u);
  cache.Clear();
  EXPECT_EQ(cache.resident_pages(), 1u);  // only the pinned page 2
  ExpectInvariants(cache);
}

TEST(PageCacheTest, CapacityZeroHoldsPagesOnlyWhilePinned) {
  CountingStore store(4);
  PageCache cache(&store, 0);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(cache.Pin(1, nullptr).ok());
  EXPECT_EQ(cache.counters().misses, 5u);
  EXPECT_EQ(cache.counters().hits, 0u);
  EXPECT_EQ(cache.resident_pages(), 0u);
  {
    auto h = cache.Pin(2, nullptr);
    auto h2 = cache.Pin(2, nullptr);  // pinned, so still there: a hit
    EXPECT_EQ(cache.resident_pages(), 1u);
    EXPECT_EQ(cache.counters().hits, 1u);
  }
  EXPECT_EQ(cache.resident_pages(), 0u);
  ExpectInvariants(cache);
}

TEST(PageCacheTest, CapacityOne) {
  CountingStore store(4);
  PageCache cache(&store, 1);
  for (uint64_t p : {0, 0, 1, 1, 0, 0}) ASSERT_TRUE(cache.Pin(p, nullptr).ok());
  EXPECT_EQ(cache.counters().misses, 3u);
  EXPECT_EQ(cache.counters().hits, 3u);
  EXPECT_EQ(cache.resident_pages(), 1u);
  ExpectInvariants(cache);
}

TEST(PageCacheTest, PagesAddedToTheStoreAfterTheCacheWasMadeAreCached) {
  CountingStore store(2);
  PageCache cache(&store, 4);
  auto past = cache.Pin(2, nullptr);
  ASSERT_FALSE(past.ok());
  EXPECT_NE(past.status().message().find("out of range"), std::string::npos) << past.status().message();
  std::vector<uint8_t> p(kPage, 9);
  ASSERT_TRUE(store.WritePage(2, p.data()).ok());
  for (int i = 0; i < 2; ++i) {
    auto h = cache.Pin(2, nullptr);
    ASSERT_TRUE(h.ok());
    EXPECT_EQ(h->data()[0], 9);
  }
  EXPECT_EQ(cache.counters().misses, 2u);  // the refused lookup, then one read
  EXPECT_EQ(cache.counters().hits, 1u);
  EXPECT_EQ(cache.resident_pages(), 1u);
  ExpectInvariants(cache);
}

TEST(PageCacheTest, ReadErrorsAreReportedAndRetried) {
  CountingStore base(4);
  FaultyPageStore faulty(&base);
  PageCache cache(&faulty, 4);
  faulty.FailNthRead(2);
  EXPECT_TRUE(cache.Pin(0, nullptr).ok());
  auto bad = cache.Pin(1, nullptr);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), Status::Code::kIOError);
  EXPECT_NE(bad.status().message().find("page 1"), std::string::npos);
  EXPECT_EQ(cache.resident_pages(), 1u);  // the failed page is not cached
  EXPECT_EQ(cache.pinned_pages(), 0u);
  auto good = cache.Pin(1, nullptr);  // a later lookup reads again
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(good->data()[0], 1);
  ExpectInvariants(cache);
  EXPECT_FALSE(cache.Pin(99, nullptr).ok());  // out of range
  ExpectInvariants(cache);
}

// A small built store in memory behind a FaultyPageStore, and its leaf 1.
class PageCacheFaultTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(testing::BuildTestStore(testing::MakeObjects(200, 4), {}, BuildParams(), &mem, &built).ok());
  }
  MemoryPageStore mem{12288, "mem.mkt"};
  testing::BuiltStore built;
  FaultyPageStore faulty{&mem};
};

TEST_F(PageCacheFaultTest, FlippedBytesAndShortReadsAreCorruptionNotWrongAnswers) {
  const LeafInfo& leaf = built.tree.leaves[1];
  auto parse = [&](PageCache& cache) -> Status {
    PinnedLeaf pinned;
    return ReadLeaf(cache, faulty.name(), 1, leaf, built.objects, mem.page_bytes(), true, nullptr, &pinned);
  };
  {
    PageCache cache(&faulty, 8);
    EXPECT_TRUE(parse(cache).ok());
  }
  faulty.FlipByte(leaf.first_page, 5000, 0x04);
  {
    PageCache cache(&faulty, 8);
    Status st = parse(cache);
    EXPECT_EQ(st.code(), Status::Code::kCorruption);
    EXPECT_NE(st.message().find("mem.mkt: page " + std::to_string(leaf.first_page)), std::string::npos)
        << st.message();
  }
  faulty.ClearFaults();
  faulty.ShortRead(leaf.first_page, 100);
  {
    PageCache cache(&faulty, 8);
    EXPECT_EQ(parse(cache).code(), Status::Code::kCorruption);
  }
}

TEST(PageCacheTest, VerifiedFlagLastsAsLongAsTheCachedCopy) {
  CountingStore store(4);
  PageCache cache(&store, 1);
  {
    auto h = cache.Pin(0, nullptr);
    ASSERT_TRUE(h.ok());
    EXPECT_FALSE(h->verified());  // fresh from the store
    h->MarkVerified();
    auto again = cache.Pin(0, nullptr);  // a second pin sees the same copy
    EXPECT_TRUE(again->verified());
  }
  {
    auto h = cache.Pin(0, nullptr);  // a hit: still verified
    EXPECT_TRUE(h->verified());
  }
  { ASSERT_TRUE(cache.Pin(1, nullptr).ok()); }  // evicts 0
  {
    auto h = cache.Pin(0, nullptr);  // read again (its frame may be a recycled one): not verified
    EXPECT_FALSE(h->verified());
    EXPECT_EQ(h->data()[7], 0);
  }
  cache.Clear();
  auto h = cache.Pin(0, nullptr);
  EXPECT_FALSE(h->verified());
  EXPECT_EQ(store.reads.load(), 4u);
  ExpectInvariants(cache);
}

// Checksums are verified once per load into the cache, yet a corrupt page is refused on every read, hit
// or miss, and a clean page is never hashed again while it stays cached.
TEST_F(PageCacheFaultTest, ChecksumsAreVerifiedOncePerLoadAndCorruptPagesAlwaysRefused) {
  const LeafInfo& leaf = built.tree.leaves[1];
  ASSERT_EQ(leaf.page_count, 1u);
  const uint64_t page_bytes = mem.page_bytes();
  PageCache cache(&faulty, 8);
  PinnedLeaf pinned;  // reused across reads, as queries do
  QueryStats s;
  ASSERT_TRUE(ReadLeaf(cache, faulty.name(), 1, leaf, built.objects, page_bytes, true, &s, &pinned).ok());
  EXPECT_EQ(pinned.view.size(), leaf.object_count);
  pinned.Release();
  EXPECT_EQ(cache.pinned_pages(), 0u);
  {
    auto h = cache.Pin(leaf.first_page, nullptr);
    EXPECT_TRUE(h->verified());
  }

  faulty.FlipByte(leaf.first_page, 5000, 0x04);
  cache.Clear();  // the next read loads the corrupt copy
  for (int round = 0; round < 3; ++round) {
    QueryStats r;
    Status st = ReadLeaf(cache, faulty.name(), 1, leaf, built.objects, page_bytes, true, &r, &pinned);
    EXPECT_EQ(st.code(), Status::Code::kCorruption) << "round " << round;
    EXPECT_NE(st.message().find("checksum mismatch"), std::string::npos) << st.message();
    EXPECT_EQ(r.pages_touched, 1u);
    EXPECT_EQ(r.pages_read, round == 0 ? 1u : 0u);  // cached once, refused on every hit too
    EXPECT_EQ(r.cache_hits + r.pages_read, r.pages_touched);
    EXPECT_EQ(pinned.view.size(), 0u);
    EXPECT_TRUE(pinned.pages.empty());
  }
  EXPECT_EQ(cache.pinned_pages(), 0u);
  // Without verification the flipped geometry byte goes unnoticed and the page is not marked verified.
  ASSERT_TRUE(
      ReadLeaf(cache, faulty.name(), 1, leaf, built.objects, page_bytes, false, nullptr, &pinned).ok());
  EXPECT_FALSE(pinned.pages[0].verified());
  pinned.Release();
  faulty.ClearFaults();
  cache.Clear();
  ASSERT_TRUE(
      ReadLeaf(cache, faulty.name(), 1, leaf, built.objects, page_bytes, true, nullptr, &pinned).ok());
  EXPECT_TRUE(pinned.pages[0].verified());
  const auto k = cache.counters();
  EXPECT_EQ(k.hits + k.misses, k.lookups);
}

TEST(PageCacheTest, ConcurrentPinsReadEachPageOnceAndKeepCountersExact) {
  CountingStore store(64);
  store.slow = true;  // widen the window in which threads miss on the same page
  PageCache cache(&store, 64);
  constexpr int kThreads = 8;
  std::vector<std::thread> threads;
  std::atomic<int> wrong{0};
  std::vector<QueryStats> stats(kThreads);
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      for (int round = 0; round < 3; ++round)
        for (uint64_t p = 0; p < 64; ++p) {
          auto h = cache.Pin(p, &stats[t]);
          if (!h.ok() || h->data()[100] != p % 251) ++wrong;
        }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(store.reads.load(), 64u);  // each page read once although all threads missed on it
  const auto k = cache.counters();
  EXPECT_EQ(k.lookups, uint64_t{kThreads} * 3 * 64);
  EXPECT_EQ(k.misses, 64u);
  ExpectInvariants(cache);
  QueryStats sum;
  for (const auto& s : stats) sum += s;
  EXPECT_EQ(sum.pages_touched, k.lookups);
  EXPECT_EQ(sum.pages_read, k.misses);
  EXPECT_EQ(sum.cache_hits, k.hits);
}

TEST(PageCacheTest, ConcurrentPinsUnderEvictionPressure) {
  CountingStore store(50);
  PageCache cache(&store, 5);
  std::vector<std::thread> threads;
  std::atomic<int> wrong{0};
  for (int t = 0; t < 6; ++t)
    threads.emplace_back([&, t] {
      std::mt19937 g(t);
      for (int i = 0; i < 3000; ++i) {
        const uint64_t a = g() % 50, b = g() % 50;
        auto ha = cache.Pin(a, nullptr);
        auto hb = cache.Pin(b, nullptr);
        if (!ha.ok() || !hb.ok() || ha->data()[7] != a % 251 || hb->data()[4000] != b % 251) ++wrong;
      }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(cache.pinned_pages(), 0u);
  EXPECT_LE(cache.resident_pages(), 5u);
  ExpectInvariants(cache);
  EXPECT_EQ(store.reads.load(), cache.counters().misses);
}

// The LRU order against a model (a list of unpinned pages, most recent first, and pin counts): random
// pins, releases one at a time or in batches, PinCached and Clear at capacities 0 to 9, with the LRU
// queue's stale entries compacted along the way. After each step the resident pages are the model's.
TEST(PageCacheTest, LruOrderMatchesAModelUnderPinCachedAndBatchReleases) {
  for (size_t capacity : {0u, 1u, 2u, 5u, 9u}) {
    SCOPED_TRACE("capacity " + std::to_string(capacity));
    constexpr uint64_t kPages = 16;
    CountingStore store(kPages);
    PageCache cache(&store, capacity);
    std::vector<uint64_t> lru;         // model: unpinned resident pages, most recently unpinned first
    std::vector<int> pins(kPages, 0);  // model: pins per page
    std::vector<bool> resident(kPages, false);
    std::vector<std::pair<uint64_t, PageHandle>> held;
    std::mt19937 g(static_cast<unsigned>(capacity) + 1);
    auto evict = [&] {
      size_t n = 0;
      for (bool r : resident) n += r;
      while (n > capacity && !lru.empty()) {
        resident[lru.back()] = false;
        lru.pop_back();
        --n;
      }
    };
    auto pinned_model = [&](uint64_t p) {
      if (pins[p]++ == 0) lru.erase(std::remove(lru.begin(), lru.end(), p), lru.end());
    };
    auto unpinned_model = [&](uint64_t p) {
      if (--pins[p] == 0) lru.insert(lru.begin(), p);
      evict();
    };
    for (int step = 0; step < 4000; ++step) {
      const unsigned op = g() % 10;
      if (op < 4 && held.size() < 6) {  // Pin
        const uint64_t p = g() % kPages;
        QueryStats s;
        auto h = cache.Pin(p, &s);
        ASSERT_TRUE(h.ok());
        EXPECT_EQ(s.cache_hits == 1, static_cast<bool>(resident[p])) << "step " << step;
        pinned_model(p);
        if (!resident[p]) {
          resident[p] = true;
          evict();
        }
        held.emplace_back(p, std::move(*h));
      } else if (op < 5 && held.size() < 6) {  // PinCachedPages of 1-3 pages anywhere
        uint64_t pages[3];
        const size_t m = 1 + g() % 3;
        for (size_t k = 0; k < m; ++k) pages[k] = g() % kPages;
        size_t expect = 0;
        while (expect < m && resident[pages[expect]]) ++expect;
        QueryStats s;
        std::vector<PageHandle> hs;
        ASSERT_EQ(cache.PinCachedPages(std::span<const uint64_t>(pages, m), false, false, &s, &hs), expect);
        EXPECT_EQ(s.cache_hits, expect);
        EXPECT_EQ(s.pages_touched, expect);
        for (size_t k = 0; k < expect; ++k) {
          pinned_model(pages[k]);
          held.emplace_back(pages[k], std::move(hs[k]));
        }
      } else if (op < 6 && held.size() < 6) {  // PinCached of a run of 1-3 pages
        const uint64_t first = g() % kPages;
        const uint64_t count = std::min<uint64_t>(1 + g() % 3, kPages - first);
        bool all = true;
        for (uint64_t p = first; p < first + count; ++p) all = all && resident[p];
        QueryStats s;
        std::vector<PageHandle> hs;
        const auto before = cache.counters();
        ASSERT_EQ(cache.PinCached(first, count, false, &s, &hs), all) << "step " << step;
        if (!all) {
          EXPECT_TRUE(hs.empty());
          EXPECT_EQ(s.pages_touched, 0u);
          EXPECT_EQ(cache.counters().lookups, before.lookups);
          continue;
        }
        EXPECT_EQ(s.cache_hits, count);
        EXPECT_EQ(s.pages_touched, count);
        for (uint64_t p = first; p < first + count; ++p) {
          pinned_model(p);
          EXPECT_EQ(hs[p - first].page(), p);
          held.emplace_back(p, std::move(hs[p - first]));
        }
      } else if (op < 8 && !held.empty()) {  // release one
        const size_t i = g() % held.size();
        unpinned_model(held[i].first);
        held[i].second.Release();
        held.erase(held.begin() + static_cast<std::ptrdiff_t>(i));
      } else if (op < 9 && !held.empty()) {  // release the last few at once, in order
        const size_t k = 1 + g() % held.size();
        std::vector<PageHandle> batch;
        for (size_t i = held.size() - k; i < held.size(); ++i) {
          unpinned_model(held[i].first);
          batch.push_back(std::move(held[i].second));
        }
        held.resize(held.size() - k);
        cache.Release(batch);
        for (const PageHandle& h : batch) EXPECT_FALSE(h);
      } else if (g() % 8 == 0) {
        cache.Clear();
        for (uint64_t p : lru) resident[p] = false;
        lru.clear();
      }
      size_t n = 0, pinned = 0;
      for (uint64_t p = 0; p < kPages; ++p) {
        n += resident[p];
        pinned += pins[p] > 0;
      }
      ASSERT_EQ(cache.resident_pages(), n) << "step " << step;
      ASSERT_EQ(cache.pinned_pages(), pinned) << "step " << step;
    }
    for (auto& [p, h] : held) {
      unpinned_model(p);
      h.Release();
    }
    held.clear();
    for (uint64_t p = 0; p < kPages; ++p) {
      if (!resident[p]) continue;
      std::vector<PageHandle> hs;
      EXPECT_TRUE(cache.PinCached(p, 1, false, nullptr, &hs)) << p;
    }
    ExpectInvariants(cache);
  }
}

// PinCached refuses a run with a page not yet verified when asked to (the caller then verifies it);
// PinCachedPages pins up to the first page not cached, verified or attached as asked.
TEST(PageCacheTest, PinCachedCanRequireVerifiedPages) {
  CountingStore store(4);
  PageCache cache(&store, 4);
  for (uint64_t p = 0; p < 3; ++p) {
    auto h = cache.Pin(p, nullptr);
    ASSERT_TRUE(h.ok());
    if (p != 1) h->MarkVerified();
  }
  std::vector<PageHandle> hs;
  EXPECT_FALSE(cache.PinCached(0, 3, true, nullptr, &hs));
  EXPECT_TRUE(cache.PinCached(0, 3, false, nullptr, &hs));
  EXPECT_EQ(hs.size(), 3u);
  EXPECT_FALSE(cache.PinCached(2, 2, false, nullptr, &hs));  // page 3 is not cached
  EXPECT_FALSE(cache.PinCached(3, 5, false, nullptr, &hs));  // past the store's end
  EXPECT_EQ(hs.size(), 3u);
  // PinCachedPages stops at the first page that fails: unverified (1), not attached (2), not cached (3).
  const uint64_t order[] = {0, 2, 1, 3};
  EXPECT_EQ(cache.PinCachedPages(order, true, false, nullptr, &hs), 2u);
  EXPECT_EQ(cache.PinCachedPages(order, false, false, nullptr, &hs), 3u);
  EXPECT_EQ(cache.PinCachedPages(order, false, true, nullptr, &hs), 0u);
  hs[0].Attach(std::make_unique<PageAttachment>());
  EXPECT_EQ(cache.PinCachedPages(order, false, true, nullptr, &hs), 1u);
  EXPECT_EQ(hs.size(), 9u);
  cache.Release(hs);
  EXPECT_EQ(cache.pinned_pages(), 0u);
}

// VisitCachedRuns leaves a cache as pinning the visited runs' pages in order and releasing them in order
// does: two caches, one visiting and one pinning, take the same random lookups, attachments, held pins and
// visits, and agree on every hit, read and statistic, so they evict the same pages in the same order.
TEST(PageCacheTest, VisitCachedRunsCountsAndOrdersAsPinAndRelease) {
  constexpr uint64_t kPages = 24;
  struct Tag : PageAttachment {
    explicit Tag(uint64_t p) : page(p) {}
    uint64_t page;
  };
  for (size_t capacity : {size_t{0}, size_t{3}, size_t{7}, size_t{30}}) {
    SCOPED_TRACE("capacity " + std::to_string(capacity));
    CountingStore store_a(kPages), store_b(kPages);
    PageCache a(&store_a, capacity), b(&store_b, capacity);
    std::mt19937 g(static_cast<unsigned>(capacity) + 7);
    std::vector<PageHandle> held_a, held_b;  // pins others hold while runs are visited
    for (int step = 0; step < 3000; ++step) {
      const unsigned op = g() % 10;
      if (op < 4) {  // a lookup, perhaps leaving an attachment (the first page of a run, as a reader would)
        const uint64_t p = g() % kPages;
        QueryStats sa, sb;
        auto ha = a.Pin(p, &sa);
        auto hb = b.Pin(p, &sb);
        ASSERT_TRUE(ha.ok() && hb.ok());
        ASSERT_EQ(sa.pages_read, sb.pages_read) << "step " << step;
        if (g() % 3 != 0) {
          ha->Attach(std::make_unique<Tag>(p));
          hb->Attach(std::make_unique<Tag>(p));
        }
        if (op == 0 && held_a.size() < 3) {
          held_a.push_back(std::move(*ha));
          held_b.push_back(std::move(*hb));
        }
      } else if (op < 5 && !held_a.empty()) {
        a.Release(held_a);
        b.Release(held_b);
        held_a.clear();
        held_b.clear();
      } else {  // 1-5 runs of 1-3 pages
        PageCache::PageRun runs[5];
        const size_t m = 1 + g() % 5;
        for (size_t k = 0; k < m; ++k) {
          runs[k].first = g() % kPages;
          runs[k].count = std::min<uint64_t>(1 + g() % 3, kPages - runs[k].first);
        }
        QueryStats sa, sb;
        std::vector<uint64_t> seen;
        auto accept = [&](const PageAttachment* t, std::span<const uint64_t> later) {
          EXPECT_EQ(later.size(), runs[seen.size()].count - 1);
          seen.push_back(static_cast<const Tag*>(t)->page);
          return true;
        };
        size_t used = 0;
        auto use = [&](std::span<const PageAttachment* const> ts) { used = ts.size(); };
        const size_t n =
            a.VisitCachedRuns(std::span<const PageCache::PageRun>(runs, m), false, accept, use, &sa);
        ASSERT_EQ(used, n);
        std::vector<PageHandle> hs;
        for (size_t k = 0; k < n; ++k) {
          EXPECT_EQ(seen[k], runs[k].first);
          ASSERT_TRUE(b.PinCached(runs[k].first, runs[k].count, false, &sb, &hs)) << "step " << step;
          ASSERT_NE(hs[hs.size() - runs[k].count].attachment(), nullptr);
        }
        b.Release(hs);
        EXPECT_EQ(sa.pages_touched, sb.pages_touched);
        EXPECT_EQ(sa.cache_hits, sb.cache_hits);
        EXPECT_EQ(sa.pages_read, 0u);
      }
      ASSERT_EQ(a.resident_pages(), b.resident_pages()) << "step " << step;
      ASSERT_EQ(a.pinned_pages(), b.pinned_pages()) << "step " << step;
      ASSERT_EQ(store_a.reads.load(), store_b.reads.load()) << "step " << step;
      const auto ka = a.counters(), kb = b.counters();
      ASSERT_EQ(ka.lookups, kb.lookups);
      ASSERT_EQ(ka.hits, kb.hits);
    }
    a.Release(held_a);
    b.Release(held_b);
    for (uint64_t p = 0; p < kPages; ++p) EXPECT_EQ(Resident(a, p), Resident(b, p)) << p;
    ExpectInvariants(a);
  }
}

// VisitCachedRuns stops at the first run with a page not cached or not verified (as asked), a first page
// without an attachment, or an attachment `accept` refuses; a failing first run counts nothing.
TEST(PageCacheTest, VisitCachedRunsStopsAtTheFirstRunItCannotUse) {
  CountingStore store(8);
  PageCache cache(&store, 8);
  for (uint64_t p = 0; p < 6; ++p) {
    auto h = cache.Pin(p, nullptr);
    ASSERT_TRUE(h.ok());
    if (p != 3) h->MarkVerified();
    if (p % 2 == 0) h->Attach(std::make_unique<PageAttachment>());
  }
  const auto before = cache.counters();
  auto yes = [](const PageAttachment*, std::span<const uint64_t>) { return true; };
  auto no = [](const PageAttachment*, std::span<const uint64_t>) { return false; };
  size_t used = 0;
  auto use = [&](std::span<const PageAttachment* const> ts) { used = ts.size(); };
  using Run = PageCache::PageRun;
  QueryStats s;
  EXPECT_EQ(cache.VisitCachedRuns(std::vector<Run>{{0, 2}, {2, 2}, {4, 2}}, true, yes, use, &s), 1u);  // 3
  EXPECT_EQ(used, 1u);
  EXPECT_EQ(s.cache_hits, 2u);
  EXPECT_EQ(cache.VisitCachedRuns(std::vector<Run>{{0, 2}, {2, 2}, {4, 2}}, false, yes, use, &s), 3u);
  EXPECT_EQ(s.cache_hits, 8u);
  EXPECT_EQ(s.pages_touched, 8u);
  EXPECT_EQ(cache.VisitCachedRuns(std::vector<Run>{{0, 2}, {4, 3}}, false, yes, use, &s), 1u);  // 6 missing
  EXPECT_EQ(cache.VisitCachedRuns(std::vector<Run>{{1, 1}, {2, 1}}, false, yes, use, &s), 0u);  // 1: none
  EXPECT_EQ(cache.VisitCachedRuns(std::vector<Run>{{7, 1}}, false, yes, use, &s), 0u);          // not cached
  EXPECT_EQ(cache.VisitCachedRuns(std::vector<Run>{{6, 9}}, false, yes, use, &s), 0u);  // past the end
  used = 99;
  EXPECT_EQ(cache.VisitCachedRuns(std::vector<Run>{{0, 1}}, false, no, use, &s), 0u);
  EXPECT_EQ(used, 99u);  // not called
  EXPECT_EQ(s.cache_hits, 10u);
  EXPECT_EQ(cache.counters().lookups - before.lookups, 10u);
  EXPECT_EQ(cache.pinned_pages(), 0u);
  ExpectInvariants(cache);
}

// Threads pin runs with PinCached and PinCachedPages and release in batches while others miss and evict.
TEST(PageCacheTest, ConcurrentPinCachedAndBatchReleases) {
  CountingStore store(40);
  PageCache cache(&store, 8);
  std::vector<std::thread> threads;
  std::atomic<int> wrong{0};
  for (int t = 0; t < 6; ++t)
    threads.emplace_back([&, t] {
      std::mt19937 g(t + 100);
      std::vector<PageHandle> hs;
      for (int i = 0; i < 3000; ++i) {
        const uint64_t first = g() % 39, count = 1 + g() % 2;
        if (t % 3 == 0) {
          auto h = cache.Pin(first, nullptr);
          if (!h.ok() || h->data()[9] != first % 251) ++wrong;
          continue;
        }
        if (t % 3 == 1) {
          if (cache.PinCached(first, count, false, nullptr, &hs))
            for (uint64_t k = 0; k < count; ++k)
              if (hs[hs.size() - count + k].data()[100] != (first + k) % 251) ++wrong;
        } else {
          const uint64_t pages[3] = {first, (first + 7) % 40, (first + 3) % 40};
          const size_t n = cache.PinCachedPages(pages, false, false, nullptr, &hs);
          for (size_t k = 0; k < n; ++k)
            if (hs[hs.size() - n + k].data()[100] != pages[k] % 251) ++wrong;
        }
        if (hs.size() > 4) {
          cache.Release(hs);
          hs.clear();
        }
      }
      cache.Release(hs);
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(cache.pinned_pages(), 0u);
  EXPECT_LE(cache.resident_pages(), 8u);
  ExpectInvariants(cache);
  EXPECT_EQ(store.reads.load(), cache.counters().misses);
}

}  // namespace
}  // namespace mktree
