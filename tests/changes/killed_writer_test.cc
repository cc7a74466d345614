// A change writer killed (kill -9: _exit in a forked child) at every write step of a commit and of a
// compaction, on both backends: the store opens at the revision before or the one after, exactly (every
// query as brute force, every live object's record and geometry intact), never anything else, and never
// before again once after; the next writer removes what the dead one left (the folders hold only what kept
// revisions name), commits, and answers right.
#include <gtest/gtest.h>

#include <chrono>
#include <iostream>

#include "change_faults.h"
#include "engine/changes/change_writer.h"

namespace mktree {
namespace {

using testing::LiveSet;
using testing::StepFileOps;

enum class Operation { kCommit, kCompact };

class KilledWriter : public ::testing::TestWithParam<Backend> {
 protected:
  // The store before: built, then `commits` batches committed.
  void Prepare(int commits) {
    std::filesystem::create_directories(dir_ / "pristine");
    ASSERT_NO_FATAL_FAILURE(
        testing::MakePristineStore(dir_.file("pristine/s.mkt"), GetParam(), 200, commits, &pristine_));
    std::mt19937_64 rng(99);
    batch_ = testing::MixedBatch(pristine_.live, 4, rng, &pristine_.counter);
    queries_ = testing::RandomQueries(40, rng);
  }

  // Runs `op` on a writer of `store` whose writes go through `ops`; the commit's report in *report.
  Status Run(const std::string& store, FileOps& ops, Operation op, CommitReport* report) const {
    auto w = OpenChangeWriter(store, options_, ops);
    if (!w.ok()) return w.status();
    if (op == Operation::kCompact) return (*w)->Compact().status();
    auto done = (*w)->Commit(batch_);
    if (!done.ok()) return done.status();
    if (report) *report = *done;
    return Status::Ok();
  }

  // The store after a killed writer: at the revision before (*after_seen false) or after, whole; then a
  // new writer cleans up, commits, and the store answers that commit.
  void ExpectWholeAndWritable(const std::string& store, const LiveSet& after, uint64_t k, bool* after_seen,
                              uint64_t* at_before, uint64_t* at_after) {
    const std::string where = "killed at step " + std::to_string(k);
    SCOPED_TRACE(where);
    uint64_t rev = 0;
    LiveSet live;
    {
      auto db = Database::Open(store);
      ASSERT_TRUE(db.ok()) << db.status().ToString();
      rev = (*db)->revision();
      ASSERT_TRUE(rev == pristine_.revision || rev == pristine_.revision + 1) << "revision " << rev;
      if (rev == pristine_.revision) {
        ASSERT_FALSE(*after_seen) << "back at the revision before after an earlier kill ended after";
        ++*at_before;
        live = pristine_.live;
      } else {
        *after_seen = true;
        ++*at_after;
        live = after;
      }
      ASSERT_NO_FATAL_FAILURE(testing::ExpectIntact(**db, live, pristine_.origin, queries_, where));
    }
    auto w = ChangeWriter::Open(store, options_);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    ASSERT_EQ((*w)->revision(), rev);
    EXPECT_EQ(testing::FolderProblems(store, true), std::vector<std::string>{});
    std::mt19937_64 rng(k);
    uint64_t counter = 1000;
    const ChangeBatch next = testing::MixedBatch(live, 3, rng, &counter);
    auto done = (*w)->Commit(next);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    ASSERT_EQ(done->revision, rev + 1);
    testing::Apply(next, *done, &live);
    w->reset();
    EXPECT_EQ(testing::FolderProblems(store, false), std::vector<std::string>{});
    auto db = Database::Open(store);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    ASSERT_EQ((*db)->revision(), rev + 1);
    ASSERT_NO_FATAL_FAILURE(testing::ExpectIntact(**db, live, pristine_.origin, queries_, where + ", next"));
  }

  // Kills the writer at step k = 1, 1 + stride, ... of `op` until a run ends without reaching k.
  void KillAtEveryStep(Operation op, uint64_t stride) {
    const auto start = std::chrono::steady_clock::now();
    const std::string store = dir_.file("run/s.mkt");
    testing::CopyStore(pristine_.path, store);
    StepFileOps count;
    CommitReport report;
    const Status reference = Run(store, count, op, &report);
    ASSERT_TRUE(reference.ok()) << reference.ToString();
    const uint64_t steps = count.steps();
    LiveSet after = pristine_.live;
    if (op == Operation::kCommit) testing::Apply(batch_, report, &after);
    bool completed = false, after_seen = false;
    uint64_t runs = 0, at_before = 0, at_after = 0;
    for (uint64_t k = 1; !completed; k += stride) {
      ASSERT_LT(k, 4 * steps + 100) << "the writer's steps do not end";
      testing::CopyStore(pristine_.path, store);
      const int status = testing::RunInChild([&] {
        StepFileOps ops;
        ops.Arm(k, StepFileOps::Action::kExit);
        return Run(store, ops, op, nullptr).ok() ? 0 : 3;
      });
      ++runs;
      ASSERT_TRUE(WIFEXITED(status) && (WEXITSTATUS(status) == 9 || WEXITSTATUS(status) == 0))
          << "step " << k << ": the writer ended with " << testing::DescribeWaitStatus(status);
      completed = WEXITSTATUS(status) == 0;
      ASSERT_NO_FATAL_FAILURE(ExpectWholeAndWritable(store, after, k, &after_seen, &at_before, &at_after));
    }
    EXPECT_GT(at_before, 0u);
    EXPECT_GT(at_after, 0u);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << "  " << (op == Operation::kCommit ? "commit" : "compaction") << ": " << steps
              << " write steps, killed at every " << (stride == 1 ? "" : std::to_string(stride) + "rd ")
              << "step: " << runs << " runs, " << at_before << " at the revision before, " << at_after
              << " after, " << seconds << " s\n";
  }

  testing::TempDir dir_{"mktree_killed_writer"};
  testing::PristineStore pristine_;
  ChangeBatch batch_;
  std::vector<Query> queries_;
  ChangeOptions options_{.compact_threshold = 0, .threads = 1};
};

TEST_P(KilledWriter, CommitOpensBeforeOrAfterAndTheNextWriterCleansUp) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  KillAtEveryStep(Operation::kCommit, 1);
}

// The first change of a built store also makes its changes folder and revision 0.
TEST_P(KilledWriter, FirstCommitOfABuiltStoreOpensBeforeOrAfter) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  KillAtEveryStep(Operation::kCommit, 1);
}

TEST_P(KilledWriter, CompactionOpensBeforeOrAfterAndTheNextWriterCleansUp) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  KillAtEveryStep(Operation::kCompact, 1);
}

INSTANTIATE_TEST_SUITE_P(Backends, KilledWriter, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
