// SQLite R*Tree peer: a 3-D rtree virtual table (float32 boxes) for the index and a rowid table for the
// geometry blobs (mktree's encoded object entries), inserted in object-id order in one transaction.
// Queries join the rtree to the geometry table (rtree outer, forced by CROSS JOIN) and read every blob,
// so a query's I/O includes the geometry, like mktree's leaf pages.
//
// I/O is counted by a VFS shim ("peers_count") registered in front of the default VFS: every xRead of the
// main database file of a full page is one page read. (SQLite's 16-byte reads of the change counter at
// the start of each read transaction are counted in bytes, not as pages.)
// Cold: sqlite3_db_release_memory() before each query empties the connection's page cache, and the driver
// drops the OS cache with posix_fadvise; warm: cache_size = kWarmCacheBytes, OS cache left alone.
#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "bench/peer_engine.h"

namespace mktree::bench {
namespace {

// ---- the counting VFS ----

Io g_io;  // one engine at a time (the driver is single-threaded)

struct CountFile {
  sqlite3_file base;
  sqlite3_file* real;  // follows this struct in the same allocation
  bool main_db;
};

sqlite3_vfs* RealVfs(sqlite3_vfs* vfs) { return static_cast<sqlite3_vfs*>(vfs->pAppData); }
sqlite3_file* Real(sqlite3_file* f) { return reinterpret_cast<CountFile*>(f)->real; }

int CfClose(sqlite3_file* f) {
  sqlite3_file* r = Real(f);
  int rc = r->pMethods ? r->pMethods->xClose(r) : SQLITE_OK;
  return rc;
}
int CfRead(sqlite3_file* f, void* buf, int amt, sqlite3_int64 off) {
  CountFile* cf = reinterpret_cast<CountFile*>(f);
  if (cf->main_db) {
    g_io.bytes += static_cast<uint64_t>(amt);
    if (amt >= static_cast<int>(kSqlitePageBytes))
      g_io.pages += static_cast<uint64_t>(amt) / kSqlitePageBytes;
  }
  return cf->real->pMethods->xRead(cf->real, buf, amt, off);
}
int CfWrite(sqlite3_file* f, const void* b, int n, sqlite3_int64 o) {
  return Real(f)->pMethods->xWrite(Real(f), b, n, o);
}
int CfTruncate(sqlite3_file* f, sqlite3_int64 n) { return Real(f)->pMethods->xTruncate(Real(f), n); }
int CfSync(sqlite3_file* f, int flags) { return Real(f)->pMethods->xSync(Real(f), flags); }
int CfFileSize(sqlite3_file* f, sqlite3_int64* n) { return Real(f)->pMethods->xFileSize(Real(f), n); }
int CfLock(sqlite3_file* f, int l) { return Real(f)->pMethods->xLock(Real(f), l); }
int CfUnlock(sqlite3_file* f, int l) { return Real(f)->pMethods->xUnlock(Real(f), l); }
int CfCheckReservedLock(sqlite3_file* f, int* out) {
  return Real(f)->pMethods->xCheckReservedLock(Real(f), out);
}
int CfFileControl(sqlite3_file* f, int op, void* arg) {
  return Real(f)->pMethods->xFileControl(Real(f), op, arg);
}
int CfSectorSize(sqlite3_file* f) { return Real(f)->pMethods->xSectorSize(Real(f)); }
int CfDeviceCharacteristics(sqlite3_file* f) { return Real(f)->pMethods->xDeviceCharacteristics(Real(f)); }
int CfShmMap(sqlite3_file* f, int pg, int sz, int ext, void volatile** p) {
  return Real(f)->pMethods->xShmMap(Real(f), pg, sz, ext, p);
}
int CfShmLock(sqlite3_file* f, int off, int n, int flags) {
  return Real(f)->pMethods->xShmLock(Real(f), off, n, flags);
}
void CfShmBarrier(sqlite3_file* f) { Real(f)->pMethods->xShmBarrier(Real(f)); }
int CfShmUnmap(sqlite3_file* f, int del) { return Real(f)->pMethods->xShmUnmap(Real(f), del); }
int CfFetch(sqlite3_file* f, sqlite3_int64 off, int amt, void** pp) {
  return Real(f)->pMethods->xFetch(Real(f), off, amt, pp);
}
int CfUnfetch(sqlite3_file* f, sqlite3_int64 off, void* p) {
  return Real(f)->pMethods->xUnfetch(Real(f), off, p);
}

sqlite3_io_methods MethodsFor(int version) {
  sqlite3_io_methods m{};
  m.iVersion = version;
  m.xClose = CfClose;
  m.xRead = CfRead;
  m.xWrite = CfWrite;
  m.xTruncate = CfTruncate;
  m.xSync = CfSync;
  m.xFileSize = CfFileSize;
  m.xLock = CfLock;
  m.xUnlock = CfUnlock;
  m.xCheckReservedLock = CfCheckReservedLock;
  m.xFileControl = CfFileControl;
  m.xSectorSize = CfSectorSize;
  m.xDeviceCharacteristics = CfDeviceCharacteristics;
  if (version >= 2) {
    m.xShmMap = CfShmMap;
    m.xShmLock = CfShmLock;
    m.xShmBarrier = CfShmBarrier;
    m.xShmUnmap = CfShmUnmap;
  }
  if (version >= 3) {
    m.xFetch = CfFetch;
    m.xUnfetch = CfUnfetch;
  }
  return m;
}
sqlite3_io_methods g_methods[4] = {MethodsFor(0), MethodsFor(1), MethodsFor(2), MethodsFor(3)};

int CvOpen(sqlite3_vfs* vfs, const char* name, sqlite3_file* f, int flags, int* out_flags) {
  CountFile* cf = reinterpret_cast<CountFile*>(f);
  cf->real = reinterpret_cast<sqlite3_file*>(cf + 1);
  cf->main_db = (flags & SQLITE_OPEN_MAIN_DB) != 0;
  int rc = RealVfs(vfs)->xOpen(RealVfs(vfs), name, cf->real, flags, out_flags);
  if (cf->real->pMethods) {
    cf->base.pMethods = &g_methods[std::clamp(cf->real->pMethods->iVersion, 1, 3)];
  } else {
    cf->base.pMethods = nullptr;
  }
  return rc;
}
int CvDelete(sqlite3_vfs* v, const char* n, int s) { return RealVfs(v)->xDelete(RealVfs(v), n, s); }
int CvAccess(sqlite3_vfs* v, const char* n, int f, int* o) {
  return RealVfs(v)->xAccess(RealVfs(v), n, f, o);
}
int CvFullPathname(sqlite3_vfs* v, const char* n, int k, char* o) {
  return RealVfs(v)->xFullPathname(RealVfs(v), n, k, o);
}
void* CvDlOpen(sqlite3_vfs* v, const char* n) { return RealVfs(v)->xDlOpen(RealVfs(v), n); }
void CvDlError(sqlite3_vfs* v, int n, char* m) { RealVfs(v)->xDlError(RealVfs(v), n, m); }
void (*CvDlSym(sqlite3_vfs* v, void* h, const char* s))(void) { return RealVfs(v)->xDlSym(RealVfs(v), h, s); }
void CvDlClose(sqlite3_vfs* v, void* h) { RealVfs(v)->xDlClose(RealVfs(v), h); }
int CvRandomness(sqlite3_vfs* v, int n, char* o) { return RealVfs(v)->xRandomness(RealVfs(v), n, o); }
int CvSleep(sqlite3_vfs* v, int us) { return RealVfs(v)->xSleep(RealVfs(v), us); }
int CvCurrentTime(sqlite3_vfs* v, double* t) { return RealVfs(v)->xCurrentTime(RealVfs(v), t); }
int CvGetLastError(sqlite3_vfs* v, int n, char* m) { return RealVfs(v)->xGetLastError(RealVfs(v), n, m); }
int CvCurrentTimeInt64(sqlite3_vfs* v, sqlite3_int64* t) {
  return RealVfs(v)->xCurrentTimeInt64(RealVfs(v), t);
}

constexpr const char* kVfsName = "peers_count";

void RegisterCountingVfs() {
  static bool done = false;
  if (done) return;
  done = true;
  static sqlite3_vfs vfs{};
  sqlite3_vfs* real = sqlite3_vfs_find(nullptr);
  vfs.iVersion = 2;
  vfs.szOsFile = static_cast<int>(sizeof(CountFile)) + real->szOsFile;
  vfs.mxPathname = real->mxPathname;
  vfs.zName = kVfsName;
  vfs.pAppData = real;
  vfs.xOpen = CvOpen;
  vfs.xDelete = CvDelete;
  vfs.xAccess = CvAccess;
  vfs.xFullPathname = CvFullPathname;
  vfs.xDlOpen = CvDlOpen;
  vfs.xDlError = CvDlError;
  vfs.xDlSym = CvDlSym;
  vfs.xDlClose = CvDlClose;
  vfs.xRandomness = CvRandomness;
  vfs.xSleep = CvSleep;
  vfs.xCurrentTime = CvCurrentTime;
  vfs.xGetLastError = CvGetLastError;
  vfs.xCurrentTimeInt64 = CvCurrentTimeInt64;
  sqlite3_vfs_register(&vfs, 0);
}

// ---- the engine ----

class SqliteEngine : public Engine {
 public:
  SqliteEngine(const std::string& dir, const CodecOptions& codec)
      : path_(dir + "/peer_sqlite.db"), codec_(codec) {}
  ~SqliteEngine() override { Close(); }

  std::string name() const override { return "sqlite-rtree"; }
  std::vector<std::string> files() const override { return {path_}; }
  std::string cold_method() const override {
    return "sqlite3_db_release_memory() and posix_fadvise(DONTNEED) before each query (buffered reads)";
  }

  Status Build(const SceneSpec& scene, Facts* facts) override {
    std::filesystem::remove(path_);
    RegisterCountingVfs();
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(path_.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, kVfsName) !=
        SQLITE_OK)
      return Fail(db, "open");
    db_ = db;
    const std::string setup = "PRAGMA page_size = " + std::to_string(kSqlitePageBytes) +
                              "; PRAGMA journal_mode = OFF; PRAGMA synchronous = OFF;"
                              " PRAGMA cache_size = -262144;"
                              " CREATE VIRTUAL TABLE rt USING rtree(id, minX, maxX, minY, maxY, minZ, maxZ);"
                              " CREATE TABLE geom(id INTEGER PRIMARY KEY, geom BLOB);"
                              " BEGIN;";
    if (sqlite3_exec(db_, setup.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) return Fail("setup");
    sqlite3_stmt *ins_rt = nullptr, *ins_geom = nullptr;
    if (sqlite3_prepare_v2(db_, "INSERT INTO rt VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)", -1, &ins_rt, nullptr) ||
        sqlite3_prepare_v2(db_, "INSERT INTO geom VALUES (?1, ?2)", -1, &ins_geom, nullptr))
      return Fail("prepare insert");
    auto src = scene.Open(0);
    if (!src.ok()) return src.status();
    SceneObject obj;
    std::vector<uint8_t> entry;
    uint64_t n = 0;
    for (;;) {
      auto more = (*src)->Next(&obj);
      if (!more.ok()) return more.status();
      if (!*more) break;
      const Box3f b = obj.Aabb();
      entry.clear();
      EncodePeerEntry(obj, codec_, &entry);
      sqlite3_bind_int64(ins_rt, 1, obj.id);
      for (int i = 0; i < 3; ++i) {
        sqlite3_bind_double(ins_rt, 2 + 2 * i, b.min[i]);
        sqlite3_bind_double(ins_rt, 3 + 2 * i, b.max[i]);
      }
      sqlite3_bind_int64(ins_geom, 1, obj.id);
      sqlite3_bind_blob(ins_geom, 2, entry.data(), static_cast<int>(entry.size()), SQLITE_STATIC);
      if (sqlite3_step(ins_rt) != SQLITE_DONE || sqlite3_step(ins_geom) != SQLITE_DONE) return Fail("insert");
      sqlite3_reset(ins_rt);
      sqlite3_reset(ins_geom);
      ++n;
    }
    sqlite3_finalize(ins_rt);
    sqlite3_finalize(ins_geom);
    if (sqlite3_exec(db_, "COMMIT;", nullptr, nullptr, nullptr) != SQLITE_OK) return Fail("commit");
    (*facts)["objects"] = static_cast<double>(n);
    // Pages per table, for B (objects per geometry page). dbstat is compiled into Debian's SQLite; without
    // it, B falls back to objects per page of the whole file.
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db_, "SELECT name, count(*) FROM dbstat GROUP BY name", -1, &st, nullptr) ==
        SQLITE_OK) {
      while (sqlite3_step(st) == SQLITE_ROW)
        (*facts)[std::string("pages_") + reinterpret_cast<const char*>(sqlite3_column_text(st, 0))] =
            sqlite3_column_double(st, 1);
    }
    sqlite3_finalize(st);
    Close();
    (*facts)["file_pages"] = static_cast<double>(std::filesystem::file_size(path_) / kSqlitePageBytes);
    return Status::Ok();
  }

  Status Open(bool warm, const Facts&) override {
    Close();
    RegisterCountingVfs();
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(path_.c_str(), &db, SQLITE_OPEN_READONLY, kVfsName) != SQLITE_OK)
      return Fail(db, "open");
    db_ = db;
    const uint64_t cache_kib = (warm ? kWarmCacheBytes : kColdCacheBytes) / 1024;
    const std::string pragma =
        "PRAGMA cache_size = -" + std::to_string(cache_kib) + "; PRAGMA mmap_size = 0;";
    if (sqlite3_exec(db_, pragma.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) return Fail("pragma");
    if (sqlite3_prepare_v2(db_,
                           "SELECT rt.id, geom.geom FROM rt CROSS JOIN geom ON geom.id = rt.id"
                           " WHERE rt.maxX >= ?1 AND rt.minX <= ?2 AND rt.maxY >= ?3 AND rt.minY <= ?4"
                           " AND rt.maxZ >= ?5 AND rt.minZ <= ?6",
                           -1, &query_, nullptr) != SQLITE_OK)
      return Fail("prepare query");
    return Status::Ok();
  }
  void Close() override {
    if (query_) sqlite3_finalize(query_);
    query_ = nullptr;
    if (db_) sqlite3_close_v2(db_);
    db_ = nullptr;
  }
  void ClearCache() override { sqlite3_db_release_memory(db_); }

  Status Run(const Query& q, std::vector<ObjectId>* hits, Io* io) override {
    hits->clear();
    g_io = Io();
    for (int i = 0; i < 3; ++i) {
      sqlite3_bind_double(query_, 1 + 2 * i, q.kind == Query::Kind::kPoint ? q.point[i] : q.box.min[i]);
      sqlite3_bind_double(query_, 2 + 2 * i, q.kind == Query::Kind::kPoint ? q.point[i] : q.box.max[i]);
    }
    int rc;
    while ((rc = sqlite3_step(query_)) == SQLITE_ROW) {
      const ObjectId id = static_cast<ObjectId>(sqlite3_column_int64(query_, 0));
      const auto* blob = static_cast<const uint8_t*>(sqlite3_column_blob(query_, 1));
      auto e = ParseObjectEntry(blob, static_cast<size_t>(sqlite3_column_bytes(query_, 1)));
      if (!e.ok() || e->id != id) {
        sqlite3_reset(query_);
        return Status::Corruption("sqlite: geometry blob of " + std::to_string(id) + " is not its entry");
      }
      hits->push_back(id);
    }
    sqlite3_reset(query_);
    if (rc != SQLITE_DONE) return Status::IOError(std::string("sqlite query: ") + sqlite3_errmsg(db_));
    std::sort(hits->begin(), hits->end());
    *io = g_io;
    return Status::Ok();
  }

  double objects_per_page(const Facts& f) const override {
    auto it = f.find("pages_geom");
    const double pages = it != f.end() ? it->second : f.at("file_pages");
    return f.at("objects") / std::max(1.0, pages);
  }

 private:
  Status Fail(sqlite3* db, const char* what) {
    std::string msg = std::string("sqlite ") + what + ": " + (db ? sqlite3_errmsg(db) : "out of memory");
    if (db) sqlite3_close(db);
    return Status::IOError(msg);
  }
  Status Fail(const char* what) {
    std::string msg = std::string("sqlite ") + what + ": " + sqlite3_errmsg(db_);
    Close();
    return Status::IOError(msg);
  }

  std::string path_;
  CodecOptions codec_;
  sqlite3* db_ = nullptr;
  sqlite3_stmt* query_ = nullptr;
};

}  // namespace

std::unique_ptr<Engine> MakeSqliteEngine(const std::string& dir, const CodecOptions& codec) {
  return std::make_unique<SqliteEngine>(dir, codec);
}

}  // namespace mktree::bench
