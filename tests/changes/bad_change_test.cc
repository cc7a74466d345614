// Bad input to a store that takes changes, each a clear error naming the thing, and the store unchanged
// (same revision, same answers, nothing left in its folder): a replace by a name that is missing or not
// unique, a remove of an unknown id or of one removed earlier, an id changed twice in one batch, NaN
// coordinates in an added or a replacing object, an added file that is missing or malformed, a second writer
// (in this process and in another), a revision never committed or retired, a store that does not exist, a
// sharded store; and damaged files of the changes folder (a revision file, a delta store, an id file):
// Corruption naming the file.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>

#include "change_faults.h"
#include "mktree/build.h"

namespace mktree {
namespace {

using testing::LiveSet;

bool Contains(const Status& st, const std::string& what) {
  return st.message().find(what) != std::string::npos;
}

class BadChange : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(dir_ / "store");
    ASSERT_NO_FATAL_FAILURE(
        testing::MakePristineStore(dir_.file("store/s.mkt"), GetParam(), 120, 3, &store_));
    std::mt19937_64 rng(41);
    queries_ = testing::RandomQueries(30, rng);
    auto w = ChangeWriter::Open(store_.path, {.compact_threshold = 0, .threads = 1});
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    w_ = std::move(*w);
    // Two live objects of one name, for a replace by a name that is not unique.
    ChangeBatch twins;
    const std::vector<SceneObject> donors = testing::ClusteredScene(2, 3);
    for (int i = 0; i < 2; ++i) twins.add.push_back(testing::MovedCopy(donors[i], rng, "twin"));
    auto done = w_->Commit(twins);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    testing::Apply(twins, *done, &store_.live);
    store_.revision = done->revision;
    removed_ = store_.live.begin()->first;
    ChangeBatch remove;
    remove.remove.push_back(removed_);
    done = w_->Commit(remove);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    testing::Apply(remove, *done, &store_.live);
    store_.revision = done->revision;
  }

  // A live object with new geometry.
  SceneObject Moved(ObjectId id, const std::string& name) {
    std::mt19937_64 rng(id);
    SceneObject o = testing::MovedCopy(store_.live.at(id), rng, name);
    o.id = id;
    return o;
  }

  // The batch is refused with InvalidArgument naming each of `names`, and the store is unchanged.
  void ExpectRefused(const ChangeBatch& batch, const std::vector<std::string>& names) {
    auto done = w_->Commit(batch);
    ASSERT_FALSE(done.ok()) << "committed as revision " << done->revision;
    EXPECT_EQ(done.status().code(), Status::Code::kInvalidArgument) << done.status().ToString();
    EXPECT_TRUE(Contains(done.status(), store_.path)) << done.status().ToString();
    for (const std::string& name : names)
      EXPECT_TRUE(Contains(done.status(), name)) << done.status().ToString();
    ExpectUnchanged();
  }

  void ExpectUnchanged() {
    ASSERT_EQ(w_->revision(), store_.revision);
    EXPECT_EQ(testing::FolderProblems(store_.path, true), std::vector<std::string>{});
    auto db = Database::Open(store_.path);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    ASSERT_EQ((*db)->revision(), store_.revision);
    ASSERT_NO_FATAL_FAILURE(testing::ExpectIntact(**db, store_.live, store_.origin, queries_, "unchanged"));
  }

  // The newest revision's file, and the first delta store and id file it names.
  std::string Folder() const { return ChangesFolder(store_.path); }
  RevisionManifest Head() const {
    auto m = ReadRevisionFile(Folder(), store_.revision);
    EXPECT_TRUE(m.ok()) << m.status().ToString();
    return m.ok() ? *m : RevisionManifest{};
  }

  testing::TempDir dir_{"mktree_bad_change"};
  testing::PristineStore store_;
  std::vector<Query> queries_;
  std::unique_ptr<ChangeWriter> w_;
  ObjectId removed_ = 0;
};

TEST_P(BadChange, ReplaceByANameThatIsMissingOrNotUnique) {
  ChangeBatch missing;
  SceneObject o = Moved(store_.live.rbegin()->first, "no such name");
  missing.replace_by_name.push_back(o);
  ExpectRefused(missing, {"'no such name'", "no object"});
  ChangeBatch twins;
  o.name = "twin";
  twins.replace_by_name.push_back(o);
  ExpectRefused(twins, {"'twin'", "2 objects"});
  // A good one goes in after them: an object whose name no other has.
  std::map<std::string, int> uses;
  for (const auto& [id, live] : store_.live) ++uses[live.name];
  ObjectId id = 0;
  for (const auto& [i, live] : store_.live)
    if (uses[live.name] == 1) id = i;
  ChangeBatch good;
  o.name = store_.live.at(id).name;
  good.replace_by_name.push_back(o);
  auto done = w_->Commit(good);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_EQ(done->replaced, 1u);
  o.id = id;
  store_.live[id] = o;
  store_.revision = done->revision;
  ExpectUnchanged();
}

TEST_P(BadChange, RemoveOfAnUnknownOrRemovedIdAndAnIdTwice) {
  const ObjectId unknown = static_cast<ObjectId>(Head().next_id + 5);
  ChangeBatch b;
  b.remove.push_back(unknown);
  ExpectRefused(b, {"object " + std::to_string(unknown)});
  b.remove = {removed_};
  ExpectRefused(b, {"object " + std::to_string(removed_), "removed"});
  const ObjectId live = store_.live.rbegin()->first;
  b.remove = {live, live};
  ExpectRefused(b, {"object " + std::to_string(live), "twice"});
  b.remove = {live};
  b.replace = {Moved(live, "again")};
  ExpectRefused(b, {"object " + std::to_string(live), "twice"});
  ChangeBatch names;
  names.remove_names = {"no such name"};
  ExpectRefused(names, {"'no such name'"});
}

TEST_P(BadChange, NanCoordinatesInAnAddedOrAReplacingObject) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ChangeBatch add;
  add.add.push_back(Moved(store_.live.begin()->first, "fine"));
  add.add.push_back(Moved(store_.live.begin()->first, "nan added"));
  add.add.back().mesh.vertices[4] = nan;
  ExpectRefused(add, {"'nan added'"});
  ChangeBatch replace;
  const ObjectId id = store_.live.rbegin()->first;
  replace.replace.push_back(Moved(id, "nan replacing"));
  replace.replace.back().mesh.vertices[0] = -nan;
  ExpectRefused(replace, {"'nan replacing'", "object " + std::to_string(id)});
  ChangeBatch by_name;
  by_name.replace_by_name.push_back(Moved(id, store_.live.at(id).name));
  by_name.replace_by_name.back().mesh.vertices[2] = std::numeric_limits<double>::infinity();
  ExpectRefused(by_name, {"'" + store_.live.at(id).name + "'"});
}

// Files added by name (ChangeBatch::add_files) are read and checked before anything is written: a bad one
// is an error naming the store, the file and the line, whichever input of the batch it is.
TEST_P(BadChange, AnAddedFileThatIsMissingMalformedOrNotFinite) {
  const std::string good = (dir_ / "good.obj").string(), nan = (dir_ / "nan.obj").string();
  const std::string index = (dir_ / "index.obj").string();
  std::ofstream(good) << "o fine\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  std::ofstream(nan) << "o a\nv 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n";
  std::ofstream(index) << "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nf 1 2 9\n";
  ChangeBatch b;
  b.add.push_back(Moved(store_.live.begin()->first, "fine"));
  // A reader's error keeps its code (a malformed file is Corruption, as in a build).
  auto refused = [&](const std::vector<std::string>& names) {
    auto done = w_->Commit(b);
    ASSERT_FALSE(done.ok()) << "committed as revision " << done->revision;
    for (const std::string& name : names)
      EXPECT_TRUE(Contains(done.status(), name)) << done.status().ToString();
    ExpectUnchanged();
  };
  b.add_files = {good, nan};
  refused({store_.path, nan + ":4", "non-finite"});
  b.add_files = {index, good};
  refused({store_.path, index + ":7", "out of range"});
  b.add_files = {good, "tanker:0"};
  refused({store_.path, "tanker:0"});
  b.add_files = {(dir_ / "missing.obj").string()};
  refused({store_.path, "missing.obj"});
  // The good file alone goes in, after the batch's own object.
  b.add_files = {good};
  auto done = w_->Commit(b);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_EQ(done->added, 2u);
  ASSERT_EQ(done->added_ids.size(), 2u);
  auto db = Database::Open(store_.path);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  auto record = (*db)->Object(done->added_ids[1]);
  ASSERT_TRUE(record.ok()) << record.status().ToString();
  EXPECT_EQ(record->name, "fine");
  EXPECT_EQ(record->source, good);
}

TEST_P(BadChange, ASecondWriterFailsAtOnceInThisProcessAndAnother) {
  auto start = std::chrono::steady_clock::now();
  auto second = ChangeWriter::Open(store_.path);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), Status::Code::kIOError) << second.status().ToString();
  EXPECT_TRUE(Contains(second.status(), store_.path)) << second.status().ToString();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 2.0);
  // In another process: exit 0 when refused with IOError naming the store within 2 s.
  const std::string store = store_.path;
  const int status = testing::RunInChild([&] {
    const auto t = std::chrono::steady_clock::now();
    auto w = ChangeWriter::Open(store);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    if (w.ok()) return 1;
    if (w.status().code() != Status::Code::kIOError || !Contains(w.status(), store)) return 2;
    return seconds < 2.0 ? 0 : 3;
  });
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << testing::DescribeWaitStatus(status);
  ExpectUnchanged();
  // Once the first writer is gone a second one opens.
  w_.reset();
  auto next = ChangeWriter::Open(store_.path);
  ASSERT_TRUE(next.ok()) << next.status().ToString();
  EXPECT_EQ((*next)->revision(), store_.revision);
}

TEST_P(BadChange, ARevisionNeverCommittedOrRetired) {
  for (const uint64_t revision : {store_.revision + 1, store_.revision + 100, uint64_t{0}, uint64_t{1}}) {
    auto db = Database::Open(store_.path, {.revision = revision});
    ASSERT_FALSE(db.ok()) << "revision " << revision;
    EXPECT_EQ(db.status().code(), Status::Code::kNotFound) << db.status().ToString();
    EXPECT_TRUE(Contains(db.status(), store_.path)) << db.status().ToString();
    EXPECT_TRUE(Contains(db.status(), "revision " + std::to_string(revision))) << db.status().ToString();
  }
  auto kept = Database::Open(store_.path, {.revision = store_.revision - 1});
  ASSERT_TRUE(kept.ok()) << kept.status().ToString();
  EXPECT_EQ((*kept)->revision(), store_.revision - 1);
}

TEST_P(BadChange, AStoreThatDoesNotExistAndBadBatchesOfAShardedStore) {
  const std::string missing = dir_.file("store/none.mkt");
  auto w = ChangeWriter::Open(missing);
  ASSERT_FALSE(w.ok());
  EXPECT_TRUE(Contains(w.status(), missing)) << w.status().ToString();
  EXPECT_FALSE(std::filesystem::exists(ChangesFolder(missing)));
  auto revisions = ListRevisions(missing);
  ASSERT_FALSE(revisions.ok());
  EXPECT_TRUE(Contains(revisions.status(), missing)) << revisions.status().ToString();

  BuildOptions o;
  o.backend = GetParam() == Backend::kHdf5 ? BuildOptions::Backend::kHdf5 : BuildOptions::Backend::kPagedFile;
  o.block_size = 1024;
  o.blocks_per_page = 2;
  o.threads = 1;
  o.shards = 2;
  const std::string manifest = dir_.file("store/sharded.mkts");
  ASSERT_TRUE(BuildFromObjects(testing::ClusteredScene(80, 2), manifest, o).ok());
  // A sharded store takes changes, and refuses a bad batch as a store file does: nothing committed.
  auto sharded = ChangeWriter::Open(manifest);
  ASSERT_TRUE(sharded.ok()) << sharded.status().ToString();
  ChangeBatch unknown;
  unknown.remove = {80};
  auto r = (*sharded)->Commit(unknown);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kInvalidArgument) << r.status().ToString();
  // Not Contains(): with this literal GCC 12 warns (-Wrestrict) inside std::string, falsely.
  EXPECT_NE(r.status().message().find("no object 80 "), std::string::npos) << r.status().ToString();
  ChangeBatch nan;
  nan.add = testing::ClusteredScene(1, 3);
  nan.add[0].mesh.vertices[4] = std::nan("");
  r = (*sharded)->Commit(nan);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kInvalidArgument) << r.status().ToString();
  EXPECT_TRUE(Contains(r.status(), manifest)) << r.status().ToString();
  sharded->reset();
  auto log = ListRevisions(manifest);
  ASSERT_TRUE(log.ok()) << log.status().ToString();
  ASSERT_EQ(log->size(), 1u);
  EXPECT_EQ(log->back().revision, 0u);
  EXPECT_EQ(log->back().objects, 80u);
  ExpectUnchanged();
}

// The file's bytes with `edit` applied.
void EditFile(const std::string& path, const std::function<void(std::string*)>& edit) {
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  edit(&bytes);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

// Database::Open and ChangeWriter::Open both refuse with Corruption naming `file` (and each of `more`).
void ExpectCorruption(const std::string& store, const std::string& file, const std::vector<std::string>& more,
                      const std::string& what) {
  SCOPED_TRACE(what);
  auto db = Database::Open(store);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), Status::Code::kCorruption) << db.status().ToString();
  EXPECT_TRUE(Contains(db.status(), file)) << db.status().ToString();
  for (const std::string& m : more) EXPECT_TRUE(Contains(db.status(), m)) << db.status().ToString();
  auto w = ChangeWriter::Open(store);
  ASSERT_FALSE(w.ok());
  EXPECT_TRUE(Contains(w.status(), file)) << w.status().ToString();
}

TEST_P(BadChange, ADamagedRevisionFile) {
  w_.reset();
  const std::string rev = ChangesFile(Folder(), RevisionFileName(store_.revision));
  const std::string saved = dir_.file("saved.rev");
  std::filesystem::copy_file(rev, saved);
  std::string text;
  EditFile(rev, [&](std::string* b) { text = *b; });
  // A flipped byte in each line: a number, a name, a keyword; every one caught, naming the line.
  size_t line = 0;
  for (size_t at = 0; at < text.size(); at = text.find('\n', at) + 1) {
    ++line;
    const size_t pos = at + 1 + (line * 7) % (text.find('\n', at) - at - 1);
    std::filesystem::copy_file(saved, rev, std::filesystem::copy_options::overwrite_existing);
    EditFile(rev, [&](std::string* b) { (*b)[pos] ^= 0x01; });
    ExpectCorruption(store_.path, rev, {"line "},
                     "byte " + std::to_string(pos) + " of line " + std::to_string(line));
  }
  // Cut in the middle of a line and at the end of one.
  for (const size_t keep : {text.size() / 2, text.rfind('\n', text.size() - 2) + 1, size_t{0}}) {
    std::filesystem::copy_file(saved, rev, std::filesystem::copy_options::overwrite_existing);
    EditFile(rev, [&](std::string* b) { b->resize(keep); });
    ExpectCorruption(store_.path, rev, {keep ? "line " : "empty"},
                     "cut to " + std::to_string(keep) + " bytes");
  }
  std::filesystem::copy_file(saved, rev, std::filesystem::copy_options::overwrite_existing);
  auto w = ChangeWriter::Open(store_.path, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  w_ = std::move(*w);
  ExpectUnchanged();
}

TEST_P(BadChange, ADamagedDeltaStoreOrIdFile) {
  w_.reset();
  const RevisionManifest head = Head();
  ASSERT_FALSE(head.deltas.empty());
  ASSERT_FALSE(head.removals.empty());
  struct Case {
    std::string file;
    std::function<void(std::string*)> damage;
    std::string what;
  };
  const std::vector<Case> cases = {
      {head.deltas[0].store.name, [](std::string* b) { (*b)[b->size() - 3] ^= 0x20; },
       "a delta store's last bytes"},
      {head.deltas[0].store.name, [](std::string* b) { b->resize(b->size() - 100); },
       "a delta store cut short"},
      {head.deltas[0].ids.name, [](std::string* b) { (*b)[b->size() / 2] ^= 0x01; }, "a delta's id file"},
      {head.removals[0].file.name, [](std::string* b) { (*b)[b->size() - 9] ^= 0x04; }, "a removal id file"},
      {head.removals[0].file.name, [](std::string* b) { b->clear(); }, "a removal id file emptied"},
  };
  for (const Case& c : cases) {
    const std::string path = ChangesFile(Folder(), c.file);
    const std::string saved = dir_.file("saved");
    std::filesystem::copy_file(path, saved, std::filesystem::copy_options::overwrite_existing);
    EditFile(path, c.damage);
    ExpectCorruption(store_.path, path, {}, c.what);
    std::filesystem::copy_file(saved, path, std::filesystem::copy_options::overwrite_existing);
  }
  auto w = ChangeWriter::Open(store_.path, {.compact_threshold = 0, .threads = 1});
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  w_ = std::move(*w);
  ExpectUnchanged();
}

INSTANTIATE_TEST_SUITE_P(Backends, BadChange, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

}  // namespace
}  // namespace mktree
