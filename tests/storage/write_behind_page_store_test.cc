#include "storage/write_behind_page_store.h"

#include <gtest/gtest.h>

#include <mutex>
#include <thread>
#include <vector>

#include "storage/memory_page_store.h"
#include "storage/paged_file_store.h"
#include "test_dirs.h"

namespace mktree {
namespace {

constexpr uint64_t kSmallPage = 512;

std::vector<uint8_t> PageOf(uint64_t index, uint8_t salt = 0) {
  std::vector<uint8_t> p(kSmallPage);
  for (uint64_t i = 0; i < kSmallPage; ++i) p[i] = static_cast<uint8_t>(index * 31 + i + salt);
  return p;
}

// Records the calls the base receives (and from which thread); fails the `fail_at`-th write.
class RecordingStore : public PageStore {
 public:
  uint64_t page_bytes() const override { return kSmallPage; }
  uint64_t page_count() const override { return memory.page_count(); }
  Status ReadPage(uint64_t index, uint8_t* out) const override { return memory.ReadPage(index, out); }
  Status WritePage(uint64_t index, const uint8_t* data) override {
    std::lock_guard<std::mutex> lock(mu);
    threads.push_back(std::this_thread::get_id());
    if (++writes == fail_at) return Status::IOError("base: page " + std::to_string(index) + ": disk full");
    order.push_back(index);
    return memory.WritePage(index, data);
  }
  Status Sync() override {
    ++syncs;
    return Status::Ok();
  }
  const std::string& name() const override { return memory.name(); }

  MemoryPageStore memory{kSmallPage, "base"};
  std::mutex mu;
  std::vector<uint64_t> order;
  std::vector<std::thread::id> threads;
  uint64_t writes = 0, fail_at = 0;
  int syncs = 0;
};

TEST(WriteBehindPageStoreTest, BaseGetsEveryPageInOrderFromOneThread) {
  RecordingStore base;
  {
    WriteBehindPageStore pages(&base, 4 * kSmallPage);  // batches of 4 pages: 250 pages cross many batches
    for (uint64_t i = 0; i < 250; ++i) ASSERT_TRUE(pages.WritePage(i, PageOf(i).data()).ok());
    ASSERT_TRUE(pages.WritePage(7, PageOf(7, 1).data()).ok());  // a rewrite, as the contract allows
    ASSERT_TRUE(pages.WritePage(250, PageOf(250).data()).ok());
    EXPECT_EQ(pages.page_count(), 251u);
    ASSERT_TRUE(pages.Sync().ok());
    EXPECT_EQ(base.syncs, 1);
    std::vector<uint8_t> got(kSmallPage);
    ASSERT_TRUE(pages.ReadPage(7, got.data()).ok());
    EXPECT_EQ(got, PageOf(7, 1));
  }
  ASSERT_EQ(base.order.size(), 252u);
  for (uint64_t i = 0; i < 250; ++i) EXPECT_EQ(base.order[i], i);
  EXPECT_EQ(base.order[250], 7u);
  EXPECT_EQ(base.order[251], 250u);
  for (const auto& t : base.threads) EXPECT_EQ(t, base.threads.front());
  EXPECT_NE(base.threads.front(), std::this_thread::get_id());
  std::vector<uint8_t> got(kSmallPage);
  for (uint64_t i : {0u, 100u, 249u, 250u}) {
    ASSERT_TRUE(base.memory.ReadPage(i, got.data()).ok());
    EXPECT_EQ(got, PageOf(i)) << i;
  }
}

// Counts the paged file's write calls.
class CountingOps : public FileOps {
 public:
  ssize_t Pwrite(int fd, const void* buf, size_t n, uint64_t offset) override {
    ++writes;
    return FileOps::Pwrite(fd, buf, n, offset);
  }
  int writes = 0;
};

// A paged file takes each run of consecutive pages in one write; a rewrite splits the run.
TEST(WriteBehindPageStoreTest, PagedFileGetsRunsOfPagesInOneWriteEach) {
  testing::TempDir dir;
  CountingOps ops;
  auto file = PagedFileStore::Create(dir.file("p.pages"), kSmallPage, ops);
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  const int created = ops.writes;  // the empty header
  {
    WriteBehindPageStore pages(file->get(), 8 * kSmallPage);
    for (uint64_t i = 0; i < 30; ++i) ASSERT_TRUE(pages.WritePage(i, PageOf(i).data()).ok());
    ASSERT_TRUE(pages.WritePage(3, PageOf(3, 9).data()).ok());  // a rewrite
    ASSERT_TRUE(pages.WritePage(30, PageOf(30).data()).ok());
    ASSERT_TRUE(pages.WritePage(31, PageOf(31).data()).ok());
    ASSERT_TRUE(pages.Flush().ok());
  }
  // Batches of 8: 0..7, 8..15, 16..23 one write each; then 24..29, 3, 30 (three runs); then 31.
  EXPECT_EQ(ops.writes - created, 3 + 3 + 1);
  EXPECT_EQ((*file)->page_count(), 32u);
  std::vector<uint8_t> got(kSmallPage);
  for (uint64_t i = 0; i < 32; ++i) {
    ASSERT_TRUE((*file)->ReadPage(i, got.data()).ok());
    EXPECT_EQ(got, PageOf(i, i == 3 ? 9 : 0)) << i;
  }
}

// Two streams into one paged file, as StoreWriter writes leaf and record pages: the second from page 20
// on, both at once, each in order and limited to its own pages.
TEST(WriteBehindPageStoreTest, TwoStreamsFillOnePagedFileAtOnce) {
  testing::TempDir dir;
  auto file = PagedFileStore::Create(dir.file("p.pages"), kSmallPage, DefaultFileOps());
  ASSERT_TRUE(file.ok()) << file.status().ToString();
  WriteBehindPageStore leaves(file->get(), 4 * kSmallPage);
  WriteBehindPageStore records(file->get(), 20, 4 * kSmallPage);
  leaves.SetLimit(20);
  std::thread other([&] {
    for (uint64_t i = 0; i < 15; ++i) ASSERT_TRUE(records.WritePage(i, PageOf(20 + i).data()).ok());
    ASSERT_TRUE(records.Flush().ok());
  });
  for (uint64_t i = 0; i < 20; ++i) ASSERT_TRUE(leaves.WritePage(i, PageOf(i).data()).ok());
  const Status past = leaves.WritePage(20, PageOf(20).data());
  EXPECT_EQ(past.code(), Status::Code::kInvalidArgument) << past.ToString();
  EXPECT_NE(past.message().find("past the 20 pages"), std::string::npos) << past.ToString();
  ASSERT_TRUE(leaves.Flush().ok());
  other.join();
  EXPECT_EQ(records.page_count(), 15u);
  EXPECT_EQ((*file)->page_count(), 35u);
  std::vector<uint8_t> got(kSmallPage);
  for (uint64_t i = 0; i < 35; ++i) {
    ASSERT_TRUE((*file)->ReadPage(i, got.data()).ok());
    EXPECT_EQ(got, PageOf(i)) << i;
  }
  ASSERT_TRUE(records.ReadPage(3, got.data()).ok());
  EXPECT_EQ(got, PageOf(23));
}

TEST(WriteBehindPageStoreTest, SmallStoreIsWrittenAtFlushWithoutAThread) {
  RecordingStore base;
  WriteBehindPageStore pages(&base, 64 * kSmallPage);
  for (uint64_t i = 0; i < 10; ++i) ASSERT_TRUE(pages.WritePage(i, PageOf(i).data()).ok());
  EXPECT_EQ(base.writes, 0u);  // still in the batch
  ASSERT_TRUE(pages.Flush().ok());
  EXPECT_EQ(base.order.size(), 10u);
  for (const auto& t : base.threads) EXPECT_EQ(t, std::this_thread::get_id());
}

TEST(WriteBehindPageStoreTest, OutOfOrderWriteIsRefusedAtOnce) {
  RecordingStore base;
  WriteBehindPageStore pages(&base, 4 * kSmallPage);
  ASSERT_TRUE(pages.WritePage(0, PageOf(0).data()).ok());
  const Status st = pages.WritePage(2, PageOf(2).data());
  EXPECT_EQ(st.code(), Status::Code::kInvalidArgument) << st.ToString();
  EXPECT_NE(st.message().find("out of order"), std::string::npos) << st.ToString();
  EXPECT_TRUE(pages.Flush().ok());
  EXPECT_EQ(base.order, std::vector<uint64_t>{0});
}

TEST(WriteBehindPageStoreTest, FailedWriteIsStickyAndStopsLaterWrites) {
  for (const uint64_t fail_at : {1u, 5u, 37u}) {
    SCOPED_TRACE(fail_at);
    RecordingStore base;
    base.fail_at = fail_at;
    WriteBehindPageStore pages(&base, 4 * kSmallPage);
    Status first;
    uint64_t i = 0;
    for (; i < 200 && first.ok(); ++i) first = pages.WritePage(i, PageOf(i).data());
    const Status flushed = pages.Flush();
    ASSERT_FALSE(flushed.ok());
    EXPECT_EQ(flushed.code(), Status::Code::kIOError);
    EXPECT_EQ(flushed.message(), "base: page " + std::to_string(fail_at - 1) + ": disk full");
    if (!first.ok()) {
      EXPECT_EQ(first.message(), flushed.message());
    }
    // Nothing after the failed page reached the base, and every later call returns the same error.
    EXPECT_EQ(base.order.size(), fail_at - 1);
    EXPECT_EQ(pages.WritePage(pages.page_count(), PageOf(i).data()).message(), flushed.message());
    EXPECT_EQ(pages.Sync().message(), flushed.message());
    EXPECT_EQ(base.syncs, 0);
  }
}

TEST(WriteBehindPageStoreTest, DestroyedUnflushedDropsPendingPages) {
  RecordingStore base;
  {
    WriteBehindPageStore pages(&base, 4 * kSmallPage);
    for (uint64_t i = 0; i < 100; ++i) ASSERT_TRUE(pages.WritePage(i, PageOf(i).data()).ok());
  }
  // Whatever reached the base is a prefix, in order.
  for (size_t i = 0; i < base.order.size(); ++i) EXPECT_EQ(base.order[i], i);
  EXPECT_LE(base.order.size(), 100u);
}

}  // namespace
}  // namespace mktree
