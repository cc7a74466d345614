// The parallel ingest paths give the single-threaded result: encoding objects on workers (object_encoder.h)
// keeps id order, and the windowed spill reads (SpillFile::ReadMany) return exactly what was written.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <new>
#include <random>
#include <stdexcept>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/object_encoder.h"
#include "engine/ingest/spill_file.h"
#include "engine/ingest/store_builder.h"
#include "engine/store_format/store_file.h"
#include "engine/store_format/tree_codec.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::TempPath;

// Two inputs continuing one numbering, so that the reader also crosses from one source to the next.
std::vector<SceneOpener> TwoTankers(uint64_t first, uint64_t second) {
  return {
      [first](ObjectId id) -> Result<std::unique_ptr<SceneSource>> { return MakeTankerSource(first, 7, id); },
      [second](ObjectId id) -> Result<std::unique_ptr<SceneSource>> {
        return MakeTankerSource(second, 8, id);
      }};
}

struct Built {
  IngestReport report;
  std::unique_ptr<StoreReader> store;
};

Built BuildWith(uint32_t threads, Backend backend, const std::string& path) {
  IngestOptions opts;
  opts.store.backend = backend;
  opts.threads = threads;
  auto report = BuildStore(TwoTankers(1900, 2300), path, opts);  // several encoder batches of 512
  EXPECT_TRUE(report.ok()) << report.status().ToString();
  auto store = StoreReader::Open(path);
  EXPECT_TRUE(store.ok()) << store.status().ToString();
  if (!report.ok() || !store.ok()) return {};
  return {*report, std::move(store).value()};
}

class ParallelIngestTest : public ::testing::TestWithParam<Backend> {};

TEST_P(ParallelIngestTest, ThreadCountDoesNotChangeTheStore) {
  const std::string one_path = TempPath("one.mkt"), three_path = TempPath("three.mkt");
  Built one = BuildWith(1, GetParam(), one_path);
  Built three = BuildWith(3, GetParam(), three_path);
  ASSERT_TRUE(one.store && three.store);
  EXPECT_EQ(one.report.objects, 4200u);
  EXPECT_EQ(one.report.objects, three.report.objects);
  EXPECT_EQ(one.report.encoded_bytes, three.report.encoded_bytes);
  EXPECT_EQ(one.report.raw_geometry_bytes, three.report.raw_geometry_bytes);
  EXPECT_TRUE(SameTree(one.store->tree(), three.store->tree()));
  EXPECT_TRUE(one.store->objects() == three.store->objects());
  EXPECT_EQ(*one.store->ObjectName(4199), *three.store->ObjectName(4199));
  // Entries are encoded alone, so the pages are byte for byte the same.
  const PageStore& a = one.store->pages();
  const PageStore& b = three.store->pages();
  ASSERT_EQ(a.page_count(), b.page_count());
  std::vector<uint8_t> pa(a.page_bytes()), pb(b.page_bytes());
  for (uint64_t p = 0; p < a.page_count(); ++p) {
    ASSERT_TRUE(a.ReadPage(p, pa.data()).ok());
    ASSERT_TRUE(b.ReadPage(p, pb.data()).ok());
    ASSERT_EQ(pa, pb) << "page " << p;
  }
  one.store.reset();
  three.store.reset();
  fs::remove(one_path);
  fs::remove(three_path);
}

INSTANTIATE_TEST_SUITE_P(Backends, ParallelIngestTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

// A unit cube at x = id, named "o<id>"; object `bad` gets an infinite corner.
void MakeCube(ObjectId id, ObjectId bad, SceneObject* obj) {
  obj->id = id;
  obj->name = "o";
  obj->name += std::to_string(id);
  obj->mesh.vertices.clear();
  for (int c = 0; c < 8; ++c)
    obj->mesh.vertices.insert(
        obj->mesh.vertices.end(),
        {static_cast<float>(id + (c & 1)), static_cast<float>(c >> 1 & 1), static_cast<float>(c >> 2)});
  if (id == bad) obj->mesh.vertices[0] = std::numeric_limits<float>::infinity();
  obj->mesh.triangles = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                         2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
}

TEST(ObjectEncoderTest, SinkSeesEveryObjectInOrderWithItsEntry) {
  for (uint32_t threads : {1u, 2u, 4u}) {
    constexpr ObjectId kCount = 5000;
    ObjectId next = 0, expected = 0;
    auto read = [&](SceneObject* obj) -> Result<bool> {
      if (next == kCount) return false;
      MakeCube(next++, kNoIndex, obj);
      return true;
    };
    auto sink = [&](const SceneObject& obj, const EncodedObject& e) -> Status {
      EXPECT_EQ(obj.id, expected);
      auto parsed = ParseObjectEntry(e.entry.data(), e.entry.size());
      EXPECT_TRUE(parsed.ok());
      if (parsed.ok()) {
        EXPECT_EQ(parsed->id, expected);
        EXPECT_EQ(parsed->entry_bytes(), e.entry.size());
        EXPECT_EQ(parsed->shape_flags, kShapeKnown | kShapeEvenEdges | kShapeClosed);
      }
      EXPECT_EQ(e.box.min[0], static_cast<float>(expected));
      ++expected;
      return Status::Ok();
    };
    ASSERT_TRUE(EncodeObjects({CodecOptions{}, threads, {}}, read, sink).ok());
    EXPECT_EQ(expected, kCount) << threads << " threads";
  }
}

TEST(ObjectEncoderTest, FirstErrorInInputOrderWins) {
  for (uint32_t threads : {1u, 2u, 4u}) {
    // Object 1500 has non-finite bounds; reading fails later, at 2600: the bounds error is the one a
    // sequential loop meets first, and nothing after object 1499 reaches the sink.
    ObjectId next = 0, sunk = 0;
    auto read = [&](SceneObject* obj) -> Result<bool> {
      if (next == 2600) return Status::IOError("disk on fire");
      MakeCube(next++, 1500, obj);
      return true;
    };
    auto sink = [&](const SceneObject&, const EncodedObject&) -> Status {
      ++sunk;
      return Status::Ok();
    };
    Status st = EncodeObjects({CodecOptions{}, threads, {}}, read, sink);
    EXPECT_EQ(st.code(), Status::Code::kInvalidArgument) << st.ToString();
    EXPECT_NE(st.message().find("object 1500 ('o1500')"), std::string::npos) << st.ToString();
    EXPECT_EQ(sunk, 1500u);

    // Without a bad object the read error comes back, after every object before it.
    next = sunk = 0;
    auto read_ok = [&](SceneObject* obj) -> Result<bool> {
      if (next == 2600) return Status::IOError("disk on fire");
      MakeCube(next++, kNoIndex, obj);
      return true;
    };
    st = EncodeObjects({CodecOptions{}, threads, {}}, read_ok, sink);
    EXPECT_EQ(st.code(), Status::Code::kIOError) << st.ToString();
    EXPECT_EQ(sunk, 2600u);

    // A sink error stops the pipeline at once.
    next = sunk = 0;
    auto failing_sink = [&](const SceneObject& obj, const EncodedObject&) -> Status {
      if (obj.id == 700) return Status::IOError("spill full");
      ++sunk;
      return Status::Ok();
    };
    st = EncodeObjects({CodecOptions{}, threads, {}}, read_ok, failing_sink);
    EXPECT_EQ(st.message(), "spill full");
    EXPECT_EQ(sunk, 700u);
  }
}

// The sink runs on the drain thread: what it throws (std::bad_alloc under a memory limit) must come back
// as a Status, not end the process; what the reader throws (on the calling thread) propagates after the
// pipeline's threads are stopped.
TEST(ObjectEncoderTest, ExceptionsInTheStagesDoNotEscapeTheirThreads) {
  for (uint32_t threads : {1u, 2u, 4u}) {
    ObjectId next = 0, sunk = 0;
    auto read = [&](SceneObject* obj) -> Result<bool> {
      if (next == 5000) return false;
      MakeCube(next++, kNoIndex, obj);
      return true;
    };
    auto throwing_sink = [&](const SceneObject& obj, const EncodedObject&) -> Status {
      if (obj.id == 900) throw std::bad_alloc();
      ++sunk;
      return Status::Ok();
    };
    Status st = Status::Ok();
    if (threads == 1) {  // no drain thread: the exception reaches the caller, as it did before
      EXPECT_THROW(st = EncodeObjects({CodecOptions{}, threads, {}}, read, throwing_sink), std::bad_alloc);
    } else {
      st = EncodeObjects({CodecOptions{}, threads, {}}, read, throwing_sink);
      EXPECT_EQ(st.code(), Status::Code::kInternal) << st.ToString();
      EXPECT_NE(st.message().find("out of memory"), std::string::npos) << st.ToString();
    }
    EXPECT_EQ(sunk, 900u);

    next = sunk = 0;
    auto throwing_read = [&](SceneObject* obj) -> Result<bool> {
      if (next == 3000) throw std::runtime_error("reader broke");
      MakeCube(next++, kNoIndex, obj);
      return true;
    };
    auto sink = [&](const SceneObject&, const EncodedObject&) -> Status {
      ++sunk;
      return Status::Ok();
    };
    EXPECT_THROW(st = EncodeObjects({CodecOptions{}, threads, {}}, throwing_read, sink), std::runtime_error);
    EXPECT_LE(sunk, 3000u);
  }
}

TEST(SpillFileTest, ReadManyAndCursorReturnWhatWasAppended) {
  auto spill = SpillFile::Create(fs::temp_directory_path().string(), "mktree_spill_test");
  ASSERT_TRUE(spill.ok()) << spill.status().ToString();
  SpillFile& f = **spill;
  std::mt19937 rng(5);
  std::vector<uint8_t> data(9 << 20);  // more than the append buffer, so some of it is flushed early
  for (uint8_t& b : data) b = static_cast<uint8_t>(rng());
  for (size_t at = 0; at < data.size();) {
    const size_t n = std::min<size_t>(data.size() - at, rng() % 5000);
    auto offset = f.Append(data.data() + at, n);
    ASSERT_TRUE(offset.ok());
    ASSERT_EQ(*offset, at);
    at += n;
  }
  ASSERT_TRUE(f.Flush().ok());
  ASSERT_EQ(f.size(), data.size());

  // Ranges: small and large gaps, overlaps, zero sizes and more ranges than one preadv takes (1024).
  std::vector<SpillFile::Range> ranges;
  std::vector<std::vector<uint8_t>> outs(6000);
  std::vector<std::pair<uint64_t, uint64_t>> want;
  for (auto& out : outs) {
    const uint64_t size = rng() % 3 == 0 ? 0 : rng() % 20000;
    const uint64_t offset = rng() % (data.size() - size);
    out.resize(size);
    ranges.push_back({offset, size, out.data()});
    want.emplace_back(offset, size);
  }
  ASSERT_TRUE(f.ReadMany(&ranges).ok());
  for (size_t i = 0; i < outs.size(); ++i)
    ASSERT_TRUE(std::equal(outs[i].begin(), outs[i].end(), data.begin() + want[i].first)) << "range " << i;
  // Adjacent ranges in order (the common case: a leaf of consecutive ids).
  std::vector<uint8_t> whole(data.size());
  ranges.clear();
  for (uint64_t at = 0; at < data.size(); at += 3000)
    ranges.push_back({at, std::min<uint64_t>(3000, data.size() - at), whole.data() + at});
  ASSERT_TRUE(f.ReadMany(&ranges).ok());
  EXPECT_EQ(whole, data);
  std::vector<SpillFile::Range> past_end = {{data.size() - 10, 11, whole.data()}};
  EXPECT_FALSE(f.ReadMany(&past_end).ok());

  SpillCursor cursor(f);
  std::vector<uint8_t> back(data.size());
  for (size_t at = 0; at < data.size();) {
    const size_t n = std::min<size_t>(data.size() - at, rng() % 300000);
    ASSERT_TRUE(cursor.Read(n, back.data() + at).ok());
    at += n;
  }
  EXPECT_EQ(back, data);
  uint8_t extra;
  EXPECT_FALSE(cursor.Read(1, &extra).ok());
}

}  // namespace
}  // namespace mktree
