// Stores of format 6 (tests/store_format/data/tanker40_format6.*, written by the mktree of issue 21.3's codec
// dictionary section, empty for these 40 objects, too few to train on, with
//   mktree build tanker:40:1 --block-size 512 --blocks-per-page 2 --backend hdf5|pagefile -q)
// open and answer queries the same with this build, and this build writes the same stores for the same
// input: the paged file byte for byte; the HDF5 file (whose objects carry modification times, so not its
// bytes) with the same datasets (HDF5 types, shapes, creation properties, contents) and attributes (types,
// values). A change of the store formats fails here: make new files then, and say so. The format 3 files
// (tanker40_format3.*, from the start of issue 19), format 4 files (tanker40_format4.*, issue 21/22's
// object record pages) and format 5 files (tanker40_format5.*, issue 21.1's leaf id digests) are refused
// by name and version.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <regex>
#include <string>
#include <vector>

#include "engine/store_format/store_file.h"
#include "store_format/store_test_util.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::RunMktree;
using testing::Slurp;
using testing::TempDir;

const std::string kOldStores = std::string(MKTREE_TESTS_DIR) + "/store_format/data/tanker40_format6";
const std::string kRefusedStores = std::string(MKTREE_TESTS_DIR) + "/store_format/data/tanker40_format";
const char* const kBuild = "build tanker:40:1 --block-size 512 --blocks-per-page 2 -q";

std::string BuildNow(const TempDir& dir, const std::string& backend) {
  const std::string path = dir.file("now." + backend);
  const testing::ToolRun r =
      RunMktree(std::string(kBuild) + " --backend " + backend + " -o " + path, dir.path());
  EXPECT_EQ(r.code, 0) << r.err;
  return path;
}

// `mktree query --cold --exact` of `queries` on `store`, without the timings and the file's name.
std::string Answers(const std::string& store, const std::string& queries, const TempDir& dir) {
  const testing::ToolRun r =
      RunMktree("query " + store + " --queries " + queries + " --cold --exact", dir.path());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"hits\""), std::string::npos) << r.out;
  return std::regex_replace(r.out, std::regex("\"(seconds|micros[a-z_]*)\": [0-9.e+-]*,? ?"), "");
}

// Everything StoreReader reads, and every page.
void ExpectSameStore(const std::string& old_path, const std::string& new_path) {
  auto a = StoreReader::Open(old_path);
  auto b = StoreReader::Open(new_path);
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  const StoreReader &x = **a, &y = **b;
  EXPECT_TRUE(SameTree(x.tree(), y.tree()));
  EXPECT_EQ(x.tree().leaf_filter, y.tree().leaf_filter);
  EXPECT_EQ(x.objects(), y.objects());
  EXPECT_EQ(x.stats_json(), y.stats_json());
  EXPECT_EQ(EncodeParams(x.options().params, x.options().codec),
            EncodeParams(y.options().params, y.options().codec));
  ASSERT_EQ(x.pages().page_count(), y.pages().page_count());
  ASSERT_EQ(x.pages().page_bytes(), y.pages().page_bytes());
  std::vector<uint8_t> p(x.pages().page_bytes()), q(y.pages().page_bytes());
  for (uint64_t i = 0; i < x.pages().page_count(); ++i) {
    ASSERT_TRUE(x.pages().ReadPage(i, p.data()).ok());
    ASSERT_TRUE(y.pages().ReadPage(i, q.data()).ok());
    EXPECT_EQ(p, q) << "page " << i;
  }
}

TEST(OldStoreTest, OldStoresOpenAndAnswerTheSame) {
  TempDir dir;
  for (const std::string backend : {"hdf5", "pagefile"}) {
    SCOPED_TRACE(backend);
    const std::string old_path = kOldStores + (backend == "hdf5" ? ".h5" : ".pf");
    const std::string now = BuildNow(dir, backend);
    ExpectSameStore(old_path, now);
    const std::string queries = dir.file("q.txt");
    ASSERT_EQ(RunMktree("generate queries " + now + " --count 40 --seed 3 -o " + queries, dir.path()).code,
              0);
    EXPECT_EQ(Answers(old_path, queries, dir), Answers(now, queries, dir));
  }
}

TEST(OldStoreTest, Format3To5StoresAreRefusedByVersion) {
  TempDir dir;
  for (const std::string version : {"3", "4", "5"}) {
    const std::string why = "format version " + version + " (this build reads version 6)";
    for (const std::string ext : {".h5", ".pf"}) {
      const std::string path = kRefusedStores + version + ext;
      auto r = StoreReader::Open(path);
      ASSERT_FALSE(r.ok()) << path;
      EXPECT_EQ(r.status().code(), Status::Code::kUnsupported) << r.status().ToString();
      EXPECT_EQ(r.status().message().rfind(path + ": ", 0), 0u) << r.status().message();
      EXPECT_NE(r.status().message().find(why), std::string::npos) << r.status().message();
    }
    const testing::ToolRun r = RunMktree("info " + kRefusedStores + version + ".pf", dir.path());
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.err.find(why), std::string::npos) << r.err;
  }
}

TEST(OldStoreTest, PagedFileIsWrittenByteForByte) {
  TempDir dir;
  EXPECT_EQ(Slurp(kOldStores + ".pf"), Slurp(BuildNow(dir, "pagefile")));
}

// An HDF5 object's creation properties, type and raw contents (or an attribute's), compared pairwise.
class Hdf5Compare {
 public:
  Hdf5Compare(const std::string& a, const std::string& b)
      : a_(H5Fopen(a.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT)),
        b_(H5Fopen(b.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT)) {}
  ~Hdf5Compare() {
    H5Fclose(a_);
    H5Fclose(b_);
  }
  bool ok() const { return a_ >= 0 && b_ >= 0; }

  hid_t old_file() const { return a_; }

  // Every link under / ("tree", "tree/nodes", ...), sorted by name.
  static std::vector<std::string> Objects(hid_t f) {
    std::vector<std::string> out;
    H5Lvisit(
        f, H5_INDEX_NAME, H5_ITER_INC,
        [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
          static_cast<std::vector<std::string>*>(data)->push_back(name);
          return 0;
        },
        &out);
    return out;
  }
  static std::vector<std::string> AttributeNames(hid_t o) {
    std::vector<std::string> out;
    H5Aiterate2(
        o, H5_INDEX_NAME, H5_ITER_INC, nullptr,
        [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
          static_cast<std::vector<std::string>*>(data)->push_back(name);
          return 0;
        },
        &out);
    return out;
  }

  void ExpectSame() {
    const std::vector<std::string> objects = Objects(a_);
    ASSERT_EQ(objects, Objects(b_));
    for (const std::string& name : objects) {
      SCOPED_TRACE(name);
      const hid_t x = H5Oopen(a_, name.c_str(), H5P_DEFAULT), y = H5Oopen(b_, name.c_str(), H5P_DEFAULT);
      ASSERT_GE(x, 0);
      ASSERT_GE(y, 0);
      EXPECT_EQ(H5Iget_type(x), H5Iget_type(y));
      ExpectSameAttributes(x, y);
      if (H5Iget_type(x) == H5I_DATASET) ExpectSameDataset(x, y);
      H5Oclose(x);
      H5Oclose(y);
    }
    SCOPED_TRACE("/");
    ExpectSameAttributes(a_, b_);
  }

 private:
  void ExpectSameAttributes(hid_t x, hid_t y) {
    const std::vector<std::string> names = AttributeNames(x);
    ASSERT_EQ(names, AttributeNames(y));
    for (const std::string& n : names) {
      SCOPED_TRACE("attribute " + n);
      const hid_t a = H5Aopen(x, n.c_str(), H5P_DEFAULT), b = H5Aopen(y, n.c_str(), H5P_DEFAULT);
      const hid_t ta = H5Aget_type(a), tb = H5Aget_type(b);
      EXPECT_GT(H5Tequal(ta, tb), 0);
      const hsize_t bytes = H5Aget_storage_size(a);
      ASSERT_EQ(bytes, H5Aget_storage_size(b));
      std::vector<uint8_t> va(bytes), vb(bytes);
      ASSERT_GE(H5Aread(a, ta, va.data()), 0);
      ASSERT_GE(H5Aread(b, tb, vb.data()), 0);
      EXPECT_EQ(va, vb);
      H5Tclose(ta);
      H5Tclose(tb);
      H5Aclose(a);
      H5Aclose(b);
    }
  }
  void ExpectSameDataset(hid_t x, hid_t y) {
    const hid_t tx = H5Dget_type(x), ty = H5Dget_type(y);
    EXPECT_GT(H5Tequal(tx, ty), 0);
    const hid_t px = H5Dget_create_plist(x), py = H5Dget_create_plist(y);
    EXPECT_GT(H5Pequal(px, py), 0);
    const hid_t sx = H5Dget_space(x), sy = H5Dget_space(y);
    EXPECT_GT(H5Sextent_equal(sx, sy), 0);
    const size_t bytes = H5Sget_simple_extent_npoints(sx) * H5Tget_size(tx);
    std::vector<uint8_t> vx(bytes), vy(bytes);
    if (bytes > 0) {
      EXPECT_GE(H5Dread(x, tx, H5S_ALL, H5S_ALL, H5P_DEFAULT, vx.data()), 0);
      EXPECT_GE(H5Dread(y, ty, H5S_ALL, H5S_ALL, H5P_DEFAULT, vy.data()), 0);
    }
    EXPECT_EQ(vx, vy);
    for (hid_t h : {sx, sy}) H5Sclose(h);
    for (hid_t h : {px, py}) H5Pclose(h);
    for (hid_t h : {tx, ty}) H5Tclose(h);
  }

  hid_t a_, b_;
};

TEST(OldStoreTest, Hdf5StoreIsWrittenWithTheSameObjectsTypesAndValues) {
  TempDir dir;
  Hdf5Compare files(kOldStores + ".h5", BuildNow(dir, "hdf5"));
  ASSERT_TRUE(files.ok());
  const std::vector<std::string> want = {
      "codec_dictionary", "objects",     "objects/leaf_digest", "objects/record_directory",
      "objects/sources",  "pages",       "stats_json",          "tree",
      "tree/leaf_filter", "tree/leaves", "tree/nodes",          "tree/split_nodes"};
  EXPECT_EQ(Hdf5Compare::Objects(files.old_file()), want);
  EXPECT_EQ(Hdf5Compare::AttributeNames(files.old_file()).size(), 20u);
  files.ExpectSame();
}

}  // namespace
}  // namespace mktree
