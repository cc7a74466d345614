// Fault injection into the build's spill files through their FileOps (storage/file_ops.h): the object and
// record spills (IngestOptions::spill_file_ops), the tree build's list spill (BuildTuning::spill_file_ops)
// and the OBJ reader's vertex spill (ObjReadOptions::spill_file_ops). A write or read that fails, at any
// call, fails the build with an IOError naming the spill file, and leaves nothing beside the output: the
// previous store byte for byte, no temporary store, no spill.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <set>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/obj_reader.h"
#include "ingest/ingest_test_util.h"
#include "storage/file_ops.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::FileHash;

// A FileOps that counts the calls of each kind and fails one chosen call with EIO. The spills read on two
// threads at once (the leaf pages' read-ahead, the object table): the counts are atomic. Each kind's calls
// come in one order whatever the threads do: a kind is called from one thread at a time.
class FailingFileOps : public FileOps {
 public:
  enum class Op { kPwrite, kPread, kPreadv };
  static constexpr Op kOps[] = {Op::kPwrite, Op::kPread, Op::kPreadv};

  void FailAt(Op op, uint64_t nth) {
    op_ = op;
    nth_ = nth;
  }
  uint64_t calls(Op op) const { return calls_[static_cast<int>(op)]; }
  bool fired() const { return fired_; }

  ssize_t Pwrite(int fd, const void* buf, size_t n, uint64_t offset) override {
    return Hit(Op::kPwrite) ? Fail() : FileOps::Pwrite(fd, buf, n, offset);
  }
  ssize_t Pread(int fd, void* buf, size_t n, uint64_t offset) override {
    return Hit(Op::kPread) ? Fail() : FileOps::Pread(fd, buf, n, offset);
  }
  ssize_t Preadv(int fd, const iovec* iov, int count, uint64_t offset) override {
    return Hit(Op::kPreadv) ? Fail() : FileOps::Preadv(fd, iov, count, offset);
  }

 private:
  bool Hit(Op op) {
    const uint64_t n = ++calls_[static_cast<int>(op)];
    if (nth_ == 0 || op != op_ || n != nth_) return false;
    fired_ = true;
    return true;
  }
  static ssize_t Fail() {
    errno = EIO;
    return -1;
  }

  std::atomic<uint64_t> calls_[3] = {};
  Op op_ = Op::kPwrite;
  uint64_t nth_ = 0;  // 0: no fault
  std::atomic<bool> fired_{false};
};

const char* Name(FailingFileOps::Op op) {
  switch (op) {
    case FailingFileOps::Op::kPwrite:
      return "pwrite";
    case FailingFileOps::Op::kPread:
      return "pread";
    case FailingFileOps::Op::kPreadv:
      return "preadv";
  }
  return "?";
}

// Which spill a build's FileOps reach.
enum class Spill { kObjects, kLists, kVertices };

class SpillFaultTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    store_ = dir_.file("store.mkt");
    obj_ = dir_.file("scene.obj");
    WriteObj();
    ASSERT_TRUE(Build(Spill::kObjects, nullptr).ok());  // the previous store, which must survive
    old_hash_ = FileHash(store_);
  }

  // An OBJ file whose vertices outgrow the reader's one block in RAM (65536 vertices), and whose faces
  // use vertices of the spilled blocks, so that the vertex spill is written and read.
  void WriteObj() {
    std::ofstream out(obj_);
    constexpr int kVertices = 140000;
    for (int i = 0; i < kVertices; ++i) out << "v " << i % 1000 << ' ' << i / 1000 << ' ' << i % 7 << '\n';
    for (int i = 0; i < 300; ++i) {
      const int v = 1 + (i * 467) % (kVertices - 2);
      out << "o part" << i << "\nf " << v << ' ' << v + 1 << ' ' << v + 2 << '\n';
    }
  }

  // Builds the store from the OBJ file with `ops` (null: none) on the spill `spill`.
  Status Build(Spill spill, FileOps* ops) {
    IngestOptions o;
    o.store.backend = GetParam();
    o.store.params.block_size = 1024;
    o.store.params.blocks_per_page = 2;
    o.threads = 1;
    o.tuning.threads = 1;
    o.tuning.ram_node_objects = 50;  // the tree build's lists go to their spill file
    if (spill == Spill::kObjects) o.spill_file_ops = ops;
    if (spill == Spill::kLists) o.tuning.spill_file_ops = ops;
    ObjReadOptions obj_options;
    obj_options.threads = 0;
    obj_options.vertex_ram_bytes = 1;  // one block
    obj_options.spill_dir = dir_.path().string();
    if (spill == Spill::kVertices) obj_options.spill_file_ops = ops;
    const std::string obj = obj_;
    auto r = BuildStore({[&](ObjectId first) { return OpenObjFile(obj, first, obj_options); }}, store_, o);
    return r.ok() ? Status::Ok() : r.status();
  }

  // The calls of every kind the spill makes in a good build fail in turn: the first three, the last three
  // and about twenty between.
  void FailEveryCall(Spill spill, const std::string& spill_name) {
    FailingFileOps count;
    ASSERT_TRUE(Build(spill, &count).ok());
    ASSERT_TRUE(Build(Spill::kObjects, nullptr).ok());  // the previous store back
    old_hash_ = FileHash(store_);
    uint64_t faults = 0;
    for (FailingFileOps::Op op : FailingFileOps::kOps) {
      const uint64_t calls = count.calls(op);
      for (uint64_t k = 1; k <= calls; k += k < 3 || k + 3 >= calls ? 1 : std::max<uint64_t>(1, calls / 20)) {
        SCOPED_TRACE(std::string(Name(op)) + " call " + std::to_string(k));
        FailingFileOps ops;
        ops.FailAt(op, k);
        const Status st = Build(spill, &ops);
        ASSERT_TRUE(ops.fired());
        ASSERT_FALSE(st.ok());
        EXPECT_EQ(st.code(), Status::Code::kIOError) << st.ToString();
        EXPECT_NE(st.message().find(spill_name), std::string::npos) << st.ToString();
        ExpectNothingLeft();
        if (HasFailure()) return;
        ++faults;
      }
    }
    // At least a write and a read of the spill.
    EXPECT_GT(count.calls(FailingFileOps::Op::kPwrite), 0u);
    EXPECT_GT(count.calls(FailingFileOps::Op::kPread) + count.calls(FailingFileOps::Op::kPreadv), 0u);
    EXPECT_GT(faults, 1u);
  }

  // The folder holds the input and the previous store, unchanged, and nothing else.
  void ExpectNothingLeft() {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.insert(e.path().filename().string());
    EXPECT_EQ(names, (std::set<std::string>{"scene.obj", "store.mkt"}));
    EXPECT_EQ(FileHash(store_), old_hash_);
  }

  testing::TempDir dir_{"mktree_spill_faults"};
  std::string store_, obj_;
  uint64_t old_hash_ = 0;
};

TEST_P(SpillFaultTest, ObjectAndRecordSpillFaultsFailTheBuildCleanly) {
  FailEveryCall(Spill::kObjects, "-spill.");  // .store.mkt.geometry-spill.XXXXXX or .record-spill.
}

TEST_P(SpillFaultTest, ListSpillFaultsFailTheBuildCleanly) {
  FailEveryCall(Spill::kLists, ".mktree-lists-spill");
}

TEST_P(SpillFaultTest, VertexSpillFaultsFailTheBuildCleanly) {
  FailEveryCall(Spill::kVertices, "the vertex spill of " + obj_);
}

INSTANTIATE_TEST_SUITE_P(Backends, SpillFaultTest, ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const auto& info) {
                           return info.param == Backend::kHdf5 ? "Hdf5" : "PagedFile";
                         });

}  // namespace
}  // namespace mktree
