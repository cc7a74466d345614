// Snapshot isolation: a reader that opened revision R, in another process (fork) or on another thread,
// answers R byte for byte, round after round, while a writer commits batches and compacts; the writer keeps
// R for as long as the reader holds it, past the store's `keep`; once the reader is gone the next commit
// retires R, and opening it is NotFound naming the store and the revision.
#include <gtest/gtest.h>
#include <poll.h>

#include <fstream>
#include <sstream>
#include <thread>

#include "change_faults.h"

namespace mktree {
namespace {

using testing::LiveSet;

// Every query's answer, sorted, one line each, and the name of each hit: what a reader at one revision
// must give byte for byte whatever the writer does.
Result<std::string> AnswersText(const Database& db, const std::vector<Query>& qs) {
  std::ostringstream out;
  out << "revision " << db.revision() << " objects " << db.object_count() << '\n';
  for (size_t i = 0; i < qs.size(); ++i) {
    QueryResult r;
    MKTREE_RETURN_IF_ERROR(db.Run(qs[i], &r));
    std::sort(r.hits.begin(), r.hits.end());
    out << i << ':';
    for (ObjectId id : r.hits) {
      MKTREE_ASSIGN_OR_RETURN(std::string name, db.ObjectName(id));
      out << ' ' << id << '=' << name;
    }
    out << '\n';
  }
  return out.str();
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

bool Readable(int fd, int timeout_ms) {
  pollfd p{fd, POLLIN, 0};
  return ::poll(&p, 1, timeout_ms) == 1;
}

bool RevisionKept(const std::string& store, uint64_t revision) {
  auto revisions = ListRevisions(store);
  if (!revisions.ok()) return false;
  for (const RevisionInfo& r : *revisions)
    if (r.revision == revision) return true;
  return false;
}

class SnapshotIsolation : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(dir_ / "store");
    ASSERT_NO_FATAL_FAILURE(testing::MakePristineStore(dir_.file("store/s.mkt"), GetParam(), 300, 2, &at_r_));
    std::mt19937_64 rng(23);
    queries_ = testing::RandomQueries(60, rng);
    auto db = Database::Open(at_r_.path);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    ASSERT_EQ((*db)->revision(), at_r_.revision);
    ASSERT_NO_FATAL_FAILURE(testing::ExpectAnswers(**db, at_r_.live, at_r_.origin, queries_, "at R"));
    auto text = AnswersText(**db, queries_);
    ASSERT_TRUE(text.ok()) << text.status().ToString();
    expected_ = *text;
  }

  // With a reader holding R (`reader_alive`): 10 batches and a compaction with keep 2, the newest revision
  // checked against brute force after each, and R kept throughout.
  void CommitAndCompact(const std::function<bool()>& reader_alive) {
    auto w = ChangeWriter::Open(at_r_.path, {.compact_threshold = 0, .threads = 1});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    ASSERT_TRUE((*w)->SetKeep(2).ok());
    LiveSet live = at_r_.live;
    std::mt19937_64 rng(5);
    uint64_t counter = 5000;
    for (int i = 0; i < 11; ++i) {
      uint64_t revision = 0;
      if (i == 7) {
        auto c = (*w)->Compact();
        ASSERT_TRUE(c.ok()) << c.status().ToString();
        ASSERT_GT(c->folded, 0u);
        revision = c->revision;
      } else {
        const ChangeBatch b = testing::MixedBatch(live, 1 + i % 4, rng, &counter);
        auto done = (*w)->Commit(b);
        ASSERT_TRUE(done.ok()) << done.status().ToString();
        testing::Apply(b, *done, &live);
        revision = done->revision;
      }
      ASSERT_TRUE(reader_alive()) << "the reader ended early";
      ASSERT_TRUE(RevisionKept(at_r_.path, at_r_.revision))
          << "revision " << at_r_.revision << " retired at " << revision << " while a reader holds it";
      auto db = Database::Open(at_r_.path);
      ASSERT_TRUE(db.ok()) << db.status().ToString();
      ASSERT_EQ((*db)->revision(), revision);
      ASSERT_NO_FATAL_FAILURE(
          testing::ExpectAnswers(**db, live, at_r_.origin, queries_, "revision " + std::to_string(revision)));
    }
    EXPECT_GT((*w)->revision(), at_r_.revision + 2);  // past keep
    live_ = live;
  }

  // After the reader is gone: the next commit retires R, which then opens as NotFound naming it.
  void ExpectRetiredAfterTheNextCommit() {
    auto w = ChangeWriter::Open(at_r_.path, {.compact_threshold = 0, .threads = 1});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    std::mt19937_64 rng(6);
    uint64_t counter = 9000;
    const ChangeBatch b = testing::MixedBatch(live_, 2, rng, &counter);
    auto done = (*w)->Commit(b);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    EXPECT_FALSE(RevisionKept(at_r_.path, at_r_.revision));
    auto revisions = ListRevisions(at_r_.path);
    ASSERT_TRUE(revisions.ok());
    EXPECT_EQ(revisions->size(), 2u);  // keep 2
    auto old = Database::Open(at_r_.path, {.revision = at_r_.revision});
    ASSERT_FALSE(old.ok());
    EXPECT_EQ(old.status().code(), Status::Code::kNotFound) << old.status().ToString();
    EXPECT_NE(old.status().message().find(at_r_.path), std::string::npos) << old.status().ToString();
    EXPECT_NE(old.status().message().find("revision " + std::to_string(at_r_.revision)), std::string::npos)
        << old.status().ToString();
  }

  testing::TempDir dir_{"mktree_snapshot"};
  testing::PristineStore at_r_;
  std::vector<Query> queries_;
  std::string expected_;
  LiveSet live_;
};

TEST_P(SnapshotIsolation, AReaderInAnotherProcessAnswersItsRevisionByteForByte) {
  int ready[2], stop[2];
  ASSERT_EQ(::pipe(ready), 0);
  ASSERT_EQ(::pipe(stop), 0);
  const std::string rounds = dir_.file("rounds");
  std::filesystem::create_directories(rounds);
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::alarm(300);
    ::close(ready[0]);
    ::close(stop[1]);
    auto db = Database::Open(at_r_.path, {.revision = at_r_.revision});
    if (!db.ok()) ::_exit(2);
    for (int round = 0;; ++round) {
      const bool last = Readable(stop[0], 0);  // the writer is done: one more round, then exit
      auto text = AnswersText(**db, queries_);
      if (!text.ok()) ::_exit(3);
      std::ofstream(rounds + "/" + std::to_string(round)) << *text;
      if (round == 0 && ::write(ready[1], "r", 1) != 1) ::_exit(4);
      if (last) ::_exit(0);
    }
  }
  ::close(ready[1]);
  ::close(stop[0]);
  ASSERT_TRUE(Readable(ready[0], 60000)) << "the reader did not open revision " << at_r_.revision;
  auto alive = [&] { return ::waitpid(pid, nullptr, WNOHANG) == 0; };
  CommitAndCompact(alive);
  ASSERT_EQ(::write(stop[1], "s", 1), 1);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ::close(ready[0]);
  ::close(stop[1]);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << testing::DescribeWaitStatus(status);
  size_t n = 0;
  for (const auto& e : std::filesystem::directory_iterator(rounds)) {
    ++n;
    ASSERT_EQ(ReadFile(e.path().string()), expected_) << "round " << e.path().filename();
  }
  EXPECT_GE(n, 2u);
  if (HasFatalFailure()) return;
  ExpectRetiredAfterTheNextCommit();
}

// The same with the reader on a thread of this process.
TEST_P(SnapshotIsolation, AReaderOnAnotherThreadAnswersItsRevisionByteForByte) {
  auto db = Database::Open(at_r_.path, {.revision = at_r_.revision});
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  std::atomic<bool> stop{false};
  std::atomic<int> rounds{0}, mismatches{0};
  std::string first_mismatch;
  std::thread reader([&] {
    for (bool last = false; !last;) {
      last = stop;
      auto text = AnswersText(**db, queries_);
      if (!text.ok() || *text != expected_) {
        if (mismatches++ == 0) first_mismatch = text.ok() ? *text : text.status().ToString();
      }
      ++rounds;
    }
  });
  CommitAndCompact([] { return true; });
  stop = true;
  reader.join();
  EXPECT_EQ(mismatches, 0) << first_mismatch;
  EXPECT_GE(rounds, 2);
  db->reset();
  if (HasFatalFailure()) return;
  ExpectRetiredAfterTheNextCommit();
}

INSTANTIATE_TEST_SUITE_P(Backends, SnapshotIsolation, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
