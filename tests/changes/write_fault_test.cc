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
using testing::Operation;
using testing::OperationName;
using testing::StepFileOps;

class WriteFault : public ::testing::TestWithParam<Backend> {
 protected:
  // The store before: built, then `commits` batches committed.
  void Prepare(int commits) {
    std::filesystem::create_directories(dir_ / "pristine");
    ASSERT_NO_FATAL_FAILURE(testing::MakePristineStore(dir_.file("pristine/s.mkt"), GetParam(), 200, commits,
                                                       &pristine_, shards_));
    std::mt19937_64 rng(17);
    batch_ = testing::MixedBatch(pristine_.live, 4, rng, &pristine_.counter);
    queries_ = testing::RandomQueries(40, rng);
  }

  ChangeOptions Options(Operation op) const {
    ChangeOptions o = options_;
    if (op == Operation::kCommitThenCompaction) o.compact_threshold = 0.01;
    return o;
  }

  // Runs `op` on `w`: the commit's report in *report, the live set after it in *after.
  Status Run(ChangeWriter& w, Operation op, CommitReport* report, LiveSet* after) const {
    *after = pristine_.live;
    if (op == Operation::kCompact) return w.Compact().status();
    auto done = w.Commit(batch_);
    if (!done.ok()) return done.status();
    *report = *done;
    testing::Apply(batch_, *done, after);
    return Status::Ok();
  }

  // Fails step k = 1, 2, ... of `op` with `error` until a run ends without reaching k.
  void FailAtEveryStep(Operation op, int error) {
    const auto start = std::chrono::steady_clock::now();
    const std::string store = dir_.file("run/s.mkt");
    const uint64_t last = pristine_.revision + (op == Operation::kCommitThenCompaction ? 2 : 1);
    uint64_t failed = 0, relinks = 0;
    for (uint64_t k = 1;; ++k) {
      const std::string where = std::string(std::strerror(error)) + " at step " + std::to_string(k);
      SCOPED_TRACE(where);
      ASSERT_LT(k, 1000u) << "the writer's steps do not end";
      testing::CopyStore(pristine_.path, store);
      StepFileOps ops;
      if (op == Operation::kFirstCommit) ops.Arm(k, StepFileOps::Action::kFail, error);
      std::unique_ptr<ChangeWriter> w;
      Status st;
      CommitReport report;
      LiveSet after;
      auto opened = OpenChangeWriter(store, Options(op), ops);
      if (opened.ok()) {
        w = std::move(*opened);
        if (op != Operation::kFirstCommit) ops.Arm(k, StepFileOps::Action::kFail, error);
        st = Run(*w, op, &report, &after);
      } else {
        st = opened.status();
      }
      const bool fired = ops.fired() != nullptr;
      const std::string step = fired ? ops.fired() : "";
      ops.Disarm();
      if (fired) {
        ++failed;
        // Where the store must be: at the revision before, but when the commit stood and its threshold's
        // compaction failed, and past a compaction's relink of the store file, which follows its commit
        // point (the compaction stands, the same objects; the next compaction or writer relinks).
        uint64_t at = pristine_.revision;
        LiveSet live = pristine_.live;
        std::string message = st.ToString();
        if (st.ok()) {
          ASSERT_EQ(op, Operation::kCommitThenCompaction) << "a failed " << step << " was not reported";
          EXPECT_FALSE(report.compacted);
          message = report.compaction_error;
          ASSERT_NE(message, "") << "a failed " << step << " was not reported";
          at = pristine_.revision + 1;
          live = after;
        }
        EXPECT_NE(message.find(store), std::string::npos) << message;
        EXPECT_NE(message.find(std::strerror(error)), std::string::npos) << message;
        if (message.find(".relink") != std::string::npos ||
            message.find("compacted store") != std::string::npos) {
          ++relinks;
          ++at;
        }
        {
          auto db = Database::Open(store);
          ASSERT_TRUE(db.ok()) << db.status().ToString();
          ASSERT_EQ((*db)->revision(), at) << "after " << message;
          ASSERT_NO_FATAL_FAILURE(testing::ExpectIntact(**db, live, pristine_.origin, queries_, where));
        }
        // The next try: the same writer (a new one when its Open failed) and the same call, or the
        // compaction alone when the commit stood.
        if (!w) {
          auto again = OpenChangeWriter(store, Options(op), ops);
          ASSERT_TRUE(again.ok()) << again.status().ToString();
          w = std::move(*again);
        }
        if (st.ok()) {
          auto c = w->Compact();
          ASSERT_TRUE(c.ok()) << c.status().ToString();
        } else {
          const Status again = Run(*w, op, &report, &after);
          ASSERT_TRUE(again.ok()) << again.ToString();
        }
      } else {
        ASSERT_TRUE(st.ok()) << st.ToString();
      }
      if (op == Operation::kCommitThenCompaction && !st.ok()) {
        EXPECT_TRUE(report.compacted);
      }
      ASSERT_EQ(w->revision(), last);
      w.reset();
      EXPECT_EQ(testing::FolderProblems(store, false), std::vector<std::string>{});
      auto db = Database::Open(store);
      ASSERT_TRUE(db.ok()) << db.status().ToString();
      ASSERT_EQ((*db)->revision(), last);
      ASSERT_NO_FATAL_FAILURE(
          testing::ExpectIntact(**db, after, pristine_.origin, queries_, where + ", after"));
      if (!fired) break;
    }
    EXPECT_GT(failed, 0u);
    // The relink's rename and its folder fsync.
    EXPECT_EQ(relinks, op == Operation::kCompact || op == Operation::kCommitThenCompaction ? 2u : 0u);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << "  " << OperationName(op) << ", " << std::strerror(error) << " at each of " << failed
              << " steps: " << seconds << " s\n";
  }

  testing::TempDir dir_{"mktree_write_fault"};
  testing::PristineStore pristine_;
  ChangeBatch batch_;
  std::vector<Query> queries_;
  ChangeOptions options_{.compact_threshold = 0, .threads = 1};
  uint32_t shards_ = 0;  // > 0: a sharded store
};

TEST_P(WriteFault, FullDiskDuringACommit) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  FailAtEveryStep(Operation::kCommit, ENOSPC);
}
TEST_P(WriteFault, IoErrorDuringACommit) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  FailAtEveryStep(Operation::kCommit, EIO);
}
TEST_P(WriteFault, FullDiskDuringACompaction) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  FailAtEveryStep(Operation::kCompact, ENOSPC);
}
TEST_P(WriteFault, IoErrorDuringACompaction) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  FailAtEveryStep(Operation::kCompact, EIO);
}
TEST_P(WriteFault, FullDiskDuringACommitThenItsCompaction) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  FailAtEveryStep(Operation::kCommitThenCompaction, ENOSPC);
}
TEST_P(WriteFault, FullDiskDuringTheFirstCommitOfABuiltStore) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  FailAtEveryStep(Operation::kFirstCommit, ENOSPC);
}

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
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
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

// A sharded store of 2 shards: the first change links its shard files in; a compaction builds shards.
class ShardedWriteFault : public WriteFault {
 protected:
  ShardedWriteFault() { shards_ = 2; }
};

TEST_P(ShardedWriteFault, FullDiskDuringTheFirstCommitOfABuiltStore) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  FailAtEveryStep(Operation::kFirstCommit, ENOSPC);
}
TEST_P(ShardedWriteFault, IoErrorDuringACompaction) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  FailAtEveryStep(Operation::kCompact, EIO);
}

INSTANTIATE_TEST_SUITE_P(Backends, ShardedWriteFault, ::testing::Values(Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

INSTANTIATE_TEST_SUITE_P(Backends, WriteFault, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
