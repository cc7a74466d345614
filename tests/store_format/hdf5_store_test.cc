// The HDF5 backend's own failure modes: HDF5 errors reach the user as one line and HDF5 prints nothing
// itself, from any thread; the object table is stored as its canonical encoding; and sizes read from a
// crafted file (dataset lengths, string and attribute sizes, counts) are checked before anything is
// allocated for them.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "engine/store_format/store_file.h"
#include "storage/byte_io.h"
#include "store_format/store_test_util.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::BuiltStore;
using testing::TempDir;

Status WriteHdf5(const std::string& path, const std::vector<SceneObject>& objects) {
  StoreOptions o;
  o.backend = Backend::kHdf5;
  auto w = StoreWriter::Create(path, o);
  if (!w.ok()) return w.status();
  BuiltStore built;
  MKTREE_RETURN_IF_ERROR(testing::BuildTestStore(objects, o.codec, o.params, &(*w)->pages(), &built));
  for (const SceneObject& o2 : objects)
    MKTREE_RETURN_IF_ERROR((*w)->AppendObject(o2.id, built.object_leaf[o2.id], o2.name));
  return (*w)->Commit(built.tree, "");
}

// Redirects this process's stderr (fd 2) to a file while in scope; text() is what was written.
class CaptureStderr {
 public:
  explicit CaptureStderr(std::string path) : path_(std::move(path)) {
    std::fflush(stderr);
    saved_ = ::dup(2);
    const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 2);
    ::close(fd);
  }
  ~CaptureStderr() { Restore(); }
  std::string text() {
    Restore();
    return testing::Slurp(path_);
  }

 private:
  void Restore() {
    if (saved_ < 0) return;
    std::fflush(stderr);
    ::dup2(saved_, 2);
    ::close(saved_);
    saved_ = -1;
  }
  std::string path_;
  int saved_ = -1;
};

// The descriptor this process holds on `path` (HDF5's), or -1.
int DescriptorOf(const std::string& path) {
  const auto want = std::filesystem::canonical(path);
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) {
    std::error_code ec;
    const auto target = std::filesystem::read_symlink(e.path(), ec);
    if (!ec && target == want) return std::stoi(e.path().filename().string());
  }
  return -1;
}

// A page read that fails in HDF5's own file driver (its descriptor replaced by a write-only one, so pread
// fails with EBADF), in a thread that never opened anything: one line naming the file and the page, and
// HDF5 prints nothing. (HDF5 1.10's message for this holds a ctime() string, newline included; and
// Debian's HDF5 is built thread-safe, so its error printing is per thread.)
TEST(Hdf5StoreTest, ReadErrorsInAnyThreadAreOneLineAndHdf5PrintsNothing) {
  TempDir dir;
  const std::string path = dir.file("s.mkt");
  ASSERT_TRUE(WriteHdf5(path, testing::MakeObjects(200, 31)).ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const int fd = DescriptorOf(path);
  ASSERT_GE(fd, 0);
  const int wronly = ::open(dir.file("junk").c_str(), O_WRONLY | O_CREAT, 0644);
  ASSERT_EQ(::dup2(wronly, fd), fd);
  ::close(wronly);
  Status st;
  H5E_auto2_t printer = nullptr;
  {
    CaptureStderr capture(dir.file("stderr.txt"));
    std::thread reader([&] {
      std::vector<uint8_t> page((*r)->pages().page_bytes());
      st = (*r)->pages().ReadPage(3, page.data());
      void* data = nullptr;
      H5Eget_auto2(H5E_DEFAULT, &printer, &data);
    });
    reader.join();
    EXPECT_EQ(capture.text(), "");
  }
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
  EXPECT_EQ(st.message().rfind(path + ": page 3: ", 0), 0u) << st.message();
  EXPECT_NE(st.message().find(std::strerror(EBADF)), std::string::npos) << st.message();
  EXPECT_EQ(printer, nullptr) << "HDF5's automatic error printing is on in a reading thread";
}

// /objects holds the canonical encoding (tree_codec.h), readable as plain arrays by h5dump or h5py.
TEST(Hdf5StoreTest, ObjectTableIsItsCanonicalEncoding) {
  TempDir dir;
  const std::string path = dir.file("s.mkt");
  std::vector<SceneObject> objects = testing::MakeObjects(50, 32);
  objects[7].name = std::string("a\0b", 3);
  ASSERT_TRUE(WriteHdf5(path, objects).ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const ObjectTable& t = (*r)->objects();
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  auto read = [&](const char* name, hid_t type, void* out, hsize_t want) {
    hid_t d = H5Dopen2(f, name, H5P_DEFAULT);
    ASSERT_GE(d, 0) << name;
    hid_t space = H5Dget_space(d);
    EXPECT_EQ(H5Sget_simple_extent_npoints(space), static_cast<hssize_t>(want)) << name;
    EXPECT_GE(H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out), 0) << name;
    H5Sclose(space);
    H5Dclose(d);
  };
  std::vector<uint64_t> digest(t.leaf_digest.size());
  std::vector<uint32_t> directory(t.record_directory.size());
  const std::vector<uint8_t> sources_bytes = EncodeSources(t.sources);
  std::vector<uint8_t> sources(sources_bytes.size());
  read("/objects/leaf_digest", H5T_NATIVE_UINT64, digest.data(), digest.size());
  read("/objects/record_directory", H5T_NATIVE_UINT32, directory.data(), directory.size());
  read("/objects/sources", H5T_NATIVE_UINT8, sources.data(), sources.size());
  H5Fclose(f);
  EXPECT_EQ(digest, t.leaf_digest);
  EXPECT_EQ(directory, t.record_directory);
  EXPECT_EQ(sources, sources_bytes);
  EXPECT_EQ(*(*r)->ObjectName(7), std::string("a\0b", 3));
}

// Open HDF5 identifiers of every kind the store code creates.
std::vector<int64_t> Hdf5Ids() {
  std::vector<int64_t> n;
  for (H5I_type_t t :
       {H5I_FILE, H5I_GROUP, H5I_DATATYPE, H5I_DATASPACE, H5I_DATASET, H5I_ATTR, H5I_GENPROP_LST}) {
    hsize_t c = 0;
    H5Inmembers(t, &c);
    n.push_back(static_cast<int64_t>(c));
  }
  return n;
}

// I/O errors other than a full disk, in the writer: its descriptor replaced by a read-only one (writes
// fail) while writing pages, or by a write-only one (HDF5's reads fail: it reads back while writing the
// tables) before Commit. Each ends in one line naming the temporary file, with every HDF5 identifier
// released and nothing left behind; the process then builds the store.
TEST(Hdf5StoreTest, WriterIoErrorsFailCleanly) {
  TempDir dir;
  const std::string path = dir.file("w.mkt");
  const std::vector<SceneObject> objects = testing::MakeObjects(3000, 34);
  ASSERT_TRUE(WriteHdf5(dir.file("warm.mkt"), objects).ok());
  std::filesystem::remove(dir.file("warm.mkt"));
  const std::vector<int64_t> ids = Hdf5Ids();
  StoreOptions o;
  for (const int mode : {O_RDONLY, O_WRONLY}) {
    SCOPED_TRACE(mode == O_RDONLY ? "writes fail" : "reads fail");
    Status st;
    {
      auto w = StoreWriter::Create(path, o);
      ASSERT_TRUE(w.ok());
      const int fd = DescriptorOf((*w)->temp_path());
      ASSERT_GE(fd, 0);
      auto swap = [&] {
        const int other = ::open((*w)->temp_path().c_str(), mode);
        ASSERT_EQ(::dup2(other, fd), fd);
        ::close(other);
      };
      if (mode == O_RDONLY) swap();
      BuiltStore built;
      st = testing::BuildTestStore(objects, o.codec, o.params, &(*w)->pages(), &built);
      // Pages reach the file on the writer's own thread: a failed page write may be returned by a
      // later call, the first AppendObject at the latest.
      for (size_t i = 0; st.ok() && i < objects.size(); ++i)
        st = (*w)->AppendObject(objects[i].id, built.object_leaf[objects[i].id], objects[i].name);
      if (mode == O_RDONLY) {
        EXPECT_FALSE(st.ok()) << "every page write failed";
      }
      if (st.ok()) {
        if (mode == O_WRONLY) swap();
        st = (*w)->Commit(built.tree, "{}");
      }
    }
    ASSERT_FALSE(st.ok());
    EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
    EXPECT_EQ(st.message().rfind(path + ".tmp.", 0), 0u) << st.message();
    EXPECT_NE(st.message().find(std::strerror(EBADF)), std::string::npos) << st.message();
    EXPECT_EQ(Hdf5Ids(), ids);
    EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
  }
  ASSERT_TRUE(WriteHdf5(path, objects).ok());
  EXPECT_TRUE(StoreReader::Open(path).ok());
}

// ---- Crafted stores: sizes read from the file are bounded before anything is allocated ----

class CraftedHdf5Test : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(WriteHdf5(good_, testing::MakeObjects(120, 33)).ok());
    auto r = StoreReader::Open(good_);
    ASSERT_TRUE(r.ok());
    params_ = (*r)->options().params;
    codec_ = (*r)->options().codec;
    pages_ = (*r)->pages().page_count();
    objects_ = (*r)->object_count();
  }
  // A copy of the good store changed by `edit` (given the open file); returns Open's status.
  template <typename Edit>
  Status OpenEdited(Edit edit) {
    std::filesystem::copy_file(good_, path_, std::filesystem::copy_options::overwrite_existing);
    hid_t f = H5Fopen(path_.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    EXPECT_GE(f, 0);
    edit(f);
    EXPECT_GE(H5Fclose(f), 0);
    auto r = StoreReader::Open(path_);
    return r.ok() ? Status::Ok() : r.status();
  }
  void ExpectCorruption(const Status& st, const std::string& words) {
    EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
    EXPECT_EQ(st.message().rfind(path_ + ": ", 0), 0u) << st.message();
    EXPECT_NE(st.message().find(words), std::string::npos) << st.message();
    EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
  }
  // Replaces dataset `name` with a chunked one of `n` elements of `type` whose chunks were never written
  // (HDF5 would read them as fill values, allocating the lot).
  static void ReplaceWithHugeDataset(hid_t f, const char* name, hid_t type, hsize_t n) {
    ASSERT_GE(H5Ldelete(f, name, H5P_DEFAULT), 0) << name;
    hsize_t dims[1] = {n}, chunk[1] = {1024};
    hid_t space = H5Screate_simple(1, dims, nullptr);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 1, chunk);
    hid_t d = H5Dcreate2(f, name, type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(d, 0) << name;
    H5Dclose(d);
    H5Pclose(dcpl);
    H5Sclose(space);
  }
  static void SetU64Attr(hid_t f, const char* name, uint64_t v) {
    hid_t a = H5Aopen(f, name, H5P_DEFAULT);
    ASSERT_GE(a, 0) << name;
    ASSERT_GE(H5Awrite(a, H5T_NATIVE_UINT64, &v), 0);
    H5Aclose(a);
  }
  // The header checksum a crafted store would carry for these counts (a checksum is not a MAC).
  uint64_t HeaderSum(uint64_t pages, uint64_t objects) const {
    std::vector<uint8_t> b = EncodeParams(params_, codec_);
    storage_internal::ByteWriter w(&b);
    w.Put<uint64_t>(pages);
    w.Put<uint64_t>(objects);
    w.Put<uint32_t>(6);                              // the HDF5 format version
    for (int i = 0; i < 3; ++i) w.Put<double>(0.0);  // the store frame's origin: these scenes lie near 0
    return Checksum(b);
  }

  TempDir dir_;
  std::string good_ = dir_.file("good.mkt"), path_ = dir_.file("crafted.mkt");
  BuildParams params_;
  CodecOptions codec_;
  uint64_t pages_ = 0, objects_ = 0;
};

TEST_F(CraftedHdf5Test, TheGoodStoreOpensAndTheHeaderSumIsReproduced) {
  EXPECT_TRUE(OpenEdited([](hid_t) {}).ok());
  hid_t f = H5Fopen(good_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  hid_t a = H5Aopen(f, "checksum_header", H5P_DEFAULT);
  uint64_t sum = 0;
  H5Aread(a, H5T_NATIVE_UINT64, &sum);
  H5Aclose(a);
  H5Fclose(f);
  EXPECT_EQ(sum, HeaderSum(pages_, objects_));
}

TEST_F(CraftedHdf5Test, HugeTreeDatasetIsRefused) {
  const Status st = OpenEdited([](hid_t f) {
    hid_t t = H5Tcopy(H5T_STD_U8LE);
    ReplaceWithHugeDataset(f, "tree/leaf_filter", t, hsize_t{1} << 40);
    H5Tclose(t);
  });
  ExpectCorruption(st, "more than the file's");
}

TEST_F(CraftedHdf5Test, HugeObjectCountWithAValidHeaderSumIsRefused) {
  const uint64_t huge = uint64_t{1} << 36;
  const Status st = OpenEdited([&](hid_t f) {
    SetU64Attr(f, "object_count", huge);
    SetU64Attr(f, "checksum_header", HeaderSum(pages_, huge));
    ReplaceWithHugeDataset(f, "objects/leaf_digest", H5T_STD_U64LE, huge);
    ReplaceWithHugeDataset(f, "objects/record_directory", H5T_STD_U32LE, huge);
  });
  ExpectCorruption(st, "objects do not fit");
}

TEST_F(CraftedHdf5Test, HugePageCountWithAValidHeaderSumIsRefused) {
  const uint64_t huge = uint64_t{1} << 36;
  const Status st = OpenEdited([&](hid_t f) {
    SetU64Attr(f, "page_count", huge);
    SetU64Attr(f, "checksum_header", HeaderSum(huge, objects_));
  });
  ExpectCorruption(st, "pages of");
}

TEST_F(CraftedHdf5Test, HugeRecordDirectoryIsRefused) {
  const Status st = OpenEdited([](hid_t f) {
    ReplaceWithHugeDataset(f, "objects/record_directory", H5T_STD_U32LE, hsize_t{1} << 36);
  });
  ExpectCorruption(st, "objects/record_directory has 68719476736 elements for");
}

TEST_F(CraftedHdf5Test, HugeSourcesDatasetIsRefused) {
  Status st = OpenEdited(
      [](hid_t f) { ReplaceWithHugeDataset(f, "objects/sources", H5T_STD_U8LE, hsize_t{1} << 40); });
  ExpectCorruption(st, "objects/sources");
  // Compressed: one chunk of zeros stored, the rest "fill value"; the length is still bounded by the file.
  st = OpenEdited([](hid_t f) {
    ASSERT_GE(H5Ldelete(f, "objects/sources", H5P_DEFAULT), 0);
    hsize_t dims[1] = {hsize_t{1} << 36}, chunk[1] = {1 << 16}, one[1] = {1 << 16}, start[1] = {0};
    hid_t space = H5Screate_simple(1, dims, nullptr);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 1, chunk);
    H5Pset_deflate(dcpl, 9);
    hid_t d = H5Dcreate2(f, "objects/sources", H5T_STD_U8LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(d, 0);
    std::vector<uint8_t> zeros(one[0], 0);
    hid_t mem = H5Screate_simple(1, one, nullptr);
    H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, one, nullptr);
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_UINT8, mem, space, H5P_DEFAULT, zeros.data()), 0);
    H5Sclose(mem);
    H5Dclose(d);
    H5Pclose(dcpl);
    H5Sclose(space);
  });
  ExpectCorruption(st, "dataset objects/sources claims 68719476736 elements");
}

TEST_F(CraftedHdf5Test, HugeStatsStringIsRefused) {
  const Status st = OpenEdited([](hid_t f) {
    ASSERT_GE(H5Ldelete(f, "stats_json", H5P_DEFAULT), 0);
    hid_t t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, size_t{1} << 31);
    hid_t space = H5Screate(H5S_SCALAR);
    hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_alloc_time(dcpl, H5D_ALLOC_TIME_LATE);
    hid_t d = H5Dcreate2(f, "stats_json", t, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(d, 0);
    H5Dclose(d);
    H5Pclose(dcpl);
    H5Sclose(space);
    H5Tclose(t);
  });
  ExpectCorruption(st, "stats_json claims");
}

TEST_F(CraftedHdf5Test, OversizedStringAttributeIsRefused) {
  const Status st = OpenEdited([](hid_t f) {
    ASSERT_GE(H5Adelete(f, "codec"), 0);
    hid_t t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, 1 << 20);
    hid_t space = H5Screate(H5S_SCALAR);
    hid_t a = H5Acreate2(f, "codec", t, space, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(a, 0);
    std::string v(1 << 20, 'z');
    H5Awrite(a, t, v.data());
    H5Aclose(a);
    H5Sclose(space);
    H5Tclose(t);
  });
  ExpectCorruption(st, "attribute codec is 1048576 bytes long");
}

// An attribute of many values would have H5Aread write past the one value it is read into.
TEST_F(CraftedHdf5Test, AttributeOfManyValuesIsRefused) {
  const Status st = OpenEdited([](hid_t f) {
    ASSERT_GE(H5Adelete(f, "page_count"), 0);
    hsize_t dims[1] = {4096};
    hid_t space = H5Screate_simple(1, dims, nullptr);
    hid_t a = H5Acreate2(f, "page_count", H5T_STD_U64LE, space, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(a, 0);
    std::vector<uint64_t> v(4096, 7);
    H5Awrite(a, H5T_NATIVE_UINT64, v.data());
    H5Aclose(a);
    H5Sclose(space);
  });
  ExpectCorruption(st, "attribute page_count is not a single value");
}

// ---- The command line on damaged stores ----

// Truncated, zeroed and bit-flipped copies of a store, through `info` and `query`: an answer (exit 0,
// nothing on stderr) or one `error:` line naming the file (exit 1); never a crash or HDF5's own output.
TEST(Hdf5CliTest, DamagedStoresGiveOneErrorLine) {
  TempDir dir;
  auto run = [&](const std::string& args) { return mktree::testing::RunMktree(args, dir.path()); };
  const std::string good = dir.file("good.mkt"), bad = dir.file("bad.mkt");
  ASSERT_EQ(run("build tanker:1500:4 -q -o " + good).code, 0);
  std::ifstream in(good, std::ios::binary);
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  const size_t n = bytes.size();
  std::mt19937 g(5);
  int errors = 0, answers = 0;
  for (int i = 0; i < 60; ++i) {
    std::vector<uint8_t> b = bytes;
    // Half of the damage near the start and the end, where HDF5 keeps its superblock and our metadata.
    const size_t off = i % 2 ? g() % n : (i % 4 ? g() % 8192 : n - 1 - g() % std::min<size_t>(n, 40000));
    if (i % 3 == 0) {
      b.resize(off);
    } else if (i % 3 == 1) {
      std::fill(b.begin() + off, b.begin() + std::min(n, off + 512), 0);
    } else {
      b[off] ^= static_cast<uint8_t>(1u << (g() % 8));
    }
    std::ofstream(bad, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(b.data()), b.size());
    for (const std::string& args : {"info " + bad, "query " + bad + " --box 0,-30,0,300,30,40"}) {
      SCOPED_TRACE(args + " (damage " + std::to_string(i) + " at " + std::to_string(off) + ")");
      const auto r = run(args);
      ASSERT_TRUE(r.code == 0 || r.code == 1) << "exit " << r.code << "\n" << r.err;
      if (r.code == 0) {
        EXPECT_EQ(r.err, "");
        ++answers;
      } else {
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
        EXPECT_NE(r.err.find("bad.mkt"), std::string::npos) << r.err;
        ++errors;
      }
    }
  }
  std::printf("[damaged stores] %d errors, %d answers\n", errors, answers);
  EXPECT_GT(errors, 40);
}

}  // namespace
}  // namespace mktree
