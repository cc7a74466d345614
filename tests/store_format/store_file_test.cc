// Store files, parameterised over both backends and both codecs: round trips, reopen equality,
// corruption and truncation detection, foreign files, atomic commit, the writer lock, concurrent reads.
#include "engine/store_format/store_file.h"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <thread>

#include "engine/store_format/leaf_codec.h"
#include "engine/store_format/leaf_source.h"
#include "storage/memory_page_store.h"
#include "storage/page_cache.h"
#include "store_format/store_test_util.h"

namespace mktree {
namespace {

using testing::BuiltStore;
using testing::TempDir;

std::vector<uint8_t> ReadFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), {});
}
void WriteFile(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}
// XORs one byte of a file in place (flipping it twice restores it).
void FlipByte(const std::string& path, size_t off, uint8_t mask) {
  std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
  f.seekg(static_cast<std::streamoff>(off));
  char c = 0;
  f.read(&c, 1);
  c = static_cast<char>(c ^ mask);
  f.seekp(static_cast<std::streamoff>(off));
  f.write(&c, 1);
}
std::vector<size_t> FindAll(const std::vector<uint8_t>& hay, const uint8_t* needle, size_t n) {
  std::vector<size_t> out;
  if (n == 0 || hay.size() < n) return out;
  for (auto it = hay.begin(); (it = std::search(it, hay.end(), needle, needle + n)) != hay.end(); ++it)
    out.push_back(static_cast<size_t>(it - hay.begin()));
  return out;
}

struct Param {
  Backend backend;
  Codec codec;
};
void PrintTo(const Param& p, std::ostream* os) {
  *os << BackendName(p.backend) << (p.codec == Codec::kZstd ? "/zstd" : "/none");
}
std::string ParamName(const ::testing::TestParamInfo<Param>& p) {
  return std::string(BackendName(p.param.backend)) + (p.param.codec == Codec::kZstd ? "_zstd" : "_none");
}

class StoreFileTest : public ::testing::TestWithParam<Param> {
 protected:
  StoreOptions Options() const {
    StoreOptions o;
    o.backend = GetParam().backend;
    o.codec.codec = GetParam().codec;
    return o;
  }
  // Writes a store of `n` objects at `path`; keeps the objects and the built tree.
  Status Write(const std::string& path, uint32_t n, uint32_t seed) {
    objects_ = testing::MakeObjects(n, seed);
    for (SceneObject& o : objects_) {  // a record of every part: two sources, attributes on some objects
      o.source = o.id % 2 ? "odd.obj" : "even.obj";
      if (o.id % 3 == 0)
        o.attributes = {{"group", "g" + std::to_string(o.id % 7)}, {"id", std::to_string(o.id)}};
    }
    auto w = StoreWriter::Create(path, Options());
    if (!w.ok()) return w.status();
    MKTREE_RETURN_IF_ERROR(
        testing::BuildTestStore(objects_, Options().codec, Options().params, &(*w)->pages(), &built_));
    for (const SceneObject& o : objects_)
      MKTREE_RETURN_IF_ERROR(
          (*w)->AppendObject(o.id, built_.object_leaf[o.id], o.Aabb(), o.name, o.source, o.attributes));
    return (*w)->Commit(built_.tree, "{\"objects\": " + std::to_string(n) + "}");
  }
  // Reads every leaf through `cache` and checks every object against the originals.
  void CheckAllLeaves(const StoreReader& r, PageCache* cache) {
    const uint64_t mem_page = r.pages().page_bytes();
    size_t seen = 0;
    for (uint32_t l = 0; l < r.tree().leaves.size(); ++l) {
      const LeafInfo& leaf = r.tree().leaves[l];
      std::vector<PageHandle> handles;
      std::vector<const uint8_t*> ptrs;
      for (uint32_t i = 0; i < leaf.page_count; ++i) {
        auto h = cache->Pin(leaf.first_page + i, nullptr);
        ASSERT_TRUE(h.ok()) << h.status().ToString();
        ptrs.push_back(h->data());
        handles.push_back(std::move(h).value());
      }
      auto v = LeafView::Parse(r.pages().name(), l, leaf.first_page, ptrs, mem_page, true);
      ASSERT_TRUE(v.ok()) << v.status().ToString();
      ASSERT_EQ(v->size(), leaf.object_count);
      for (size_t i = 0; i < v->size(); ++i) {
        const ObjectEntryView& e = v->entry(i);
        ASSERT_LT(e.id, objects_.size());
        EXPECT_EQ(*r.ObjectLeaf(e.id), l);
        EXPECT_EQ(e.box, testing::StoredBox(objects_[e.id].mesh));
        Mesh m;
        ASSERT_TRUE(DecodeObjectMesh(e, &m).ok());
        ASSERT_TRUE(testing::SameMesh(m, objects_[e.id].mesh)) << "object " << e.id;
        ++seen;
      }
    }
    EXPECT_EQ(seen, objects_.size());
  }
  // Opens the store and reads every leaf; returns the first error.
  Status OpenAndReadAll(const std::string& path) {
    auto r = StoreReader::Open(path);
    if (!r.ok()) return r.status();
    PageCache cache(&(*r)->pages(), 0);
    const LeafSource leaves(**r, cache, true);
    for (uint32_t l = 0; l < (*r)->tree().leaves.size(); ++l) {
      auto v = leaves.Read(l, nullptr);
      if (!v.ok()) return v.status();
      for (const auto& e : v->view.entries()) {
        Mesh m;
        MKTREE_RETURN_IF_ERROR(DecodeObjectMesh(e, &m));
        if (!testing::SameMesh(m, objects_.at(e.id).mesh)) return Status::Internal("wrong answer");
      }
    }
    // Every record, through the same cache (record pages are pages of the store too).
    RecordReader records((*r)->record_layout(), &cache, true);
    for (const SceneObject& o : objects_) {
      auto rec = records.Get(o.id, nullptr);
      if (!rec.ok()) return rec.status();
      if ((*rec)->name != o.name || (*rec)->attributes != o.attributes || !((*rec)->box == o.Aabb()) ||
          *(*r)->SourceName(**rec) != o.source)
        return Status::Internal("wrong record");
    }
    return Status::Ok();
  }

  // in_page[i]: byte i of the file lies in a leaf page (pages are stored verbatim in both backends).
  std::vector<bool> PageBytes(const std::string& path, const std::vector<uint8_t>& file) {
    std::vector<bool> in_page(file.size(), false);
    auto r = StoreReader::Open(path);
    EXPECT_TRUE(r.ok());
    if (!r.ok()) return in_page;
    std::vector<uint8_t> buf((*r)->pages().page_bytes());
    for (uint64_t p = 0; p < (*r)->pages().page_count(); ++p) {
      EXPECT_TRUE((*r)->pages().ReadPage(p, buf.data()).ok());
      for (size_t a : FindAll(file, buf.data(), buf.size()))
        std::fill(in_page.begin() + a, in_page.begin() + a + buf.size(), true);
    }
    return in_page;
  }

  TempDir dir_;
  std::vector<SceneObject> objects_;
  BuiltStore built_;
};

TEST_P(StoreFileTest, EveryLeafRoundTripsAndTheStoreReopensEqual) {
  const std::string path = dir_.file("store.mkt");
  ASSERT_TRUE(Write(path, 400, 1).ok());
  EXPECT_FALSE(std::filesystem::exists(path + ".lock"));
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const StoreReader& s = **r;
  EXPECT_EQ(s.options().backend, GetParam().backend);
  EXPECT_EQ(s.options().codec.codec, GetParam().codec);
  EXPECT_EQ(s.options().codec.zstd_level, CodecOptions{}.zstd_level);
  EXPECT_EQ(s.options().params.mem_page(), BuildParams().mem_page());
  EXPECT_EQ(s.options().params.balance_r, BuildParams().balance_r);
  EXPECT_EQ(s.options().params.split_tree_node_budget, BuildParams().split_tree_node_budget);
  EXPECT_TRUE(SameTree(s.tree(), built_.tree));
  EXPECT_EQ(s.tree().nodes.size(), built_.tree.nodes.size());
  EXPECT_EQ(s.tree().split_nodes.size(), built_.tree.split_nodes.size());
  EXPECT_GT(s.tree().split_nodes.size(), 0u);
  EXPECT_EQ(s.stats_json(), "{\"objects\": 400}");
  ASSERT_EQ(s.object_count(), objects_.size());
  for (const SceneObject& o : objects_) {
    EXPECT_EQ(*s.ObjectName(o.id), o.name);
    EXPECT_EQ(*s.ObjectLeaf(o.id), built_.object_leaf[o.id]);
  }
  for (uint32_t id : {400u, UINT32_MAX}) {
    EXPECT_EQ(s.ObjectName(id).status().code(), Status::Code::kInvalidArgument);
    EXPECT_EQ(s.ObjectLeaf(id).status().code(), Status::Code::kInvalidArgument);
    EXPECT_EQ(s.ReadRecord(id, nullptr, true, nullptr).status().code(), Status::Code::kInvalidArgument);
  }
  uint64_t pages = 0;
  for (const auto& l : built_.tree.leaves) pages += l.page_count;
  EXPECT_EQ(s.leaf_page_count(), pages);
  EXPECT_GT(pages, built_.tree.leaves.size());  // some multi-page leaves
  EXPECT_EQ(s.pages().page_count(), pages + s.objects().record_directory.size());
  EXPECT_GT(s.objects().record_directory.size(), 1u);
  EXPECT_EQ(s.objects().sources, (std::vector<std::string>{"even.obj", "odd.obj"}));
  PageCache cache(&s.pages(), 16);
  CheckAllLeaves(s, &cache);
  EXPECT_TRUE(OpenAndReadAll(path).ok());
  const uint64_t total = s.pages().page_count();
  EXPECT_FALSE(s.pages().ReadPage(total, std::vector<uint8_t>(s.pages().page_bytes()).data()).ok());
}

// The object table written on another thread while the leaf pages are (as ingest does, after
// BeginObjects) gives the store the sequential order gives; a leaf page left out fails the commit.
TEST_P(StoreFileTest, ObjectsAppendedWhileLeafPagesAreWrittenGiveTheSameStore) {
  const std::string sequential = dir_.file("sequential.mkt"), together = dir_.file("together.mkt");
  ASSERT_TRUE(Write(sequential, 600, 17).ok());
  MemoryPageStore leaves(Options().params.mem_page());
  BuiltStore built;
  ASSERT_TRUE(testing::BuildTestStore(objects_, Options().codec, Options().params, &leaves, &built).ok());
  ASSERT_GT(leaves.page_count(), 8u);
  std::vector<uint8_t> page(leaves.page_bytes());
  for (const bool leave_one_out : {false, true}) {
    SCOPED_TRACE(leave_one_out ? "a leaf page left out" : "every leaf page");
    auto w = StoreWriter::Create(together, Options());
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    ASSERT_TRUE((*w)->BeginObjects(leaves.page_count()).ok());
    Status table;
    std::thread other([&] {
      for (const SceneObject& o : objects_) {
        table = (*w)->AppendObject(o.id, built.object_leaf[o.id], o.Aabb(), o.name, o.source, o.attributes);
        if (!table.ok()) return;
      }
    });
    const uint64_t written = leaves.page_count() - (leave_one_out ? 1 : 0);
    for (uint64_t p = 0; p < written; ++p) {
      ASSERT_TRUE(leaves.ReadPage(p, page.data()).ok());
      ASSERT_TRUE((*w)->pages().WritePage(p, page.data()).ok());
    }
    const Status past = (*w)->pages().WritePage(leaves.page_count(), page.data());
    EXPECT_EQ(past.code(), Status::Code::kInvalidArgument) << past.ToString();
    other.join();
    ASSERT_TRUE(table.ok()) << table.ToString();
    const Status st = (*w)->Commit(built.tree, "{\"objects\": 600}");
    if (leave_one_out) {
      EXPECT_FALSE(st.ok());
      EXPECT_NE(st.message().find("leaf pages written"), std::string::npos) << st.ToString();
      w->reset();
      EXPECT_TRUE(OpenAndReadAll(together).ok()) << "the previous store is kept";
      for (const auto& f : std::filesystem::directory_iterator(dir_.path()))
        EXPECT_EQ(f.path().string().find(".tmp."), std::string::npos) << f.path();
      continue;
    }
    ASSERT_TRUE(st.ok()) << st.ToString();
    EXPECT_TRUE(OpenAndReadAll(together).ok());
    if (GetParam().backend == Backend::kPagedFile) {
      EXPECT_EQ(ReadFile(together), ReadFile(sequential));
    }
  }
}

TEST_P(StoreFileTest, EmptyStore) {
  const std::string path = dir_.file("empty.mkt");
  auto w = StoreWriter::Create(path, Options());
  ASSERT_TRUE(w.ok());
  MKTree tree;
  ASSERT_TRUE((*w)->Commit(tree, "").ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ((*r)->object_count(), 0u);
  EXPECT_EQ((*r)->pages().page_count(), 0u);
  EXPECT_TRUE((*r)->tree().empty());
}

// A store of format version 1 (its leaf filter 8-bit levels in 6 bytes an object) is refused by name and
// version, not misread.
TEST_P(StoreFileTest, OlderFormatVersionIsRefused) {
  const std::string path = dir_.file("v1.mkt");
  ASSERT_TRUE(Write(path, 100, 1).ok());
  const uint32_t old_version = 2;
  if (GetParam().backend == Backend::kPagedFile) {
    std::vector<uint8_t> file = ReadFile(path);
    std::memcpy(file.data() + 8, &old_version, 4);  // (little-endian, as the format)
    WriteFile(path, file);
  } else {
    hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    hid_t a = H5Aopen(f, "format_version", H5P_DEFAULT);
    ASSERT_GE(a, 0);
    ASSERT_GE(H5Awrite(a, H5T_NATIVE_UINT32, &old_version), 0);
    H5Aclose(a);
    H5Fclose(f);
  }
  auto r = StoreReader::Open(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kUnsupported) << r.status().ToString();
  EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
  // (Each backend reads its own current version.)
  EXPECT_NE(r.status().message().find("format version 2 (this build reads version "), std::string::npos)
      << r.status().message();
  EXPECT_NE(r.status().message().find("): build the store again"), std::string::npos) << r.status().message();
}

TEST_P(StoreFileTest, FlippedBytesInLeafPagesAreDetected) {
  const std::string path = dir_.file("flip.mkt");
  ASSERT_TRUE(Write(path, 150, 2).ok());
  const std::vector<uint8_t> good = ReadFile(path);
  // Where each page lies in the file (pages are stored verbatim in both backends).
  std::vector<size_t> page_offset;
  {
    auto r = StoreReader::Open(path);
    ASSERT_TRUE(r.ok());
    std::vector<uint8_t> buf((*r)->pages().page_bytes());
    for (uint64_t p = 0; p < (*r)->pages().page_count(); ++p) {
      ASSERT_TRUE((*r)->pages().ReadPage(p, buf.data()).ok());
      auto at = FindAll(good, buf.data(), buf.size());
      ASSERT_EQ(at.size(), 1u);
      page_offset.push_back(at[0]);
    }
  }
  std::mt19937 g(3);
  const uint64_t mem_page = BuildParams().mem_page();
  for (int trial = 0; trial < 60; ++trial) {
    const size_t page = g() % page_offset.size();
    const size_t off =
        trial < 3 ? trial * (mem_page - 1) / 2 : g() % mem_page;  // first, middle, last bytes too
    const uint8_t mask = static_cast<uint8_t>(1u << (g() % 8));
    FlipByte(path, page_offset[page] + off, mask);
    Status st = OpenAndReadAll(path);
    FlipByte(path, page_offset[page] + off, mask);
    ASSERT_FALSE(st.ok()) << "flip in page " << page << " byte " << off << " not detected";
    EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
    EXPECT_NE(st.message().find(path), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("page " + std::to_string(page)), std::string::npos) << st.message();
  }
  EXPECT_EQ(ReadFile(path), good);
  EXPECT_TRUE(OpenAndReadAll(path).ok());
}

TEST_P(StoreFileTest, FlippedBytesInMetadataAreDetected) {
  const std::string path = dir_.file("meta.mkt");
  ASSERT_TRUE(Write(path, 150, 4).ok());
  const std::vector<uint8_t> good = ReadFile(path);
  const std::vector<bool> in_page = PageBytes(path, good);
  auto expect_refused = [&](size_t off, const char* what) {
    FlipByte(path, off, 0x20);
    auto r = StoreReader::Open(path);
    EXPECT_FALSE(r.ok()) << what << ": flip at " << off << " not detected";
    if (!r.ok()) {
      EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
    }
    FlipByte(path, off, 0x20);
  };
  auto metadata_hits = [&](const void* p, size_t n) {
    std::vector<size_t> out;
    for (size_t a : FindAll(good, static_cast<const uint8_t*>(p), n))
      if (!in_page[a]) out.push_back(a);
    return out;
  };
  // Distinctive metadata bytes, found in the file: a source file name, the stats JSON, a leaf's box.
  // (Object names live in the record pages, which open does not read: FlippedBytesInLeafPagesAreDetected.)
  const std::string name = objects_[7].name;
  EXPECT_TRUE(metadata_hits(name.data(), name.size()).empty());
  const std::string source = "even.obj";
  auto at = metadata_hits(source.data(), source.size());
  ASSERT_FALSE(at.empty());
  expect_refused(at[0] + 2, "source");
  const std::string stats = "{\"objects\": 150}";
  at = metadata_hits(stats.data(), stats.size());
  ASSERT_FALSE(at.empty());
  expect_refused(at[0] + 3, "stats JSON");
  const Box3f& box = built_.tree.leaves[3].box;
  float boxfloats[6] = {box.min[0], box.min[1], box.min[2], box.max[0], box.max[1], box.max[2]};
  at = metadata_hits(boxfloats, sizeof(boxfloats));
  ASSERT_FALSE(at.empty());
  for (size_t a : at) expect_refused(a + 5, "leaf box");

  if (GetParam().backend == Backend::kPagedFile) {
    // Every byte outside the leaf pages is covered: the header page and all sections.
    const uint64_t mem_page = BuildParams().mem_page();
    auto r = StoreReader::Open(path);
    ASSERT_TRUE(r.ok());
    const uint64_t data_end = (1 + (*r)->pages().page_count()) * mem_page;  // leaf and record pages
    for (size_t off = 0; off < 256; ++off) expect_refused(off, "header");
    for (size_t off = 256; off < mem_page; off += 101) expect_refused(off, "header padding");
    for (size_t off = data_end; off < good.size(); off += 31) expect_refused(off, "section");
  } else {
    // HDF5: a flip outside our checksummed data may land in unused space; it must never yield a store
    // that reads differently. Sample the bytes outside the pages.
    int refused = 0, accepted = 0, page_errors = 0;
    for (size_t off = 0; off < good.size(); off += 23) {
      if (in_page[off]) continue;
      FlipByte(path, off, 0x20);
      auto rr = StoreReader::Open(path);
      if (!rr.ok()) {
        ++refused;
      } else {
        ++accepted;
        EXPECT_TRUE(SameTree((*rr)->tree(), built_.tree)) << "flip at " << off;
        ASSERT_EQ((*rr)->object_count(), objects_.size()) << "flip at " << off;
        // Names are read from the record pages: an error naming a page (damaged chunk index), or the name.
        for (const auto& o : objects_) {
          auto n = (*rr)->ObjectName(o.id);
          if (n.ok()) {
            ASSERT_EQ(*n, o.name) << "flip at " << off;
          } else {
            EXPECT_NE(n.status().message().find("page "), std::string::npos) << n.status().message();
          }
        }
        EXPECT_EQ((*rr)->stats_json(), stats);
        // Damage to HDF5's chunk index shows at the page read: an error naming the page, never a wrong
        // answer.
        Status st = OpenAndReadAll(path);
        if (!st.ok()) {
          ++page_errors;
          EXPECT_NE(st.code(), Status::Code::kInternal) << "wrong answer after a flip at " << off;
          EXPECT_NE(st.message().find("page "), std::string::npos) << st.message();
          if (page_errors < 3) std::printf("[hdf5 metadata flip at %zu] %s\n", off, st.ToString().c_str());
        }
      }
      FlipByte(path, off, 0x20);
    }
    std::printf("[hdf5 metadata flips] refused at open %d, page read errors %d, harmless %d\n", refused,
                page_errors, accepted - page_errors);
    EXPECT_GT(refused, 0);
  }
  EXPECT_EQ(ReadFile(path), good);
  EXPECT_TRUE(StoreReader::Open(path).ok());
}

TEST_P(StoreFileTest, TruncatedFilesAreRefused) {
  const std::string path = dir_.file("trunc.mkt");
  ASSERT_TRUE(Write(path, 120, 5).ok());
  const std::vector<uint8_t> good = ReadFile(path);
  const size_t n = good.size();
  for (size_t cut : std::vector<size_t>{0, 1, 7, 8, 100, 255, 256, 4096, 12287, 12288, 12289, n / 3, n / 2,
                                        n - 4096, n - 100, n - 1}) {
    if (cut >= n) continue;
    WriteFile(path, std::vector<uint8_t>(good.begin(), good.begin() + cut));
    auto r = StoreReader::Open(path);
    ASSERT_FALSE(r.ok()) << "truncated at " << cut << " of " << n << " accepted";
    EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
  }
  // Trailing garbage is refused by the paged file (exact size); HDF5 ignores bytes past its end of file.
  std::vector<uint8_t> longer = good;
  longer.resize(n + 10, 0xab);
  WriteFile(path, longer);
  if (GetParam().backend == Backend::kPagedFile) {
    EXPECT_FALSE(StoreReader::Open(path).ok());
  }
}

TEST_P(StoreFileTest, UncommittedWriterLeavesNothing) {
  const std::string path = dir_.file("half.mkt");
  objects_ = testing::MakeObjects(200, 6);
  {
    auto w = StoreWriter::Create(path, Options());
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    ASSERT_TRUE(
        testing::BuildTestStore(objects_, Options().codec, Options().params, &(*w)->pages(), &built_).ok());
    for (uint32_t i = 0; i < 100; ++i)
      ASSERT_TRUE((*w)->AppendObject(i, built_.object_leaf[i], objects_[i].name).ok());
    EXPECT_TRUE(std::filesystem::exists((*w)->temp_path()));
    EXPECT_FALSE(std::filesystem::exists(path));
    EXPECT_FALSE((*w)->AppendObject(5, 0, "out of order").ok());
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_TRUE(std::filesystem::is_empty(dir_.path())) << "temp or lock file left behind";
  EXPECT_EQ(StoreReader::Open(path).status().code(), Status::Code::kNotFound);
}

TEST_P(StoreFileTest, KilledWriterLeavesNothingThatOpens) {
  const std::string path = dir_.file("killed.mkt");
  objects_ = testing::MakeObjects(100, 7);
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    // Child: write every page and the object table, then die without committing or cleaning up.
    auto w = StoreWriter::Create(path, Options());
    if (!w.ok()) ::_exit(2);
    if (!testing::BuildTestStore(objects_, Options().codec, Options().params, &(*w)->pages(), &built_).ok())
      ::_exit(3);
    if (!(*w)->pages().Sync().ok()) ::_exit(4);
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_FALSE(std::filesystem::exists(path));
  const std::string temp = path + ".tmp." + std::to_string(pid);
  ASSERT_TRUE(std::filesystem::exists(temp));
  auto r = StoreReader::Open(temp);
  EXPECT_FALSE(r.ok()) << "an unfinished store opened";
  // The dead writer's lock is gone with it: a new build succeeds.
  EXPECT_TRUE(Write(path, 50, 8).ok());
  EXPECT_TRUE(StoreReader::Open(path).ok());
}

TEST_P(StoreFileTest, CommitRejectsInconsistentTrees) {
  const std::string path = dir_.file("bad.mkt");
  objects_ = testing::MakeObjects(60, 9);
  auto w = StoreWriter::Create(path, Options());
  ASSERT_TRUE(w.ok());
  ASSERT_TRUE(
      testing::BuildTestStore(objects_, Options().codec, Options().params, &(*w)->pages(), &built_).ok());
  for (const auto& o : objects_) ASSERT_TRUE((*w)->AppendObject(o.id, built_.object_leaf[o.id], o.name).ok());
  MKTree tree = built_.tree;
  tree.leaves.back().page_count += 1;  // past the last page written
  Status st = (*w)->Commit(tree, "");
  EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
  EXPECT_FALSE((*w)->Commit(built_.tree, "").ok());  // no second chance
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST_P(StoreFileTest, SecondWriterIsRefused) {
  const std::string path = dir_.file("locked.mkt");
  {
    auto w1 = StoreWriter::Create(path, Options());
    ASSERT_TRUE(w1.ok());
    auto w2 = StoreWriter::Create(path, Options());  // same process
    ASSERT_FALSE(w2.ok());
    EXPECT_NE(w2.status().message().find("another writer"), std::string::npos) << w2.status().message();
    // Another process.
    std::fflush(nullptr);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      auto w = StoreWriter::Create(path, Options());
      ::_exit(w.ok() ? 1 : 0);
    }
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "another process got the writer lock";
    // A writer for a different store is independent.
    EXPECT_TRUE(StoreWriter::Create(dir_.file("other.mkt"), Options()).ok());
  }
  EXPECT_TRUE(StoreWriter::Create(path, Options()).ok());  // released with the first writer
}

TEST_P(StoreFileTest, ReadersSeeTheLastCommittedStoreDuringABuild) {
  const std::string path = dir_.file("live.mkt");
  ASSERT_TRUE(Write(path, 80, 10).ok());
  auto old_reader = StoreReader::Open(path);
  ASSERT_TRUE(old_reader.ok());
  const auto old_objects = objects_;
  // A rebuild in progress.
  std::vector<SceneObject> next = testing::MakeObjects(130, 11);
  auto w = StoreWriter::Create(path, Options());
  ASSERT_TRUE(w.ok());
  BuiltStore built;
  ASSERT_TRUE(testing::BuildTestStore(next, Options().codec, Options().params, &(*w)->pages(), &built).ok());
  for (const auto& o : next) ASSERT_TRUE((*w)->AppendObject(o.id, built.object_leaf[o.id], o.name).ok());
  auto during = StoreReader::Open(path);  // neither fails nor waits: the committed version
  ASSERT_TRUE(during.ok());
  EXPECT_EQ((*during)->object_count(), 80u);
  ASSERT_TRUE((*w)->Commit(built.tree, "{\"objects\": 130}").ok());
  auto after = StoreReader::Open(path);
  ASSERT_TRUE(after.ok());
  EXPECT_EQ((*after)->object_count(), 130u);
  EXPECT_EQ((*after)->stats_json(), "{\"objects\": 130}");
  // Readers opened before the rename still read their own (old) file.
  objects_ = old_objects;
  PageCache cache(&(*old_reader)->pages(), 4);
  CheckAllLeaves(**old_reader, &cache);
}

TEST_P(StoreFileTest, ConcurrentReaders) {
  const std::string path = dir_.file("threads.mkt");
  ASSERT_TRUE(Write(path, 300, 12).ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok());
  const StoreReader& s = **r;
  PageCache cache(&s.pages(), 6);  // small: forces concurrent misses and evictions
  std::vector<std::thread> threads;
  std::atomic<int> failures{0};
  for (int t = 0; t < 6; ++t)
    threads.emplace_back([&, t] {
      std::mt19937 g(t);
      std::vector<uint8_t> buf(s.pages().page_bytes());
      for (int i = 0; i < 150; ++i) {
        const uint32_t l = g() % s.tree().leaves.size();
        const LeafInfo& leaf = s.tree().leaves[l];
        std::vector<PageHandle> hs;
        std::vector<const uint8_t*> ptrs;
        std::vector<std::vector<uint8_t>> direct;
        for (uint32_t p = 0; p < leaf.page_count; ++p) {
          if (t % 2 == 0) {
            auto h = cache.Pin(leaf.first_page + p, nullptr);
            if (!h.ok()) {
              ++failures;
              return;
            }
            ptrs.push_back(h->data());
            hs.push_back(std::move(h).value());
          } else {  // straight from the store
            direct.emplace_back(s.pages().page_bytes());
            if (!s.pages().ReadPage(leaf.first_page + p, direct.back().data()).ok()) {
              ++failures;
              return;
            }
            ptrs.push_back(direct.back().data());
          }
        }
        auto v = LeafView::Parse(s.pages().name(), l, leaf.first_page, ptrs, s.pages().page_bytes(), true);
        if (!v.ok()) {
          ++failures;
          continue;
        }
        for (const auto& e : v->entries()) {
          Mesh m;
          if (!DecodeObjectMesh(e, &m).ok() || !testing::SameMesh(m, objects_[e.id].mesh)) ++failures;
        }
      }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(failures.load(), 0);
  const auto k = cache.counters();
  EXPECT_EQ(k.hits + k.misses, k.lookups);
}

TEST_P(StoreFileTest, DirectIoReadsTheSameBytesOrSaysWhyNot) {
  const std::string path = dir_.file("direct.mkt");
  ASSERT_TRUE(Write(path, 100, 13).ok());
  ReadOptions ro;
  ro.direct_io = true;
  auto r = StoreReader::Open(path, ro);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  if (GetParam().backend == Backend::kHdf5) {
    EXPECT_FALSE((*r)->notice().empty());
  }
  if (!(*r)->notice().empty()) std::printf("[direct io] %s\n", (*r)->notice().c_str());
  EXPECT_EQ((*r)->options().direct_io, (*r)->notice().empty());
  auto plain = StoreReader::Open(path);
  ASSERT_TRUE(plain.ok());
  std::vector<uint8_t> a((*r)->pages().page_bytes()), b(a.size());
  for (uint64_t p = 0; p < (*r)->pages().page_count(); ++p) {
    ASSERT_TRUE((*r)->pages().ReadPage(p, a.data()).ok());
    ASSERT_TRUE((*plain)->pages().ReadPage(p, b.data()).ok());
    ASSERT_EQ(a, b);
  }
  PageCache cache(&(*r)->pages(), 2);  // cache buffers are aligned: the O_DIRECT path without a bounce
  CheckAllLeaves(**r, &cache);
}

// No store serves pages in place (PageStore::MappedPage): a paged file mapped read-only kept every page
// touched through the mapping in the process's RSS, which then grew with the pages a run read instead of
// with the cache. Every miss is a read, of the same bytes.
TEST_P(StoreFileTest, PagesAreReadNeverServedInPlace) {
  const std::string path = dir_.file("mapped.mkt");
  ASSERT_TRUE(Write(path, 300, 21).ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const PageStore& pages = (*r)->pages();
  std::vector<uint8_t> a(pages.page_bytes());
  for (uint64_t p = 0; p < pages.page_count(); ++p) {
    ASSERT_TRUE(pages.ReadPage(p, a.data()).ok());
    EXPECT_EQ(pages.MappedPage(p), nullptr) << "page " << p;
  }
  // Through a one-page cache every leaf is read, evicted and met again: once read, then in place.
  PageCache cache(&pages, 1);
  CheckAllLeaves(**r, &cache);
  CheckAllLeaves(**r, &cache);
  ReadOptions ro;
  ro.direct_io = true;
  auto direct = StoreReader::Open(path, ro);
  ASSERT_TRUE(direct.ok());
  if ((*direct)->options().direct_io) {
    ASSERT_TRUE((*direct)->pages().ReadPage(0, a.data()).ok());
    EXPECT_EQ((*direct)->pages().MappedPage(0), nullptr);
  }
}

// A page flipped on disk after its first read is refused when it is loaded into the cache again.
TEST_P(StoreFileTest, PagesChangedOnDiskAfterTheirFirstReadAreStillRefused) {
  const std::string path = dir_.file("mapped_flip.mkt");
  ASSERT_TRUE(Write(path, 300, 22).ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok());
  const LeafInfo leaf = (*r)->tree().leaves[0];
  PageCache cache(&(*r)->pages(), 0);
  const uint64_t mem_page = (*r)->pages().page_bytes();
  const LeafSource leaves(**r, cache, true);
  ASSERT_TRUE(leaves.Read(0, nullptr).ok());
  if (GetParam().backend != Backend::kPagedFile) return;  // (where HDF5 keeps the page is its business)
  FlipByte(path, (1 + leaf.first_page) * mem_page + 100, 0x10);
  auto again = leaves.Read(0, nullptr);
  EXPECT_EQ(again.status().code(), Status::Code::kCorruption) << again.status().ToString();
}

INSTANTIATE_TEST_SUITE_P(Backends, StoreFileTest,
                         ::testing::Values(Param{Backend::kPagedFile, Codec::kZstd},
                                           Param{Backend::kPagedFile, Codec::kNone},
                                           Param{Backend::kHdf5, Codec::kZstd},
                                           Param{Backend::kHdf5, Codec::kNone}),
                         ParamName);

TEST(StoreOpenTest, ForeignFilesAreRefused) {
  TempDir dir;
  auto refused = [&](const std::string& path, const char* what) {
    auto r = StoreReader::Open(path);
    ASSERT_FALSE(r.ok()) << what;
    EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
  };
  const std::string empty = dir.file("empty");
  WriteFile(empty, {});
  refused(empty, "empty file");
  std::mt19937 g(1);
  std::vector<uint8_t> noise(100000);
  for (auto& b : noise) b = static_cast<uint8_t>(g());
  const std::string random = dir.file("random");
  WriteFile(random, noise);
  refused(random, "random bytes");
  std::memcpy(noise.data(), "MKTREEPF", 8);  // our magic, then garbage
  WriteFile(random, noise);
  refused(random, "paged-file magic then garbage");
  const unsigned char sig[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  std::memcpy(noise.data(), sig, 8);  // the HDF5 signature, then garbage
  WriteFile(random, noise);
  refused(random, "HDF5 signature then garbage");
  const std::string text = dir.file("text");
  WriteFile(text, std::vector<uint8_t>{'h', 'e', 'l', 'l', 'o'});
  refused(text, "short text");
  // A valid HDF5 file that is not ours.
  const std::string foreign = dir.file("foreign.h5");
  {
    hid_t f = H5Fcreate(foreign.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    hsize_t dims[1] = {10};
    hid_t space = H5Screate_simple(1, dims, nullptr);
    hid_t d = H5Dcreate2(f, "pages", H5T_NATIVE_INT, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    int data[10] = {};
    H5Dwrite(d, H5T_NATIVE_INT, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
    H5Dclose(d);
    H5Sclose(space);
    H5Fclose(f);
  }
  refused(foreign, "foreign HDF5 file");
  auto missing = StoreReader::Open(dir.file("missing"));
  EXPECT_EQ(missing.status().code(), Status::Code::kNotFound);
  refused(dir.path().string(), "a directory");
}

}  // namespace
}  // namespace mktree
