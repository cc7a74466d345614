// The store's zstd dictionary (store format 6): training on the first objects, entries compressed with it,
// the fallback to no dictionary for scenes too small to train on, and a damaged dictionary section refused
// at open in both backends.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstring>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/store_format/object_codec.h"
#include "engine/store_format/store_file.h"
#include "storage/byte_io.h"
#include "store_format/store_test_util.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::RunMktree;
using testing::SameMesh;
using testing::TempDir;

std::vector<SceneObject> Tanker(uint64_t n) {
  std::vector<SceneObject> out;
  auto src = MakeTankerSource(n, 1, 0);
  SceneObject o;
  for (;;) {
    auto more = src->Next(&o);
    EXPECT_TRUE(more.ok());
    if (!more.ok() || !*more) break;
    out.push_back(o);
  }
  return out;
}

// The first objects' packed geometry, whole objects up to kDictionarySampleBytes, as ingest samples it.
std::vector<uint8_t> Sample(const std::vector<SceneObject>& objects, std::vector<size_t>* sizes) {
  std::vector<uint8_t> sample;
  for (const SceneObject& o : objects) {
    const size_t before = sample.size();
    EXPECT_TRUE(PackObjectGeometry(o, Vec3d{}, true, &sample).ok());
    if (sample.size() > kDictionarySampleBytes) {
      sample.resize(before);
      break;
    }
    sizes->push_back(sample.size() - before);
  }
  return sample;
}

TEST(CodecDictionaryTest, TrainingIsDeterministicAndEntriesRoundTrip) {
  const std::vector<SceneObject> objects = Tanker(3000);
  std::vector<size_t> sizes;
  const std::vector<uint8_t> sample = Sample(objects, &sizes);
  const std::vector<uint8_t> dict = TrainDictionary(sample, sizes, 3);
  ASSERT_FALSE(dict.empty());
  EXPECT_LE(dict.size(), size_t{64} << 10);
  EXPECT_EQ(dict, TrainDictionary(sample, sizes, 3));

  auto loaded = CodecDictionary::Load(dict, 3);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  CodecOptions with;
  with.dictionary = *loaded;
  const CodecOptions without;
  uint64_t bytes_with = 0, bytes_without = 0, dict_entries = 0;
  for (const SceneObject& o : objects) {
    std::vector<uint8_t> a, b;
    auto n = EncodeObjectEntry(o, Vec3d{}, with, &a);
    ASSERT_TRUE(n.ok());
    ASSERT_TRUE(EncodeObjectEntry(o, Vec3d{}, without, &b).ok());
    bytes_with += a.size();
    bytes_without += b.size();
    auto e = ParseObjectEntry(a.data(), a.size());
    ASSERT_TRUE(e.ok()) << e.status().ToString();
    ASSERT_NE(e->codec, Codec::kZstd);  // a dictionary's store has no dictionary-less frame
    Mesh m;
    ASSERT_TRUE(DecodeObjectMesh(*e, &m, loaded->get()).ok());
    EXPECT_TRUE(SameMesh(m, o.mesh)) << "object " << o.id;
    if (e->codec == Codec::kZstdDict) {
      ++dict_entries;
      Status st = DecodeObjectMesh(*e, &m);  // the store's dictionary not given
      EXPECT_EQ(st.code(), Status::Code::kCorruption);
      EXPECT_NE(st.message().find("dictionary"), std::string::npos) << st.message();
    }
  }
  EXPECT_EQ(dict_entries, objects.size());
  EXPECT_LT(bytes_with + dict.size(), bytes_without);
}

TEST(CodecDictionaryTest, TooFewObjectsGiveNoDictionary) {
  const std::vector<SceneObject> objects = Tanker(10);
  for (size_t n : {1, 2, 10}) {
    SCOPED_TRACE(n);
    std::vector<size_t> sizes;
    const std::vector<uint8_t> sample =
        Sample(std::vector<SceneObject>(objects.begin(), objects.begin() + n), &sizes);
    EXPECT_TRUE(TrainDictionary(sample, sizes, 3).empty());
  }
  EXPECT_TRUE(TrainDictionary({}, {}, 3).empty());
}

TEST(CodecDictionaryTest, BytesThatAreNoDictionaryAreRefused) {
  const std::vector<SceneObject> objects = Tanker(3000);
  std::vector<size_t> sizes;
  const std::vector<uint8_t> sample = Sample(objects, &sizes);
  const std::vector<uint8_t> dict = TrainDictionary(sample, sizes, 3);
  ASSERT_FALSE(dict.empty());
  std::vector<uint8_t> no_magic = dict;
  std::memset(no_magic.data(), 0, 4);
  std::vector<uint8_t> cut(dict.begin(), dict.begin() + 12);
  for (const std::vector<uint8_t>& bad : {no_magic, cut, std::vector<uint8_t>{1, 2, 3}}) {
    auto d = CodecDictionary::Load(bad, std::nullopt);
    ASSERT_FALSE(d.ok());
    EXPECT_EQ(d.status().code(), Status::Code::kCorruption) << d.status().ToString();
  }
}

// `mktree build` of a tanker of n objects into dir (GCC 12 warns, wrongly, of operator+ chains here).
std::string BuildTanker(const TempDir& dir, uint64_t n, const std::string& backend) {
  const std::string count = std::to_string(n);
  const std::string path = dir.file(backend + "_" + count + ".mkt");
  const testing::ToolRun r = RunMktree(std::string("build tanker:")
                                           .append(count)
                                           .append(":1 -q --backend ")
                                           .append(backend)
                                           .append(" -o ")
                                           .append(path),
                                       dir.path());
  EXPECT_EQ(r.code, 0) << r.err;
  return path;
}

TEST(CodecDictionaryTest, SmallScenesAreStoredWithoutADictionary) {
  TempDir dir;
  for (const std::string backend : {"pagefile", "hdf5"}) {
    for (uint64_t n : {1, 2, 10, 3000}) {
      SCOPED_TRACE(backend + " " + std::to_string(n));
      const std::string path = BuildTanker(dir, n, backend);
      auto r = StoreReader::Open(path);
      ASSERT_TRUE(r.ok()) << r.status().ToString();
      EXPECT_EQ((*r)->options().codec.dictionary != nullptr, n == 3000);
      // Exact answers need every entry decoded: a box around the whole hull.
      const testing::ToolRun q =
          RunMktree("query " + path + " --exact --count --box -1,-30,-1,301,30,31", dir.path());
      EXPECT_EQ(q.code, 0) << q.err;
      EXPECT_NE(q.out.find("\"hit_count\": " + std::to_string(n)), std::string::npos) << q.out;
    }
  }
}

// The paged file's section table: offset, bytes, checksum of section i (docs/store_format.md).
constexpr uint64_t kDictionarySection = 8;

TEST(CodecDictionaryTest, DamagedDictionaryIsCorruptionNamingTheStore) {
  TempDir dir;
  {
    const std::string path = BuildTanker(dir, 3000, "pagefile");
    std::string bytes = testing::Slurp(path);
    uint64_t off, n;
    std::memcpy(&off, bytes.data() + 80 + 24 * kDictionarySection, 8);
    std::memcpy(&n, bytes.data() + 88 + 24 * kDictionarySection, 8);
    ASSERT_GT(n, 16u);
    ASSERT_EQ(off + n, bytes.size());  // the last section
    bytes[off + n / 2] ^= 0x20;
    FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    ASSERT_EQ(std::fwrite(bytes.data(), 1, bytes.size(), f), bytes.size());
    std::fclose(f);
    auto r = StoreReader::Open(path);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), Status::Code::kCorruption);
    EXPECT_EQ(r.status().message().rfind(path + ": ", 0), 0u) << r.status().message();
    EXPECT_NE(r.status().message().find("codec dictionary"), std::string::npos) << r.status().message();
  }
  {
    const std::string path = BuildTanker(dir, 3000, "hdf5");
    const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    const hid_t d = H5Dopen2(f, "codec_dictionary", H5P_DEFAULT);
    ASSERT_GE(d, 0);
    const hid_t space = H5Dget_space(d);
    std::vector<uint8_t> dict(static_cast<size_t>(H5Sget_simple_extent_npoints(space)));
    ASSERT_GT(dict.size(), 16u);
    ASSERT_GE(H5Dread(d, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, dict.data()), 0);
    dict[dict.size() / 2] ^= 0x20;
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, dict.data()), 0);
    H5Sclose(space);
    H5Dclose(d);
    H5Fclose(f);
    auto r = StoreReader::Open(path);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), Status::Code::kCorruption);
    EXPECT_EQ(r.status().message().rfind(path + ": ", 0), 0u) << r.status().message();
    EXPECT_NE(r.status().message().find("codec_dictionary"), std::string::npos) << r.status().message();
  }
}

}  // namespace
}  // namespace mktree
