// What the crash, fault and snapshot tests of a store that takes changes share: a FileOps that counts the
// change writer's write steps (every Pwrite, Ftruncate, Fsync and Rename) and kills the process or fails at
// a chosen one; a pristine store with a few revisions copied afresh for every run; the checks that a store
// is whole (every live object intact, every query as brute force) and that its folders hold nothing that
// no kept revision names; and a child process to run a writer or a reader in.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "change_fixtures.h"
#include "engine/revision/change_folder.h"
#include "engine/shard/manifest.h"
#include "storage/file_ops.h"

namespace mktree::testing {

// Counts the write steps that pass through it and, once armed, acts at the k-th step from the arming:
// _exit(9) (a kill -9 of the writer: nothing after the step reaches the file system) or a failure with a
// chosen errno. Fsync does nothing else: a killed process loses nothing the page cache holds, and hundreds
// of runs would wait for the disk. Steps come from several threads (the store writer's page streams).
class StepFileOps : public FileOps {
 public:
  enum class Action { kCount, kExit, kFail };

  void Arm(uint64_t k, Action action, int error = EIO) {
    action_ = Action::kCount;
    steps_ = 0;
    fired_ = nullptr;
    k_ = k;
    error_ = error;
    action_ = action;
  }
  void Disarm() { Arm(0, Action::kCount); }
  uint64_t steps() const { return steps_; }
  // The kind of step that failed ("pwrite", ...), or null.
  const char* fired() const { return fired_; }

  ssize_t Pwrite(int fd, const void* buf, size_t n, uint64_t offset) override {
    if (Step("pwrite")) return -1;
    return FileOps::Pwrite(fd, buf, n, offset);
  }
  int Ftruncate(int fd, uint64_t size) override {
    if (Step("ftruncate")) return -1;
    return FileOps::Ftruncate(fd, size);
  }
  int Fsync(int /*fd*/) override { return Step("fsync") ? -1 : 0; }
  int Rename(const std::string& from, const std::string& to) override {
    if (Step("rename")) return -1;
    return FileOps::Rename(from, to);
  }

 private:
  // True when this step fails (errno set).
  bool Step(const char* what) {
    const uint64_t n = ++steps_;
    if (action_ == Action::kCount || n != k_) return false;
    if (action_ == Action::kExit) ::_exit(9);
    fired_ = what;
    errno = error_;
    return true;
  }

  std::atomic<Action> action_{Action::kCount};
  std::atomic<uint64_t> steps_{0};
  std::atomic<const char*> fired_{nullptr};
  uint64_t k_ = 0;
  int error_ = EIO;
};

// What a kill or fault test runs the writer through: a commit; a compaction; a commit whose changes pass
// the threshold, so that a compaction follows it; the first commit of a built store, whose writer's Open
// makes the changes folder.
enum class Operation { kCommit, kCompact, kCommitThenCompaction, kFirstCommit };

inline const char* OperationName(Operation op) {
  switch (op) {
    case Operation::kCommit:
      return "commit";
    case Operation::kCompact:
      return "compaction";
    case Operation::kCommitThenCompaction:
      return "commit then compaction";
    case Operation::kFirstCommit:
      return "first commit";
  }
  return "";
}

// The store file and its changes folder copied to `to`, in a folder of its own that is emptied first.
inline void CopyStore(const std::string& from, const std::string& to) {
  namespace fs = std::filesystem;
  fs::remove_all(fs::path(to).parent_path());
  fs::create_directories(fs::path(to).parent_path());
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  // A sharded store's shard files beside its manifest ("<store>.shard-N.mkt", ".ids"), under its new name.
  const std::string stem = fs::path(from).filename().string();
  for (const auto& e : fs::directory_iterator(fs::path(from).parent_path())) {
    const std::string name = e.path().filename().string();
    if (name.rfind(stem + ".shard-", 0) == 0)
      fs::copy_file(e.path(), fs::path(to).string() + name.substr(stem.size()));
  }
  if (fs::exists(ChangesFolder(from)))
    fs::copy(ChangesFolder(from), ChangesFolder(to), fs::copy_options::recursive);
}

// What is wrong with the files of `store`: in its changes folder, a file that no kept revision names (or a
// named one missing); beside it, a leftover of a writer ("<store>.lock" unless `writer_open`, temporaries,
// "<store>.relink.*", "<store>.changes.stale.*"). Empty: nothing.
inline std::vector<std::string> FolderProblems(const std::string& store, bool writer_open) {
  namespace fs = std::filesystem;
  std::vector<std::string> problems;
  const std::string folder = ChangesFolder(store);
  auto revisions = ListRevisionNumbers(folder);
  if (!revisions.ok()) return {revisions.status().ToString()};
  std::set<std::string> named;
  for (uint64_t r : *revisions) {
    auto m = ReadRevisionFile(folder, r);
    if (!m.ok()) {
      problems.push_back(m.status().ToString());
      continue;
    }
    named.insert(RevisionFileName(r));
    auto add = [&](const RevisionFile& f) {
      if (!f.name.empty()) named.insert(f.name);
    };
    add(m->base.store);
    add(m->base.ids);
    if (auto sharded = ReadManifest(ChangesFile(folder, m->base.store.name)); sharded.ok())
      for (const ShardEntry& e : sharded->shards) {
        add(e.store);
        add(e.ids);
      }
    for (const RevisionPart& d : m->deltas) {
      add(d.store);
      add(d.ids);
    }
    for (const RevisionIdList& l : m->removals) add(l.file);
    for (const RevisionIdList& l : m->touched) add(l.file);
  }
  std::set<std::string> present;
  if (fs::exists(folder))
    for (const auto& e : fs::directory_iterator(folder)) present.insert(e.path().filename().string());
  for (const std::string& name : present)
    if (!named.count(name)) problems.push_back("unreferenced " + folder + "/" + name);
  for (const std::string& name : named)
    if (!present.count(name)) problems.push_back("missing " + folder + "/" + name);
  const std::string stem = fs::path(store).filename().string();
  std::set<std::string> beside;  // the shard files the store's manifest names beside it
  if (auto m = ReadManifest(store); m.ok())
    for (const ShardEntry& e : m->shards) {
      beside.insert(e.store.name);
      beside.insert(e.ids.name);
    }
  for (const auto& e : fs::directory_iterator(fs::path(store).parent_path())) {
    const std::string name = e.path().filename().string();
    if (name == stem || name == stem + ".changes" || name.compare(0, stem.size() + 1, stem + ".") != 0)
      continue;
    if (writer_open && (name == stem + ".lock" || name == stem + ".build-lock")) continue;
    if (name.rfind(stem + ".shard-", 0) == 0 && beside.count(name)) continue;
    problems.push_back("leftover " + e.path().string());
  }
  return problems;
}

// Every live object of `live` is whole at `db`: its record (name, source, attributes) and its geometry (the
// stored mesh, in world coordinates, within float32 rounding); no other id below id_limit() is live; and
// every query of `qs` answers as brute force (ExpectAnswers).
inline void ExpectIntact(const Database& db, const LiveSet& live, const Vec3d& origin,
                         const std::vector<Query>& qs, const std::string& where) {
  SCOPED_TRACE(where);
  ExpectAnswers(db, live, origin, qs, where);
  for (const auto& [id, o] : live) {
    auto rec = db.Object(id);
    ASSERT_TRUE(rec.ok()) << "object " << id << ": " << rec.status().ToString();
    ASSERT_EQ(rec->name, o.name) << "object " << id;
    ASSERT_EQ(rec->source, o.source) << "object " << id;
    ASSERT_EQ(rec->attributes, o.attributes) << "object " << id;
    auto mesh = db.ObjectGeometry(id);
    ASSERT_TRUE(mesh.ok()) << "object " << id << ": " << mesh.status().ToString();
    ASSERT_EQ(mesh->triangles, o.mesh.triangles) << "object " << id;
    const Mesh want = StoredMesh(o.mesh, origin);
    ASSERT_EQ(mesh->vertices.size(), want.vertices.size()) << "object " << id;
    for (size_t v = 0; v < want.vertices.size(); ++v) {
      ASSERT_NEAR(mesh->vertices[v], want.vertices[v] + origin[v % 3], 1e-4) << "object " << id;
    }
  }
  for (ObjectId id = 0; id < db.id_limit(); ++id) {
    if (live.count(id)) continue;
    ASSERT_FALSE(db.Object(id).ok()) << "object " << id << " is not live";
  }
}

// Runs `child` in a forked process (which ends with its return value; an alarm ends a hung one) and
// returns the wait status. The caller holds no open store: the child starts with the parent's memory only.
inline int RunInChild(const std::function<int()>& child, unsigned alarm_seconds = 120) {
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::alarm(alarm_seconds);
    ::_exit(child());
  }
  if (pid < 0) return -1;
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return status;
}

inline std::string DescribeWaitStatus(int status) {
  if (status == -1) return "fork failed";
  if (WIFEXITED(status)) return "exit " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return "signal " + std::to_string(WTERMSIG(status));
  return "status " + std::to_string(status);
}

// A batch of every kind: `n` each of adds, removes and replaces against `live`.
inline ChangeBatch MixedBatch(const LiveSet& live, size_t n, std::mt19937_64& rng, uint64_t* counter) {
  ChangeBatch b;
  std::vector<ObjectId> ids;
  for (const auto& [id, o] : live) ids.push_back(id);
  std::shuffle(ids.begin(), ids.end(), rng);
  const std::vector<SceneObject> donors = ClusteredScene(2 * n + 8, rng());
  for (size_t i = 0; i < n; ++i) {
    b.add.push_back(MovedCopy(donors[i], rng, "add_" + std::to_string((*counter)++)));
    b.remove.push_back(ids[i]);
    SceneObject o = MovedCopy(donors[n + i], rng, "rep_" + std::to_string((*counter)++));
    o.id = ids[n + i];
    b.replace.push_back(std::move(o));
  }
  b.message = "mixed batch";
  return b;
}

// A store with a few revisions: `objects` objects built, then `commits` mixed batches committed with
// keep 2, so that deltas lie beside the base, some merged, and older revisions are retired (none: the
// built store alone, without a changes folder).
struct PristineStore {
  std::string path;
  Vec3d origin;
  LiveSet live;  // at `revision`
  uint64_t revision = 0;
  uint64_t counter = 0;  // names given so far
};
// `shards` > 0: a sharded store of that many shards.
inline void MakePristineStore(const std::string& path, Backend backend, size_t objects, int commits,
                              PristineStore* out, uint32_t shards = 0) {
  const std::vector<SceneObject> scene = ClusteredScene(objects, 38);
  ASSERT_TRUE((shards ? BuildShardedFromObjects(scene, path, SmallPages(backend), shards)
                      : BuildFromObjects(scene, path, SmallPages(backend)))
                  .ok());
  out->path = path;
  out->origin = ChooseStoreOrigin(scene[0].mesh.Bounds());
  for (const SceneObject& o : scene) out->live[o.id] = o;
  if (commits == 0) return;  // no changes folder yet
  auto w = ChangeWriter::Open(path, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  ASSERT_TRUE((*w)->SetKeep(2).ok());
  std::mt19937_64 rng(7);
  for (int i = 0; i < commits; ++i) {
    const ChangeBatch b = MixedBatch(out->live, 2 + 2 * static_cast<size_t>(i), rng, &out->counter);
    auto done = (*w)->Commit(b);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    Apply(b, *done, &out->live);
    out->revision = done->revision;
  }
}

}  // namespace mktree::testing
