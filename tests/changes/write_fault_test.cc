// A full disk (ENOSPC) or an I/O error (EIO) at each write step of a commit and of a compaction, in
// process, on both backends: the call returns an error naming the store or the file, the store still opens
// at the revision before with the right answers (but for the relink of the store file to the compacted
// base, which follows a compaction's commit point), the same writer's next try succeeds, and the folders
// then hold only what kept revisions name.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <iostream>

#include "change_faults.h"
#include "engine/changes/change_writer.h"

namespace mktree {
namespace {

using testing::LiveSet;
using testing::StepFileOps;

enum class Operation { kCommit, kCompact };

class WriteFault : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(dir_ / "pristine");
    ASSERT_NO_FATAL_FAILURE(
        testing::MakePristineStore(dir_.file("pristine/s.mkt"), GetParam(), 200, 3, &pristine_));
    std::mt19937_64 rng(17);
    batch_ = testing::MixedBatch(pristine_.live, 4, rng, &pristine_.counter);
    queries_ = testing::RandomQueries(40, rng);
  }

  // Runs `op` on `w`; the live set after it in *after.
  Status Run(ChangeWriter& w, Operation op, LiveSet* after) const {
    *after = pristine_.live;
    if (op == Operation::kCompact) return w.Compact().status();
    auto done = w.Commit(batch_);
    if (!done.ok()) return done.status();
    testing::Apply(batch_, *done, after);
    return Status::Ok();
  }

  // Fails step k = 1, 2, ... of `op` with `error` until a run ends without reaching k.
  void FailAtEveryStep(Operation op, int error) {
    const auto start = std::chrono::steady_clock::now();
    const std::string store = dir_.file("run/s.mkt");
    uint64_t failed = 0, relinks = 0;
    for (uint64_t k = 1;; ++k) {
      const std::string where = std::string(std::strerror(error)) + " at step " + std::to_string(k);
      SCOPED_TRACE(where);
      ASSERT_LT(k, 1000u) << "the writer's steps do not end";
      testing::CopyStore(pristine_.path, store);
      StepFileOps ops;
      auto w = OpenChangeWriter(store, options_, ops);
      ASSERT_TRUE(w.ok()) << w.status().ToString();
      ops.Arm(k, StepFileOps::Action::kFail, error);
      LiveSet after;
      const Status st = Run(**w, op, &after);
      const bool fired = ops.fired() != nullptr;
      ops.Disarm();
      if (fired) {
        ++failed;
        ASSERT_FALSE(st.ok()) << "a failed " << ops.fired() << " was not reported";
        EXPECT_NE(st.message().find(store), std::string::npos) << st.ToString();
        EXPECT_NE(st.message().find(std::strerror(error)), std::string::npos) << st.ToString();
        // A compaction's relink of the store file comes after its commit point: the compaction stands
        // (the same objects), and the relink is done again by the next compaction or writer.
        const bool relink =
            op == Operation::kCompact && (st.message().find(".relink") != std::string::npos ||
                                          st.message().find("compacted") != std::string::npos);
        relinks += relink;
        {
          auto db = Database::Open(store);
          ASSERT_TRUE(db.ok()) << db.status().ToString();
          ASSERT_EQ((*db)->revision(), pristine_.revision + relink) << "after " << st.ToString();
          ASSERT_NO_FATAL_FAILURE(
              testing::ExpectIntact(**db, pristine_.live, pristine_.origin, queries_, where));
        }
        const Status again = Run(**w, op, &after);
        ASSERT_TRUE(again.ok()) << again.ToString();
      } else {
        ASSERT_TRUE(st.ok()) << st.ToString();
      }
      ASSERT_EQ((*w)->revision(), pristine_.revision + 1);
      w->reset();
      EXPECT_EQ(testing::FolderProblems(store, false), std::vector<std::string>{});
      auto db = Database::Open(store);
      ASSERT_TRUE(db.ok()) << db.status().ToString();
      ASSERT_EQ((*db)->revision(), pristine_.revision + 1);
      ASSERT_NO_FATAL_FAILURE(
          testing::ExpectIntact(**db, after, pristine_.origin, queries_, where + ", after"));
      if (!fired) break;
    }
    EXPECT_GT(failed, 0u);
    EXPECT_EQ(relinks, op == Operation::kCompact ? 2u : 0u);  // the relink's rename and folder fsync
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << "  " << (op == Operation::kCommit ? "commit" : "compaction") << ", " << std::strerror(error)
              << " at each of " << failed << " steps: " << seconds << " s\n";
  }

  testing::TempDir dir_{"mktree_write_fault"};
  testing::PristineStore pristine_;
  ChangeBatch batch_;
  std::vector<Query> queries_;
  ChangeOptions options_{.compact_threshold = 0, .threads = 1};
};

TEST_P(WriteFault, FullDiskDuringACommit) { FailAtEveryStep(Operation::kCommit, ENOSPC); }
TEST_P(WriteFault, IoErrorDuringACommit) { FailAtEveryStep(Operation::kCommit, EIO); }
TEST_P(WriteFault, FullDiskDuringACompaction) { FailAtEveryStep(Operation::kCompact, ENOSPC); }
TEST_P(WriteFault, IoErrorDuringACompaction) { FailAtEveryStep(Operation::kCompact, EIO); }

// Fails every rename onto the store file while armed: the relink of the store to a compacted base.
class FailingRelink : public FileOps {
 public:
  explicit FailingRelink(std::string store) : store_(std::move(store)) {}
  int Rename(const std::string& from, const std::string& to) override {
    if (armed && to == store_) {
      ++failed;
      errno = EIO;
      return -1;
    }
    return FileOps::Rename(from, to);
  }
  int Fsync(int /*fd*/) override { return 0; }
  std::atomic<bool> armed{false};
  std::atomic<int> failed{0};

 private:
  std::string store_;
};

// A compaction whose relink of the store file fails after its commit point, then more commits than the
// store keeps: the store file is still the old base, so the revisions of that base must stay until a
// relink succeeds, or the store would open as its old base alone and the next writer start it anew.
TEST_P(WriteFault, AFailedRelinkAfterACompactionLosesNothing) {
  const std::string store = dir_.file("run/s.mkt");
  testing::CopyStore(pristine_.path, store);
  FailingRelink ops(store);
  auto w = OpenChangeWriter(store, options_, ops);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  ops.armed = true;
  auto c = (*w)->Compact();
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.status().message().find(store), std::string::npos) << c.status().ToString();
  LiveSet live = pristine_.live;
  std::mt19937_64 rng(3);
  uint64_t counter = 2000;
  for (int i = 0; i < 4; ++i) {
    const ChangeBatch b = testing::MixedBatch(live, 2, rng, &counter);
    auto done = (*w)->Commit(b);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    testing::Apply(b, *done, &live);
    auto db = Database::Open(store);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    ASSERT_EQ((*db)->revision(), done->revision);
    ASSERT_NO_FATAL_FAILURE(testing::ExpectIntact(
        **db, live, pristine_.origin, queries_, "commit " + std::to_string(i) + " after the failed relink"));
  }
  ops.armed = false;
  auto again = (*w)->Compact();
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  w->reset();
  EXPECT_EQ(testing::FolderProblems(store, false), std::vector<std::string>{});
  auto reopened = ChangeWriter::Open(store, options_);
  ASSERT_TRUE(reopened.ok()) << reopened.status().ToString();
  EXPECT_EQ((*reopened)->revision(), again->revision);
  reopened->reset();
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  ASSERT_NO_FATAL_FAILURE(testing::ExpectIntact(**db, live, pristine_.origin, queries_, "relinked"));
  // The store file is the newest base again: it alone holds the live objects.
  auto revisions = ListRevisionNumbers(ChangesFolder(store));
  ASSERT_TRUE(revisions.ok());
  auto head = ReadRevisionFile(ChangesFolder(store), revisions->back());
  ASSERT_TRUE(head.ok());
  auto now = FingerprintFile(store);
  ASSERT_TRUE(now.ok());
  EXPECT_EQ(now->fingerprint, head->base.store.fingerprint);
}

INSTANTIATE_TEST_SUITE_P(Backends, WriteFault, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
