// Object entry and leaf page codecs: round trips, size accounting, corruption detection, and the
// compression ratio of the shuffle transform on tanker-like meshes.
#include <gtest/gtest.h>

#include <cstdio>
#include <limits>

#include "engine/store_format/leaf_codec.h"
#include "engine/store_format/object_codec.h"
#include "storage/byte_io.h"
#include "storage/page_codec.h"
#include "store_format/store_test_util.h"

namespace mktree {
namespace {

using testing::BoxMesh;
using testing::PrismMesh;
using testing::RandomMesh;
using testing::SameMesh;

const CodecOptions kCodecs[] = {{Codec::kNone, 3, false, nullptr},
                                {Codec::kZstd, 3, false, nullptr},
                                {Codec::kZstd, 3, true, nullptr},
                                {Codec::kZstd, 19, true, nullptr},
                                {Codec::kZstd, -5, true, nullptr}};

TEST(ObjectCodecTest, RoundTripsEveryCodec) {
  std::mt19937 g(7);
  std::vector<SceneObject> objects = testing::MakeObjects(300, 11);
  SceneObject no_triangles;  // an empty array next to a non-empty one (no memcpy from a null data())
  no_triangles.id = 998;
  no_triangles.mesh.vertices = {0, 0, 0, 1, 2, 3};
  objects.push_back(no_triangles);
  for (const CodecOptions& c : kCodecs) {
    for (const SceneObject& o : objects) {
      std::vector<uint8_t> buf = {1, 2, 3};  // appends after existing bytes
      const uint32_t n = EncodeObjectEntry(o, c, &buf);
      ASSERT_EQ(n + 3u, buf.size());
      auto e = ParseObjectEntry(buf.data() + 3, n);
      ASSERT_TRUE(e.ok()) << e.status().ToString();
      EXPECT_EQ(e->id, o.id);
      // The box's min corner is the local frame's origin; its max may grow where rounding a local
      // coordinate up took the decoded vertex past it.
      EXPECT_EQ(e->box.min, o.Aabb().min);
      for (int k = 0; k < 3; ++k) EXPECT_GE(e->box.max[k], o.Aabb().max[k]);
      EXPECT_EQ(e->entry_bytes(), n);
      EXPECT_EQ(e->vertex_count, o.mesh.vertex_count());
      EXPECT_EQ(e->triangle_count, o.mesh.triangle_count());
      if (c.codec == Codec::kNone) {
        EXPECT_EQ(e->codec, Codec::kNone);
      }
      Mesh m;
      ASSERT_TRUE(DecodeObjectMesh(*e, &m).ok());
      EXPECT_TRUE(SameMesh(m, o.mesh)) << "object " << o.id;
    }
  }
}

// Objects a leaf entry cannot hold are refused with a reason, appending nothing: no vertex, a non-finite
// coordinate, a coordinate beyond float32's range from the store's origin.
TEST(ObjectCodecTest, UnencodableObjectsAreRefused) {
  SceneObject o;
  o.id = 4;
  o.name = "bad";
  std::vector<uint8_t> buf = {7};
  auto expect_refused = [&](const char* why) {
    auto n = EncodeObjectEntry(o, Vec3d{}, CodecOptions{}, &buf);
    ASSERT_FALSE(n.ok()) << why;
    EXPECT_EQ(n.status().code(), Status::Code::kInvalidArgument);
    EXPECT_NE(n.status().message().find("object 4 ('bad')"), std::string::npos) << n.status().ToString();
    EXPECT_NE(n.status().message().find(why), std::string::npos) << n.status().ToString();
    EXPECT_EQ(buf.size(), 1u);
  };
  expect_refused("no vertices");
  o.mesh.vertices = {0, 0, 0, 1, 0, 0, 0, std::nan(""), 0};
  o.mesh.triangles = {0, 1, 2};
  expect_refused("non-finite");
  o.mesh.vertices = {0, 0, 0, 1, 0, 0, 0, 1e300, 0};
  expect_refused("beyond float32's range");
}

// Coordinates far from 0 keep float32's precision of the object's own box: a 0.2 m cube at UTM-sized
// coordinates decodes within 2^-22 of its box's extent (0.2 m in a store frame near it), where float32
// world coordinates would move its corners by up to 0.25 m.
TEST(ObjectCodecTest, FarCoordinatesKeepTheObjectsPrecision) {
  for (const Vec3d origin : {Vec3d{}, Vec3d{500000, 5000000, 0}}) {
    SceneObject o;
    o.id = 1;
    const double c[3] = {500000.1234, 5000000.0001, 100.05};
    for (int i = 0; i < 8; ++i)
      for (int k = 0; k < 3; ++k) o.mesh.vertices.push_back(c[k] + ((i >> k) & 1) * 0.2);
    o.mesh.triangles = {0, 1, 3, 0, 3, 2};
    for (const CodecOptions& codec : kCodecs) {
      std::vector<uint8_t> buf;
      Box3f box;
      auto n = EncodeObjectEntry(o, origin, codec, &buf, 0, &box);
      ASSERT_TRUE(n.ok()) << n.status().ToString();
      auto e = ParseObjectEntry(buf.data(), *n);
      ASSERT_TRUE(e.ok());
      EXPECT_EQ(e->box, box);
      Mesh m;
      ASSERT_TRUE(DecodeObjectMesh(*e, &m).ok());
      EXPECT_TRUE(SameMesh(m, o.mesh, origin));
      for (size_t i = 0; i < m.vertices.size(); ++i) {
        const double world = m.vertices[i] + origin[i % 3];
        const double extent = double{box.max[i % 3]} - box.min[i % 3];
        EXPECT_NEAR(world, o.mesh.vertices[i], extent * 0x1p-22) << i;
        EXPECT_GE(m.vertices[i], box.min[i % 3]);
        EXPECT_LE(m.vertices[i], box.max[i % 3]);
      }
      // In the store frame the box is as tight as float32 allows there: within a few ulps of 0.2 m wide
      // at the origin that holds it near 0, and within 0.5 m where the frame is the world's.
      const double width = double{box.max[0]} - box.min[0];
      if (origin.x != 0) {
        EXPECT_NEAR(width, 0.2, 1e-6);
      } else {
        EXPECT_GT(width, 0.2 - 1e-9);
      }
    }
  }
}

TEST(ObjectCodecTest, EncodedSizeIsDeterministic) {
  // Ingest sizes leaves from encoded_bytes of a first encoding: a second encoding must be identical.
  for (const SceneObject& o : testing::MakeObjects(50, 3)) {
    std::vector<uint8_t> a, b;
    EncodeObjectEntry(o, {}, &a);
    EncodeObjectEntry(o, {}, &b);
    EXPECT_EQ(a, b);
  }
}

TEST(ObjectCodecTest, CorruptEntriesAreRefused) {
  std::mt19937 g(1);
  SceneObject o;
  o.id = 5;
  o.mesh = PrismMesh(g, 12, 0);
  std::vector<uint8_t> buf;
  const uint32_t n = EncodeObjectEntry(o, {}, &buf);
  EXPECT_FALSE(ParseObjectEntry(buf.data(), n - 1).ok());  // runs past the end
  EXPECT_FALSE(ParseObjectEntry(buf.data(), 10).ok());
  auto with = [&](size_t off, uint8_t v) {
    std::vector<uint8_t> b = buf;
    b[off] = v;
    return b;
  };
  EXPECT_FALSE(ParseObjectEntry(with(28, 7).data(), n).ok());   // unknown codec
  EXPECT_FALSE(ParseObjectEntry(with(29, 9).data(), n).ok());   // unknown transform
  EXPECT_FALSE(ParseObjectEntry(with(32, 99).data(), n).ok());  // counts disagree with raw size
  // Boxes that are not finite or inverted (fuzz regression store_open/entry-box-infinite-extent: an
  // infinite extent overflowed the local frame's exponent).
  for (float bad :
       {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::quiet_NaN(), -1e30f}) {
    std::vector<uint8_t> b = buf;
    storage_internal::Put<float>(b.data() + 16, bad);  // box.max.x
    auto e = ParseObjectEntry(b.data(), n);
    ASSERT_FALSE(e.ok()) << bad;
    EXPECT_NE(e.status().message().find("box is not finite"), std::string::npos) << e.status().message();
  }
  // Garbage in the compressed stream: decoding fails (or, if zstd accepts it, the sizes or indices do
  // not check out); it never returns a different mesh silently for these bytes.
  int refused = 0;
  for (size_t off = kObjectEntryHeaderBytes; off < n; ++off) {
    std::vector<uint8_t> b = with(off, buf[off] ^ 0xff);
    auto e = ParseObjectEntry(b.data(), n);
    ASSERT_TRUE(e.ok());
    Mesh m;
    if (!DecodeObjectMesh(*e, &m).ok()) ++refused;
  }
  EXPECT_GT(refused, 0);
  // A triangle index out of range in a raw entry.
  std::vector<uint8_t> raw;
  const uint32_t rn = EncodeObjectEntry(o, {Codec::kNone, 0, false, nullptr}, &raw);
  storage_internal::Put<uint32_t>(raw.data() + rn - 4, 1000);
  auto e = ParseObjectEntry(raw.data(), rn);
  ASSERT_TRUE(e.ok());
  Mesh m;
  Status st = DecodeObjectMesh(*e, &m);
  EXPECT_EQ(st.code(), Status::Code::kCorruption);
}

// Measures the compressed size of tanker-like meshes with and without the shuffle transform. The
// transform is on by default because it wins here; this test keeps that claim true.
TEST(ObjectCodecTest, ShuffleShrinksPrismsAndBoxes) {
  std::mt19937 g(42);
  std::vector<SceneObject> prisms(2000), boxes(2000);
  for (auto& o : prisms) o.mesh = PrismMesh(g, 8 + static_cast<int>(g() % 9), static_cast<int>(g() % 3));
  for (auto& o : boxes) o.mesh = BoxMesh(g);
  auto total = [](const std::vector<SceneObject>& v, const CodecOptions& c) {
    std::vector<uint8_t> buf;
    uint64_t sum = 0;
    for (const auto& o : v) {
      buf.clear();
      sum += EncodeObjectEntry(o, c, &buf) - kObjectEntryHeaderBytes;
    }
    return sum;
  };
  for (auto* set : {&prisms, &boxes}) {
    const uint64_t raw = total(*set, {Codec::kNone, 0, false, nullptr});
    const uint64_t plain = total(*set, {Codec::kZstd, 3, false, nullptr});
    const uint64_t shuf = total(*set, {Codec::kZstd, 3, true, nullptr});
    const uint64_t shuf19 = total(*set, {Codec::kZstd, 19, true, nullptr});
    std::printf("[ratio] %s: raw %llu B, zstd-3 %.2fx, shuffle+zstd-3 %.2fx, shuffle+zstd-19 %.2fx\n",
                set == &prisms ? "prisms (8-16 sides)" : "boxes", static_cast<unsigned long long>(raw),
                double(raw) / plain, double(raw) / shuf, double(raw) / shuf19);
    EXPECT_LT(shuf, plain);
    EXPECT_LT(plain, raw);
  }
}

class LeafCodecTest : public ::testing::Test {
 protected:
  static constexpr uint64_t kMemPage = 12288;
  std::vector<std::vector<uint8_t>> Entries(const std::vector<SceneObject>& objs) {
    std::vector<std::vector<uint8_t>> out;
    for (const auto& o : objs) {
      out.emplace_back();
      EncodeObjectEntry(o, {}, &out.back());
    }
    return out;
  }
  // Encodes a leaf into consecutive pages.
  std::vector<std::vector<uint8_t>> Pages(uint32_t leaf, const std::vector<std::vector<uint8_t>>& entries) {
    std::vector<std::span<const uint8_t>> spans(entries.begin(), entries.end());
    std::vector<std::vector<uint8_t>> pages;
    Status st = EncodeLeafPages(leaf, spans, kMemPage, [&](const uint8_t* p) {
      pages.emplace_back(p, p + kMemPage);
      return Status::Ok();
    });
    EXPECT_TRUE(st.ok());
    return pages;
  }
  static std::vector<const uint8_t*> Ptrs(const std::vector<std::vector<uint8_t>>& pages) {
    std::vector<const uint8_t*> v;
    for (const auto& p : pages) v.push_back(p.data());
    return v;
  }
};

TEST_F(LeafCodecTest, SingleAndMultiPageLeavesRoundTrip) {
  std::mt19937 g(3);
  // One page, full to the byte budget.
  std::vector<SceneObject> objs;
  std::vector<std::vector<uint8_t>> entries;
  uint64_t sum = 0;
  for (uint32_t i = 0;; ++i) {
    SceneObject o;
    o.id = i;
    o.mesh = PrismMesh(g, 12, i % 3);
    std::vector<uint8_t> e;
    EncodeObjectEntry(o, {}, &e);
    if (!FitsInOnePage(sum + e.size(), kMemPage)) break;
    sum += e.size();
    objs.push_back(o);
    entries.push_back(e);
  }
  auto pages = Pages(4, entries);
  ASSERT_EQ(pages.size(), 1u);
  auto v = LeafView::Parse("mem", 4, 10, Ptrs(pages), kMemPage, true);
  ASSERT_TRUE(v.ok()) << v.status().ToString();
  ASSERT_EQ(v->size(), objs.size());
  EXPECT_EQ(v->payload_bytes(), LeafPayloadBytes(sum));
  for (size_t i = 0; i < objs.size(); ++i) {
    Mesh m;
    ASSERT_TRUE(DecodeObjectMesh(v->entry(i), &m).ok());
    EXPECT_TRUE(SameMesh(m, objs[i].mesh));
  }
  // One oversized object: several pages.
  SceneObject big;
  big.id = 77;
  big.mesh = RandomMesh(g, 3000, 4000);
  auto big_entries = Entries({big});
  auto big_pages = Pages(9, big_entries);
  EXPECT_EQ(big_pages.size(), PagesForLeaf(big_entries[0].size(), kMemPage));
  EXPECT_GT(big_pages.size(), 2u);
  auto bv = LeafView::Parse("mem", 9, 0, Ptrs(big_pages), kMemPage, true);
  ASSERT_TRUE(bv.ok()) << bv.status().ToString();
  LeafView moved = std::move(bv).value();  // views survive a move
  Mesh m;
  ASSERT_TRUE(DecodeObjectMesh(moved.entry(0), &m).ok());
  EXPECT_TRUE(SameMesh(m, big.mesh));
  // An empty leaf is legal (header only).
  auto empty = Pages(1, {});
  auto ev = LeafView::Parse("mem", 1, 0, Ptrs(empty), kMemPage, true);
  ASSERT_TRUE(ev.ok());
  EXPECT_EQ(ev->size(), 0u);
}

TEST_F(LeafCodecTest, ParsingIntoOneViewLeafAfterLeafEqualsFreshParses) {
  std::mt19937 g(5);
  SceneObject big;
  big.id = 3;
  big.mesh = RandomMesh(g, 2000, 2000);
  auto big_pages = Pages(7, Entries({big}));
  ASSERT_GT(big_pages.size(), 1u);
  auto small_pages = Pages(2, Entries(testing::MakeObjects(20, 5, false)));
  ASSERT_EQ(small_pages.size(), 1u);
  auto fresh_small = LeafView::Parse("s", 2, 0, Ptrs(small_pages), kMemPage, true);
  ASSERT_TRUE(fresh_small.ok());

  LeafView v;
  ASSERT_TRUE(LeafView::Parse("s", 7, 0, Ptrs(big_pages), kMemPage, true, &v).ok());
  ASSERT_EQ(v.size(), 1u);
  Mesh m;
  ASSERT_TRUE(DecodeObjectMesh(v.entry(0), &m).ok());
  EXPECT_TRUE(SameMesh(m, big.mesh));
  ASSERT_TRUE(LeafView::Parse("s", 2, 0, Ptrs(small_pages), kMemPage, true, &v).ok());
  EXPECT_EQ(v.leaf_index(), 2u);
  EXPECT_EQ(v.payload_bytes(), fresh_small->payload_bytes());
  ASSERT_EQ(v.size(), fresh_small->size());
  for (size_t i = 0; i < v.size(); ++i) {
    EXPECT_EQ(v.entry(i).id, fresh_small->entry(i).id);
    EXPECT_EQ(v.entry(i).geometry.data(), fresh_small->entry(i).geometry.data());  // into the page itself
  }
  // A failed parse leaves the view empty, never holding the previous leaf's entries.
  auto bad = small_pages;
  bad[0][500] ^= 1;
  EXPECT_FALSE(LeafView::Parse("s", 2, 0, Ptrs(bad), kMemPage, true, &v).ok());
  EXPECT_EQ(v.size(), 0u);
  ASSERT_TRUE(LeafView::Parse("s", 2, 0, Ptrs(small_pages), kMemPage, true, &v).ok());
  EXPECT_FALSE(LeafView::Parse("s", 3, 0, Ptrs(small_pages), kMemPage, true, &v).ok());  // wrong leaf
  EXPECT_EQ(v.size(), 0u);
}

TEST_F(LeafCodecTest, EveryFlippedByteIsDetected) {
  auto entries = Entries(testing::MakeObjects(20, 5, false));
  auto pages = Pages(2, entries);
  ASSERT_EQ(pages.size(), 1u);
  for (size_t off = 0; off < kMemPage; ++off) {
    auto bad = pages;
    bad[0][off] ^= 0x10;
    auto v = LeafView::Parse("store.mkt", 2, 33, Ptrs(bad), kMemPage, true);
    ASSERT_FALSE(v.ok()) << "flip at byte " << off << " not detected";
    EXPECT_EQ(v.status().code(), Status::Code::kCorruption);
    ASSERT_NE(v.status().message().find("store.mkt: page 33"), std::string::npos) << v.status().message();
  }
}

TEST_F(LeafCodecTest, MisplacedPagesAreDetected) {
  std::mt19937 g(8);
  SceneObject big;
  big.mesh = RandomMesh(g, 2000, 2000);
  auto pages = Pages(3, Entries({big}));
  ASSERT_GE(pages.size(), 3u);
  auto p = Ptrs(pages);
  EXPECT_FALSE(LeafView::Parse("s", 4, 0, p, kMemPage, true).ok());  // wrong leaf
  std::swap(p[0], p[1]);
  EXPECT_FALSE(LeafView::Parse("s", 3, 0, p, kMemPage, true).ok());  // wrong order
  p = Ptrs(pages);
  p.pop_back();
  EXPECT_FALSE(LeafView::Parse("s", 3, 0, p, kMemPage, true).ok());  // missing page
  std::vector<uint8_t> zero(kMemPage, 0);
  EXPECT_FALSE(LeafView::Parse("s", 3, 0, {zero.data()}, kMemPage, false).ok());  // not a page
}

TEST_F(LeafCodecTest, VerificationCanBeSkipped) {
  auto entries = Entries(testing::MakeObjects(5, 9, false));
  auto pages = Pages(0, entries);
  pages[0][kMemPage - 1] ^= 1;  // padding: only the checksum sees it
  EXPECT_FALSE(LeafView::Parse("s", 0, 0, Ptrs(pages), kMemPage, true).ok());
  EXPECT_TRUE(LeafView::Parse("s", 0, 0, Ptrs(pages), kMemPage, false).ok());
}

}  // namespace
}  // namespace mktree
