// A change writer killed (kill -9: _exit in a forked child) at every write step of a commit, of a
// compaction and of a commit followed by the threshold's compaction, on both backends: the store opens at
// the revision before or one the operation writes, exactly (every query as brute force, every live
// object's record and geometry intact), never anything else, and never at an older one than an earlier
// kill left; the next writer removes what the dead one left (the folders hold only what kept revisions
// name), commits, and answers right.
#include <gtest/gtest.h>

#include <chrono>
#include <iostream>
#include <map>

#include "change_faults.h"
#include "engine/changes/change_writer.h"

namespace mktree {
namespace {

using testing::LiveSet;
using testing::Operation;
using testing::OperationName;
using testing::StepFileOps;

class KilledWriter : public ::testing::TestWithParam<Backend> {
 protected:
  // The store before: built, then `commits` batches committed.
  void Prepare(int commits) {
    std::filesystem::create_directories(dir_ / "pristine");
    ASSERT_NO_FATAL_FAILURE(testing::MakePristineStore(dir_.file("pristine/s.mkt"), GetParam(), 200, commits,
                                                       &pristine_, shards_));
    std::mt19937_64 rng(99);
    batch_ = testing::MixedBatch(pristine_.live, 4, rng, &pristine_.counter);
    queries_ = testing::RandomQueries(40, rng);
  }

  // Runs `op` on a writer of `store` whose writes go through `ops`; the commit's report in *report.
  Status Run(const std::string& store, FileOps& ops, Operation op, CommitReport* report) const {
    ChangeOptions options = options_;
    if (op == Operation::kCommitThenCompaction) options.compact_threshold = 0.01;
    auto w = OpenChangeWriter(store, options, ops);
    if (!w.ok()) return w.status();
    if (op == Operation::kCompact) return (*w)->Compact().status();
    auto done = (*w)->Commit(batch_);
    if (!done.ok()) return done.status();
    if (op == Operation::kCommitThenCompaction && !done->compacted)
      return Status::Internal("not compacted: " + done->compaction_error);
    if (report) *report = *done;
    return Status::Ok();
  }

  // The store after a killed writer: at the revision before or one the operation writes (never below the
  // highest an earlier kill left), whole; then a new writer cleans up, commits, and the store answers it.
  void ExpectWholeAndWritable(const std::string& store, const LiveSet& after, uint64_t last, uint64_t k,
                              std::map<uint64_t, uint64_t>* outcomes) {
    const std::string where = "killed at step " + std::to_string(k);
    SCOPED_TRACE(where);
    uint64_t rev = 0;
    LiveSet live;
    {
      auto db = Database::Open(store);
      ASSERT_TRUE(db.ok()) << db.status().ToString();
      rev = (*db)->revision();
      ASSERT_TRUE(rev >= pristine_.revision && rev <= last) << "revision " << rev;
      ASSERT_TRUE(outcomes->empty() || rev >= outcomes->rbegin()->first)
          << "revision " << rev << " after an earlier kill left " << outcomes->rbegin()->first;
      ++(*outcomes)[rev];
      live = rev == pristine_.revision ? pristine_.live : after;
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
    // Above the last committed one: a killed writer's files may have named a revision (and ids) that the next
    // writer then skips, never reuses.
    ASSERT_GE(done->revision, rev + 1);
    testing::Apply(next, *done, &live);
    w->reset();
    EXPECT_EQ(testing::FolderProblems(store, false), std::vector<std::string>{});
    auto db = Database::Open(store);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    ASSERT_EQ((*db)->revision(), done->revision);
    ASSERT_NO_FATAL_FAILURE(testing::ExpectIntact(**db, live, pristine_.origin, queries_, where + ", next"));
  }

  // Kills the writer at step k = 1, 2, ... of `op` until a run ends without reaching k.
  void KillAtEveryStep(Operation op) {
    const auto start = std::chrono::steady_clock::now();
    const std::string store = dir_.file("run/s.mkt");
    testing::CopyStore(pristine_.path, store);
    StepFileOps count;
    CommitReport report;
    const Status reference = Run(store, count, op, &report);
    ASSERT_TRUE(reference.ok()) << reference.ToString();
    const uint64_t steps = count.steps();
    LiveSet after = pristine_.live;
    if (op != Operation::kCompact) testing::Apply(batch_, report, &after);
    const uint64_t last = pristine_.revision + (op == Operation::kCommitThenCompaction ? 2 : 1);
    std::map<uint64_t, uint64_t> outcomes;  // revision the store opened at -> runs
    bool completed = false;
    uint64_t runs = 0;
    for (uint64_t k = 1; !completed; ++k) {
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
      ASSERT_NO_FATAL_FAILURE(ExpectWholeAndWritable(store, after, last, k, &outcomes));
    }
    for (uint64_t rev = pristine_.revision; rev <= last; ++rev)
      EXPECT_GT(outcomes[rev], 0u) << "no kill left the store at revision " << rev;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << "  " << OperationName(op) << ": " << steps << " write steps, killed at each: " << runs
              << " runs, the store opened at";
    for (const auto& [rev, n] : outcomes) std::cout << " revision " << rev << " " << n << "x";
    std::cout << "; " << seconds << " s\n";
  }

  testing::TempDir dir_{"mktree_killed_writer"};
  testing::PristineStore pristine_;
  ChangeBatch batch_;
  std::vector<Query> queries_;
  ChangeOptions options_{.compact_threshold = 0, .threads = 1};
  uint32_t shards_ = 0;  // > 0: a sharded store
};

TEST_P(KilledWriter, CommitOpensBeforeOrAfterAndTheNextWriterCleansUp) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  KillAtEveryStep(Operation::kCommit);
}

// The first change of a built store also makes its changes folder and revision 0.
TEST_P(KilledWriter, FirstCommitOfABuiltStoreOpensBeforeOrAfter) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  KillAtEveryStep(Operation::kCommit);
}

TEST_P(KilledWriter, CompactionOpensBeforeOrAfterAndTheNextWriterCleansUp) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  KillAtEveryStep(Operation::kCompact);
}

// The threshold's compaction after a commit: the store opens at the revision before, the commit's, or the
// compaction's.
TEST_P(KilledWriter, CommitThenItsCompactionOpensAtOneOfTheirRevisions) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  KillAtEveryStep(Operation::kCommitThenCompaction);
}

// The same on a sharded store of 2 shards: the first change links its shard files into the folder, and a
// compaction is a sharded build whose manifest is written last.
class KilledShardedWriter : public KilledWriter {
 protected:
  KilledShardedWriter() { shards_ = 2; }
};

TEST_P(KilledShardedWriter, FirstCommitOpensBeforeOrAfter) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  KillAtEveryStep(Operation::kCommit);
}

TEST_P(KilledShardedWriter, CommitThenItsCompactionOpensAtOneOfTheirRevisions) {
  ASSERT_NO_FATAL_FAILURE(Prepare(3));
  KillAtEveryStep(Operation::kCommitThenCompaction);
}

INSTANTIATE_TEST_SUITE_P(Backends, KilledShardedWriter, ::testing::Values(Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

INSTANTIATE_TEST_SUITE_P(Backends, KilledWriter, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
