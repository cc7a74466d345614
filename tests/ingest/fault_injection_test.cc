// Fault injection through the store's I/O seams, driving the builder and the queries end to end:
//   - the writer's system calls (storage/file_ops.h): a page or metadata write that fails, is written short
//     while reporting success, or reaches the disk with a flipped byte; a truncate, fsync or rename that
//     fails; at every point of a build, over a previous good store;
//   - page reads under queries (FaultyPageStore via StoreReader::WrapPages): a read that fails, returns
//     short, or returns a flipped byte.
// The invariant everywhere: an error or the right answer, and the previous store intact (or, once the
// rename happened, the new store complete).
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/store_builder.h"
#include "engine/query/store_database.h"
#include "engine/scene/obj_reader.h"
#include "ingest/ingest_test_util.h"
#include "storage/file_ops.h"
#include "storage/memory_page_store.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::FileHash;

// A FileOps that counts calls of each kind and injects one fault at a chosen call. The store writer's
// leaf and record pages are written on two threads at once (storage/file_ops.h), so the counts are atomic:
// each call gets its own number, and exactly one call is the chosen one.
class FaultyFileOps : public FileOps {
 public:
  enum class Op { kPwrite, kFtruncate, kFsync, kRename };
  enum class Fault { kNone, kFail, kShortSilent, kFlip };

  void Inject(Op op, uint64_t nth, Fault fault) {
    op_ = op;
    nth_ = nth;
    fault_ = fault;
  }
  uint64_t calls(Op op) const { return calls_[static_cast<int>(op)]; }
  bool fired() const { return fired_; }

  ssize_t Pwrite(int fd, const void* buf, size_t n, uint64_t offset) override {
    if (!Hit(Op::kPwrite)) return FileOps::Pwrite(fd, buf, n, offset);
    switch (fault_) {
      case Fault::kFail:
        errno = EIO;
        return -1;
      case Fault::kShortSilent:  // half reaches the disk, all is reported written
        if (FileOps::Pwrite(fd, buf, n / 2, offset) < 0) return -1;
        return static_cast<ssize_t>(n);
      case Fault::kFlip: {
        std::vector<uint8_t> copy(static_cast<const uint8_t*>(buf), static_cast<const uint8_t*>(buf) + n);
        copy[n / 2] ^= 0x10;
        return FileOps::Pwrite(fd, copy.data(), n, offset);
      }
      case Fault::kNone:
        break;
    }
    return FileOps::Pwrite(fd, buf, n, offset);
  }
  int Ftruncate(int fd, uint64_t size) override {
    if (Hit(Op::kFtruncate)) return Fail(EIO);
    return FileOps::Ftruncate(fd, size);
  }
  // Never a real fsync: these stores need no durability, and hundreds of builds would wait for the disk.
  int Fsync(int /*fd*/) override { return Hit(Op::kFsync) ? Fail(EIO) : 0; }
  int Rename(const std::string& from, const std::string& to) override {
    if (Hit(Op::kRename)) return Fail(EXDEV);
    return FileOps::Rename(from, to);
  }

 private:
  bool Hit(Op op) {
    const uint64_t n = ++calls_[static_cast<int>(op)];
    if (fault_ == Fault::kNone || op != op_ || n != nth_) return false;
    fired_ = true;
    return true;
  }
  static int Fail(int err) {
    errno = err;
    return -1;
  }

  std::atomic<uint64_t> calls_[4] = {};
  Op op_ = Op::kPwrite;
  uint64_t nth_ = 0;
  Fault fault_ = Fault::kNone;
  std::atomic<bool> fired_{false};
};

std::vector<Query> SomeQueries(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  const Box3d hull = TankerHullBounds();
  std::vector<Query> qs;
  for (int i = 0; i < 60; ++i) {
    Vec3d p;
    for (int k = 0; k < 3; ++k) p[k] = hull.min[k] + unit(rng) * (hull.max[k] - hull.min[k]);
    if (i % 2 == 0) {
      qs.push_back(Query::Point(p));
    } else {
      Box3d b;
      for (int k = 0; k < 3; ++k) {
        b.min[k] = p[k] - 4;
        b.max[k] = p[k] + 4;
      }
      qs.push_back(Query::Box(b));
    }
  }
  return qs;
}

// Every query's answer, or the first error.
Result<std::vector<std::vector<ObjectId>>> Answers(const Database& db, const std::vector<Query>& qs,
                                                   QueryMode mode) {
  std::vector<std::vector<ObjectId>> out;
  QueryResult r;
  for (Query q : qs) {
    q.mode = mode;
    MKTREE_RETURN_IF_ERROR(db.Run(q, &r));
    out.push_back(r.hits);
  }
  return out;
}

Result<std::vector<std::vector<ObjectId>>> AnswersOf(const std::string& path, const std::vector<Query>& qs) {
  MKTREE_ASSIGN_OR_RETURN(auto db, Database::Open(path, {.cache_pages = 0}));
  return Answers(*db, qs, QueryMode::kExact);
}

class WriterFaultTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    path_ = dir_.file("store.mkt");
    ASSERT_TRUE(Build(1, nullptr).ok());
    old_hash_ = FileHash(path_);
    auto old = AnswersOf(path_, queries_);
    ASSERT_TRUE(old.ok()) << old.status().ToString();
    old_answers_ = *old;
    // The new scene's answers, from a store built aside.
    const std::string aside = (dir_ / "aside.mkt").string();
    ASSERT_TRUE(Build(2, nullptr, aside).ok());
    auto fresh = AnswersOf(aside, queries_);
    ASSERT_TRUE(fresh.ok());
    new_answers_ = *fresh;
    ASSERT_NE(new_answers_, old_answers_);
    fs::remove(aside);
  }

  // Builds a 600-object tanker of `seed` at `path` (default: the store under test) through `ops`.
  Status Build(uint64_t seed, FileOps* ops, const std::string& path = "") {
    static FaultyFileOps no_faults;  // no fsync either
    if (ops == nullptr) ops = &no_faults;
    IngestOptions o;
    o.store.backend = GetParam();
    o.store.params.block_size = 1024;
    o.store.params.blocks_per_page = 2;
    o.store.file_ops = ops;
    o.store.write_batch_bytes = 1;  // a write per page, so that the faults below can hit each
    o.threads = 1;
    auto r = BuildStore({[seed](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
                          return MakeTankerSource(600, seed, first);
                        }},
                        path.empty() ? path_ : path, o);
    return r.ok() ? Status::Ok() : r.status();
  }

  // After a build with a fault: an error and the old store untouched, or success and the new store, any of
  // whose queries may fail (a damaged page) but none answers wrongly. Nothing is left beside the store.
  void Check(const Status& build, const std::string& what, bool new_store_expected = false) {
    SCOPED_TRACE(what);
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir_))
      if (e.path().filename() != "store.mkt") left.push_back(e.path().filename().string());
    EXPECT_TRUE(left.empty()) << left.front();
    if (!build.ok() && !new_store_expected) {
      EXPECT_NE(build.message().find(path_), std::string::npos) << build.ToString();
      EXPECT_EQ(FileHash(path_), old_hash_) << build.ToString();
      auto answers = AnswersOf(path_, queries_);
      ASSERT_TRUE(answers.ok()) << answers.status().ToString();
      EXPECT_EQ(*answers, old_answers_);
      return;
    }
    auto db = Database::Open(path_, {.cache_pages = 0});
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    QueryResult r;
    for (size_t i = 0; i < queries_.size(); ++i) {
      Query q = queries_[i];
      q.mode = QueryMode::kExact;
      Status st = (*db)->Run(q, &r);
      if (st.ok()) {
        EXPECT_EQ(r.hits, new_answers_[i]) << "query " << i;
      } else {
        EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
        ++damaged_queries_;
      }
    }
    // A good build leaves the new store; so does a failed fsync of the directory after the rename.
    if (build.ok()) ++completed_builds_;
  }

  testing::TempDir dir_{"mktree_faults"};
  std::string path_;
  const std::vector<Query> queries_ = SomeQueries(3);
  uint64_t old_hash_ = 0;
  std::vector<std::vector<ObjectId>> old_answers_, new_answers_;
  int damaged_queries_ = 0, completed_builds_ = 0;
};

TEST_P(WriterFaultTest, EveryWriteFaultIsAnErrorOrAStoreThatNeverAnswersWrongly) {
  FaultyFileOps count;
  ASSERT_TRUE(Build(2, &count).ok());
  ASSERT_TRUE(Build(1, nullptr).ok());  // the old store back
  old_hash_ = FileHash(path_);
  const uint64_t writes = count.calls(FaultyFileOps::Op::kPwrite);
  // One write per leaf and record page (write_batch_bytes), then the sections and the header.
  ASSERT_GT(writes, 40u);
  int silent_caught = 0;  // silent damage refused before the rename
  for (FaultyFileOps::Fault fault :
       {FaultyFileOps::Fault::kFail, FaultyFileOps::Fault::kShortSilent, FaultyFileOps::Fault::kFlip}) {
    // The first writes, every 5th, and the last 20 (the metadata written at Commit comes last).
    for (uint64_t k = 1; k <= writes; k += k < 3 || k + 20 >= writes ? 1 : 5) {
      FaultyFileOps ops;
      ops.Inject(FaultyFileOps::Op::kPwrite, k, fault);
      const Status st = Build(2, &ops);
      ASSERT_TRUE(ops.fired());
      Check(st, "write " + std::to_string(k) + " fault " + std::to_string(static_cast<int>(fault)));
      if (fault == FaultyFileOps::Fault::kFail) {
        EXPECT_FALSE(st.ok()) << "write " << k;
      }
      silent_caught += fault != FaultyFileOps::Fault::kFail && !st.ok();
      if (!st.ok() || HasFailure()) {
        if (HasFailure()) return;
        continue;
      }
      ASSERT_TRUE(Build(1, nullptr).ok());  // the old store back for the next case
      old_hash_ = FileHash(path_);
    }
  }
  // Silent damage in metadata is caught before the rename (the store is read back); in a leaf page, by the
  // page checksum when a query reads it.
  EXPECT_GT(silent_caught, 0);
  EXPECT_GT(damaged_queries_, 0);
}

TEST_P(WriterFaultTest, FailedTruncateFsyncAndRenameKeepThePreviousStore) {
  FaultyFileOps count;
  ASSERT_TRUE(Build(2, &count).ok());
  ASSERT_TRUE(Build(1, nullptr).ok());
  old_hash_ = FileHash(path_);
  const uint64_t fsyncs = count.calls(FaultyFileOps::Op::kFsync);
  ASSERT_GE(fsyncs, 2u);  // the file's, then the directory's after the rename
  for (FaultyFileOps::Op op :
       {FaultyFileOps::Op::kFtruncate, FaultyFileOps::Op::kFsync, FaultyFileOps::Op::kRename}) {
    for (uint64_t k = 1; k <= count.calls(op); ++k) {
      FaultyFileOps ops;
      ops.Inject(op, k, FaultyFileOps::Fault::kFail);
      const Status st = Build(2, &ops);
      ASSERT_TRUE(ops.fired());
      ASSERT_FALSE(st.ok()) << "op " << static_cast<int>(op) << " call " << k;
      const bool after_rename = op == FaultyFileOps::Op::kFsync && k == fsyncs;
      if (after_rename) {
        EXPECT_NE(st.message().find("the new store is in place but may not survive a power loss"),
                  std::string::npos)
            << st.ToString();
      }
      Check(st, "op " + std::to_string(static_cast<int>(op)) + " call " + std::to_string(k), after_rename);
      if (HasFailure()) return;
      if (after_rename) {
        ASSERT_TRUE(Build(1, nullptr).ok());
        old_hash_ = FileHash(path_);
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, WriterFaultTest, ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const auto& info) {
                           return info.param == Backend::kHdf5 ? "Hdf5" : "PagedFile";
                         });

// Page reads under queries: a read that fails, returns short or returns a flipped byte gives an error
// for the queries that need that page and the right answer for every other, and nothing damaged stays in
// the cache: once the fault is gone, every answer is right again.
class ReadFaultTest : public ::testing::TestWithParam<Backend> {};

TEST_P(ReadFaultTest, EveryReadFaultIsAnErrorOrTheRightAnswer) {
  const testing::TempDir dir("mktree_read_faults");
  const std::string path = dir.file("store.mkt");
  IngestOptions o;
  o.store.backend = GetParam();
  o.store.params.block_size = 1024;
  o.store.params.blocks_per_page = 2;
  ASSERT_TRUE(BuildStore({[](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
                           return MakeTankerSource(600, 5, first);
                         }},
                         path, o)
                  .ok());
  const std::vector<Query> qs = SomeQueries(8);
  auto truth = AnswersOf(path, qs);
  ASSERT_TRUE(truth.ok());

  auto reader = StoreReader::Open(path);
  ASSERT_TRUE(reader.ok());
  FaultyPageStore* faulty = nullptr;
  (*reader)->WrapPages([&](std::unique_ptr<PageStore> pages) {
    auto f = std::make_unique<FaultyPageStore>(std::move(pages));
    faulty = f.get();
    return f;
  });
  const uint64_t page_bytes = (*reader)->pages().page_bytes(), pages = (*reader)->leaf_page_count();
  auto db = OpenStoreDatabase(std::move(*reader), {.cache_pages = 16});
  int errors = 0;
  auto run_all = [&](const std::string& what) {
    QueryResult r;
    for (size_t i = 0; i < qs.size(); ++i) {
      for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
        Query q = qs[i];
        q.mode = mode;
        Status st = db->Run(q, &r);
        if (!st.ok()) {
          ++errors;
          EXPECT_TRUE(st.code() == Status::Code::kCorruption || st.code() == Status::Code::kIOError)
              << what << ": " << st.ToString();
        } else if (mode == QueryMode::kExact) {
          ASSERT_EQ(r.hits, (*truth)[i]) << what << ", query " << i;
        }
      }
    }
  };
  for (uint64_t page = 0; page < pages; page += std::max<uint64_t>(1, pages / 25)) {
    for (uint64_t offset : {uint64_t{3}, uint64_t{40}, page_bytes / 2, page_bytes - 1}) {
      faulty->FlipByte(page, offset, 0x40);
      db->ClearCache();
      run_all("flip page " + std::to_string(page) + " byte " + std::to_string(offset));
      faulty->ClearFaults();
      faulty->ShortRead(page, offset);
      db->ClearCache();
      run_all("short page " + std::to_string(page) + " at " + std::to_string(offset));
      faulty->ClearFaults();
    }
  }
  for (uint64_t k = 1; k < 40; k += 3) {
    faulty->FailNthRead(k);
    db->ClearCache();
    run_all("failed read " + std::to_string(k));
    faulty->ClearFaults();
  }
  EXPECT_GT(errors, 100);
  // Nothing damaged was kept: with the faults gone, every answer is right.
  db->ClearCache();
  const int before = errors;
  run_all("after the faults");
  EXPECT_EQ(errors, before);
}

INSTANTIATE_TEST_SUITE_P(Backends, ReadFaultTest, ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const auto& info) {
                           return info.param == Backend::kHdf5 ? "Hdf5" : "PagedFile";
                         });

// An OBJ input truncated while the build reads it (after its 100th object, between two calls of Next(),
// so deterministically): the build fails with an IOError naming the file and line, and leaves nothing
// behind: no store, no spill file, the previous store byte for byte when there was one.
class TruncatingSource : public SceneSource {
 public:
  TruncatingSource(std::unique_ptr<SceneSource> inner, std::string path, uint64_t after)
      : inner_(std::move(inner)), path_(std::move(path)), after_(after) {}
  Result<bool> Next(SceneObject* out) override {
    if (++calls_ == after_ + 1) {
      EXPECT_EQ(::truncate(path_.c_str(), 4096), 0);
    }
    return inner_->Next(out);
  }

 private:
  std::unique_ptr<SceneSource> inner_;
  std::string path_;
  uint64_t after_, calls_ = 0;
};

class TruncatedInputTest : public ::testing::TestWithParam<Backend> {};

TEST_P(TruncatedInputTest, BuildFailsAndLeavesNothingBehind) {
  const testing::TempDir dir("mktree_truncated_input");
  std::string obj;
  for (int i = 0; i < 20000; ++i) {
    const std::string x = std::to_string(i);
    obj += "o t" + x + "\nv " + x + " 0 0\nv " + x + " 1 0\nv " + x + " 0 1\nf 1 2 3\nf -3 -2 -1\n";
  }
  const std::string input = dir.file("input.obj"), store = dir.file("store.mkt");
  IngestOptions o;
  o.store.backend = GetParam();
  auto opener = [&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    std::ofstream(input, std::ios::binary | std::ios::trunc) << obj;
    ObjReadOptions read;
    read.chunk_bytes = 4096;
    auto src = OpenObjFile(input, first, read);
    if (!src.ok()) return src.status();
    return std::unique_ptr<SceneSource>(new TruncatingSource(std::move(src).value(), input, 100));
  };
  auto listing = [&] {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir.path())) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  };
  std::ofstream(input, std::ios::binary) << obj;
  for (bool previous : {false, true}) {
    std::string before;
    if (previous) {
      ASSERT_TRUE(BuildStore({[](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
                               return MakeTankerSource(300, 1, first);
                             }},
                             store, o)
                      .ok());
      std::ifstream in(store, std::ios::binary);
      before.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::vector<std::string> files = listing();
    auto report = BuildStore({opener}, store, o);
    ASSERT_FALSE(report.ok()) << "previous store " << previous;
    EXPECT_EQ(report.status().code(), Status::Code::kIOError) << report.status().ToString();
    EXPECT_NE(report.status().message().find(input + ":"), std::string::npos) << report.status().ToString();
    EXPECT_NE(report.status().message().find("shrank while being read"), std::string::npos);
    EXPECT_EQ(listing(), files) << "previous store " << previous;
    if (previous) {
      std::ifstream in(store, std::ios::binary);
      EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), before);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, TruncatedInputTest, ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const auto& info) {
                           return info.param == Backend::kHdf5 ? "Hdf5" : "PagedFile";
                         });

}  // namespace
}  // namespace mktree
