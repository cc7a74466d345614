// SQLite R*Tree peer of changes_bench: a 3-D rtree virtual table of the objects' boxes (float32, no
// geometry), 16 KiB pages (peer_engine.h), WAL journal. Load inserts the tanker's boxes in id order in one
// transaction with synchronous=OFF, then checkpoints and sets the synchronous level measured. One batch is
// one transaction: INSERT (add), DELETE (remove), UPDATE of the box (replace), COMMIT. With
// synchronous=FULL the WAL is synced at every commit; with NORMAL only at checkpoints (a power loss may
// lose the last commits, never corrupt). Automatic checkpoints (every 1000 WAL pages, SQLite's default)
// run inside the commits that trigger them and count in their latency.
#include <sqlite3.h>

#include <algorithm>
#include <filesystem>

#include "bench/change_engine.h"
#include "bench/peer_engine.h"

namespace mktree::bench {
namespace {

class SqliteChangeEngine : public ChangeEngine {
 public:
  SqliteChangeEngine(const std::string& dir, SqliteSync sync)
      : path_(dir + "/changes_sqlite.db"), sync_(sync) {}
  ~SqliteChangeEngine() override {
    Close();
    for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path_ + suffix);
  }

  std::string name() const override { return sync_ == SqliteSync::kFull ? "sqlite" : "sqlite-normal"; }
  std::string description() const override {
    return std::string("SQLite ") + sqlite3_libversion() + " rtree virtual table (boxes only), " +
           std::to_string(kSqlitePageBytes / 1024) + " KiB pages, " + std::to_string(kWarmCacheBytes >> 20) +
           " MiB cache, WAL, synchronous=" + (sync_ == SqliteSync::kFull ? "FULL" : "NORMAL") +
           ", one transaction per batch";
  }

  Status Load(const ChangeWorkload& w) override {
    for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path_ + suffix);
    if (sqlite3_open_v2(path_.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) !=
        SQLITE_OK)
      return Fail("open");
    const std::string setup =
        "PRAGMA page_size = " + std::to_string(kSqlitePageBytes) +
        "; PRAGMA journal_mode = WAL; PRAGMA synchronous = OFF; PRAGMA cache_size = -" +
        std::to_string(kWarmCacheBytes / 1024) +
        "; CREATE VIRTUAL TABLE rt USING rtree(id, minX, maxX, minY, maxY, minZ, maxZ);";
    MKTREE_RETURN_IF_ERROR(Exec(setup));
    MKTREE_RETURN_IF_ERROR(Prepare("INSERT INTO rt VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)", &insert_));
    MKTREE_RETURN_IF_ERROR(Prepare("DELETE FROM rt WHERE id = ?1", &delete_));
    MKTREE_RETURN_IF_ERROR(Prepare(
        "UPDATE rt SET minX = ?2, maxX = ?3, minY = ?4, maxY = ?5, minZ = ?6, maxZ = ?7 WHERE id = ?1",
        &update_));
    MKTREE_RETURN_IF_ERROR(
        Prepare("SELECT id FROM rt WHERE maxX >= ?1 AND minX <= ?2 AND maxY >= ?3 AND"
                " minY <= ?4 AND maxZ >= ?5 AND minZ <= ?6",
                &query_));
    MKTREE_RETURN_IF_ERROR(Exec("BEGIN"));
    for (size_t id = 0; id < w.base_boxes.size(); ++id)
      MKTREE_RETURN_IF_ERROR(Step(insert_, static_cast<ObjectId>(id), w.base_boxes[id], "insert"));
    MKTREE_RETURN_IF_ERROR(Exec("COMMIT"));
    return Exec(std::string("PRAGMA wal_checkpoint(TRUNCATE); PRAGMA synchronous = ") +
                (sync_ == SqliteSync::kFull ? "FULL" : "NORMAL"));
  }

  Status Stage(const ChangeBatchScript& batch) override {
    batch_ = &batch;
    return Status::Ok();
  }

  Status Commit() override {
    MKTREE_RETURN_IF_ERROR(Exec("BEGIN"));
    for (const Change& c : batch_->changes) {
      switch (c.kind) {
        case ChangeKind::kAdd:
          MKTREE_RETURN_IF_ERROR(Step(insert_, c.id, c.box, "insert"));
          break;
        case ChangeKind::kRemove:
          MKTREE_RETURN_IF_ERROR(Step(delete_, c.id, Box3f(), "delete"));
          break;
        case ChangeKind::kReplace:
          MKTREE_RETURN_IF_ERROR(Step(update_, c.id, c.box, "update"));
          break;
      }
      if (sqlite3_changes(db_) != 1)
        return Status::Internal("sqlite: change of object " + std::to_string(c.id) + " met no row");
    }
    return Exec("COMMIT");
  }

  Status Query(const Box3f& box, std::vector<ObjectId>* ids) override {
    ids->clear();
    for (int i = 0; i < 3; ++i) {
      sqlite3_bind_double(query_, 1 + 2 * i, box.min[i]);
      sqlite3_bind_double(query_, 2 + 2 * i, box.max[i]);
    }
    int rc;
    while ((rc = sqlite3_step(query_)) == SQLITE_ROW)
      ids->push_back(static_cast<ObjectId>(sqlite3_column_int64(query_, 0)));
    sqlite3_reset(query_);
    if (rc != SQLITE_DONE) return Fail("query");
    std::sort(ids->begin(), ids->end());
    return Status::Ok();
  }

 private:
  Status Exec(const std::string& sql) {
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) return Fail(sql.c_str());
    return Status::Ok();
  }
  Status Prepare(const char* sql, sqlite3_stmt** stmt) {
    if (sqlite3_prepare_v2(db_, sql, -1, stmt, nullptr) != SQLITE_OK) return Fail(sql);
    return Status::Ok();
  }
  // Binds the id and, for statements that take one, the box; runs the statement once.
  Status Step(sqlite3_stmt* stmt, ObjectId id, const Box3f& box, const char* what) {
    sqlite3_bind_int64(stmt, 1, id);
    if (sqlite3_bind_parameter_count(stmt) > 1)
      for (int i = 0; i < 3; ++i) {
        sqlite3_bind_double(stmt, 2 + 2 * i, box.min[i]);
        sqlite3_bind_double(stmt, 3 + 2 * i, box.max[i]);
      }
    const int rc = sqlite3_step(stmt);
    sqlite3_reset(stmt);
    if (rc != SQLITE_DONE) return Fail(what);
    return Status::Ok();
  }
  Status Fail(const char* what) {
    return Status::IOError(std::string("sqlite ") + what + ": " +
                           (db_ ? sqlite3_errmsg(db_) : "out of memory"));
  }
  void Close() {
    for (sqlite3_stmt* s : {insert_, delete_, update_, query_})
      if (s) sqlite3_finalize(s);
    insert_ = delete_ = update_ = query_ = nullptr;
    if (db_) sqlite3_close_v2(db_);
    db_ = nullptr;
  }

  std::string path_;
  SqliteSync sync_;
  sqlite3* db_ = nullptr;
  sqlite3_stmt *insert_ = nullptr, *delete_ = nullptr, *update_ = nullptr, *query_ = nullptr;
  const ChangeBatchScript* batch_ = nullptr;
};

}  // namespace

std::unique_ptr<ChangeEngine> MakeSqliteChangeEngine(const std::string& dir, SqliteSync sync) {
  return std::make_unique<SqliteChangeEngine>(dir, sync);
}

}  // namespace mktree::bench
