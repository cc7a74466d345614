// mktree's engine of changes_bench: a store built by BuildFromFiles({"tanker:N:SEED"}) on a paged file
// with 12 KiB pages (ChangesBenchBuildOptions), changed through mktree::ChangeWriter: one batch is one
// Commit, a new durable revision holding the added and replaced objects' meshes, names and boxes. The
// moved copies are made by Stage (untimed); Commit() times ChangeWriter::Commit and checks that the added
// objects got the ids the script expects (N, N+1, ... in order).
#include <cstdio>
#include <filesystem>

#include "bench/change_engine.h"
#include "mktree/build.h"
#include "mktree/changes.h"
#include "mktree/database.h"

namespace mktree::bench {
namespace {

class MktreeChangeEngine : public ChangeEngine {
 public:
  MktreeChangeEngine(const std::string& dir, double compact_threshold)
      : path_(dir + "/changes_mktree.mkt"), compact_threshold_(compact_threshold) {}
  ~MktreeChangeEngine() override {
    db_.reset();
    writer_.reset();
    RemoveStore();
  }

  std::string name() const override { return "mktree"; }
  std::string description() const override {
    char threshold[32];
    std::snprintf(threshold, sizeof threshold, "%g", compact_threshold_);
    return std::string(
               "mktree ChangeWriter::Commit on a paged-file store, 12 KiB pages (4096 x 3), zstd: each ") +
           "added or replaced object's mesh, name and box, one durable revision per batch; "
           "compact_threshold " +
           threshold + (compact_threshold_ == 0 ? " (no automatic compaction)" : "");
  }

  Status Load(const ChangeWorkload& w) override {
    RemoveStore();
    MKTREE_ASSIGN_OR_RETURN(const BuildStats built,
                            BuildFromFiles({w.TankerInput()}, path_, ChangesBenchBuildOptions()));
    if (built.objects != w.objects)
      return Status::Internal("mktree: built " + std::to_string(built.objects) + " objects, expected " +
                              std::to_string(w.objects));
    MKTREE_ASSIGN_OR_RETURN(sources_, LoadSourceObjects(w));
    ChangeOptions options;
    options.compact_threshold = compact_threshold_;
    MKTREE_ASSIGN_OR_RETURN(writer_, ChangeWriter::Open(path_, options));
    return Status::Ok();
  }

  Status Stage(const ChangeBatchScript& script) override {
    batch_ = ChangeBatch();
    expected_ids_.clear();
    for (const Change& c : script.changes) {
      switch (c.kind) {
        case ChangeKind::kAdd:
          batch_.add.push_back(MovedCopy(sources_.at(c.source), c.offset, 0));
          expected_ids_.push_back(c.id);
          break;
        case ChangeKind::kRemove:
          batch_.remove.push_back(c.id);
          break;
        case ChangeKind::kReplace:
          batch_.replace.push_back(MovedCopy(sources_.at(c.source), c.offset, c.id));
          break;
      }
    }
    batch_.message = "changes_bench batch of " + std::to_string(script.changes.size());
    return Status::Ok();
  }

  Status Commit() override {
    MKTREE_ASSIGN_OR_RETURN(const CommitReport report, writer_->Commit(batch_));
    if (report.added_ids != expected_ids_)
      return Status::Internal("mktree: revision " + std::to_string(report.revision) +
                              " gave the added objects other ids than N, N+1, ... in order");
    compactions_ += report.compacted;
    return Status::Ok();
  }

  Status Query(const Box3f& box, std::vector<ObjectId>* ids) override {
    if (!db_) {
      MKTREE_ASSIGN_OR_RETURN(db_, Database::Open(path_));
    }
    Box3d b;
    for (int i = 0; i < 3; ++i) {
      b.min[i] = box.min[i];
      b.max[i] = box.max[i];
    }
    QueryResult r;
    MKTREE_RETURN_IF_ERROR(db_->Run(mktree::Query::Box(b), &r));
    ids->swap(r.hits);
    return Status::Ok();
  }

  std::string summary() const override {
    return "commits that ran an automatic compaction: " + std::to_string(compactions_);
  }

 private:
  void RemoveStore() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
    std::filesystem::remove_all(path_ + ".changes", ec);
  }

  std::string path_;
  double compact_threshold_;
  SourceObjects sources_;
  std::unique_ptr<ChangeWriter> writer_;
  std::unique_ptr<Database> db_;
  ChangeBatch batch_;
  std::vector<ObjectId> expected_ids_;
  uint64_t compactions_ = 0;
};

}  // namespace

std::unique_ptr<ChangeEngine> MakeMktreeChangeEngine(const std::string& dir, double compact_threshold) {
  return std::make_unique<MktreeChangeEngine>(dir, compact_threshold);
}

}  // namespace mktree::bench
