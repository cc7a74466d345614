#include "engine/scene/mkscene_format.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <xxhash.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "engine/generator/tanker_generator.h"
#include "generator/mesh_checks.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;
using testing::Drain;

class MkSceneFormatTest : public ::testing::Test {
 protected:
  // Writes `objects` to `path` and returns them.
  std::vector<SceneObject> WriteTanker(const std::string& path, uint64_t n) {
    auto source = MakeTankerSource(n, 77);
    std::vector<SceneObject> objects = Drain(source.get());
    auto writer = MkSceneWriter::Create(path);
    EXPECT_TRUE(writer.ok()) << writer.status().ToString();
    for (const SceneObject& o : objects) EXPECT_TRUE((*writer)->Write(o).ok());
    EXPECT_TRUE((*writer)->Finish().ok());
    EXPECT_EQ((*writer)->objects_written(), n);
    EXPECT_EQ((*writer)->bytes_written(), fs::file_size(path));
    return objects;
  }

  static std::string Slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  static void Spit(const std::string& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), bytes.size());
  }

  // Reads `path` to the end and returns the first error (ok status if none).
  static Status ReadAll(const std::string& path, uint64_t* objects = nullptr) {
    auto source = OpenMkSceneFile(path);
    if (!source.ok()) return source.status();
    SceneObject o;
    uint64_t n = 0;
    while (true) {
      Result<bool> more = (*source)->Next(&o);
      if (!more.ok()) return more.status();
      if (!*more) break;
      ++n;
    }
    if (objects) *objects = n;
    return Status::Ok();
  }

  testing::TempDir dir_{"mktree_mkscene"};
};

TEST_F(MkSceneFormatTest, RoundTripIsExact) {
  const std::string path = dir_ / "scene.mks";
  const auto written = WriteTanker(path, 700);
  auto source = OpenMkSceneFile(path, 1000);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  const auto read = Drain(source->get());
  ASSERT_EQ(read.size(), written.size());
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].id, 1000 + i);
    EXPECT_EQ(read[i].name, written[i].name);
    EXPECT_EQ(read[i].source, path);  // the file read, not the generator that wrote it
    EXPECT_EQ(read[i].mesh.vertices, written[i].mesh.vertices);
    EXPECT_EQ(read[i].mesh.triangles, written[i].mesh.triangles);
  }
  // Deterministic bytes: writing the same scene again gives the same file.
  WriteTanker(dir_ / "again.mks", 700);
  EXPECT_EQ(Slurp(path), Slurp(dir_ / "again.mks"));
}

TEST_F(MkSceneFormatTest, EmptySceneAndUnusualObjects) {
  const std::string path = dir_ / "odd.mks";
  auto writer = MkSceneWriter::Create(path);
  ASSERT_TRUE(writer.ok());
  SceneObject empty;  // no name, no geometry
  SceneObject named;
  named.name = "tri \xc3\xa9";
  named.mesh.vertices = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  named.mesh.triangles = {0, 1, 2};
  ASSERT_TRUE((*writer)->Write(empty).ok());
  ASSERT_TRUE((*writer)->Write(named).ok());
  SceneObject bad = named;
  bad.mesh.triangles = {0, 1, 3};
  EXPECT_EQ((*writer)->Write(bad).code(), Status::Code::kInvalidArgument);
  ASSERT_TRUE((*writer)->Finish().ok());
  auto source = OpenMkSceneFile(path);
  ASSERT_TRUE(source.ok());
  const auto read = Drain(source->get());
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].name, "");
  EXPECT_EQ(read[0].mesh.vertex_count(), 0u);
  EXPECT_EQ(read[1].name, named.name);
  EXPECT_EQ(read[1].mesh.triangles, named.mesh.triangles);

  const std::string none = dir_ / "none.mks";
  auto w2 = MkSceneWriter::Create(none);
  ASSERT_TRUE(w2.ok());
  ASSERT_TRUE((*w2)->Finish().ok());
  uint64_t n = 99;
  EXPECT_TRUE(ReadAll(none, &n).ok());
  EXPECT_EQ(n, 0u);
}

// Scenes far from 0 keep every digit: float64 vertices (format version 2).
TEST_F(MkSceneFormatTest, UtmCoordinatesRoundTripExactly) {
  const std::string path = dir_ / "utm.mks";
  SceneObject o;
  o.name = "bolt";
  o.mesh.vertices = {500000.1234, 5000000.0001, 100.001,      500000.1244, 5000000.0001,
                     100.001,     500000.1234,  5000000.0011, 100.002};
  o.mesh.triangles = {0, 1, 2};
  auto writer = MkSceneWriter::Create(path);
  ASSERT_TRUE(writer.ok());
  ASSERT_TRUE((*writer)->Write(o).ok());
  ASSERT_TRUE((*writer)->Finish().ok());
  auto source = OpenMkSceneFile(path);
  ASSERT_TRUE(source.ok());
  SceneObject back;
  auto more = (*source)->Next(&back);
  ASSERT_TRUE(more.ok() && *more) << more.status().ToString();
  EXPECT_EQ(back.mesh.vertices, o.mesh.vertices);
}

// Files of format version 1 (float32 vertices) written by earlier builds are still read.
TEST_F(MkSceneFormatTest, Version1FilesAreStillRead) {
  const std::string path = dir_ / "v1.mks";
  std::string bytes("MKSCENE\0", 8);
  auto put32 = [&](uint32_t v) { bytes.append(reinterpret_cast<const char*>(&v), 4); };
  auto put64 = [&](uint64_t v) { bytes.append(reinterpret_cast<const char*>(&v), 8); };
  put32(1);
  put32(0);
  const size_t record = bytes.size();
  put32(0x424f4b4d);  // "MKOB"
  put32(3);
  bytes += "tri";
  put32(3);
  put32(1);
  for (float v : {0.5f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.25f, 0.f})
    bytes.append(reinterpret_cast<const char*>(&v), 4);
  for (uint32_t i : {0u, 1u, 2u}) put32(i);
  put64(XXH3_64bits(bytes.data() + record, bytes.size() - record));
  const size_t end = bytes.size();
  put32(0x4e454b4d);  // "MKEN"
  put32(0);
  put64(1);
  put64(XXH3_64bits(bytes.data() + end, 16));
  Spit(path, bytes);
  auto source = OpenMkSceneFile(path, 4);
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  SceneObject o;
  auto more = (*source)->Next(&o);
  ASSERT_TRUE(more.ok() && *more) << more.status().ToString();
  EXPECT_EQ(o.id, 4u);
  EXPECT_EQ(o.name, "tri");
  EXPECT_EQ(o.mesh.vertices, (std::vector<double>{0.5, 0, 0, 1, 0, 0, 0, 1.25, 0}));
  EXPECT_EQ(o.mesh.triangles, (std::vector<uint32_t>{0, 1, 2}));
  more = (*source)->Next(&o);
  ASSERT_TRUE(more.ok()) << more.status().ToString();
  EXPECT_FALSE(*more);
}

TEST_F(MkSceneFormatTest, FlippedByteIsAChecksumErrorNamingTheObject) {
  const std::string path = dir_ / "scene.mks";
  WriteTanker(path, 50);
  const std::string good = Slurp(path);
  // Find object 3's record: walk the records by their sizes.
  size_t offset = 16;
  for (int i = 0; i < 3; ++i) {
    uint32_t name_bytes, nv, nt;
    std::memcpy(&name_bytes, good.data() + offset + 4, 4);
    std::memcpy(&nv, good.data() + offset + 8 + name_bytes, 4);
    std::memcpy(&nt, good.data() + offset + 12 + name_bytes, 4);
    offset += 16 + name_bytes + 24 * nv + 12 * nt + 8;
  }
  std::string bad = good;
  bad[offset + 40] ^= 0x10;  // inside object 3's name or vertices
  Spit(path, bad);
  uint64_t read = 0;
  auto source = OpenMkSceneFile(path);
  ASSERT_TRUE(source.ok());
  SceneObject o;
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(*(*source)->Next(&o)) << i;
  Result<bool> r = (*source)->Next(&o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kCorruption);
  const std::string msg = r.status().message();
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("object 3 (offset " + std::to_string(offset) + ")"), std::string::npos) << msg;
  EXPECT_NE(msg.find("checksum mismatch"), std::string::npos) << msg;
  EXPECT_FALSE(ReadAll(path, &read).ok());

  // A flipped byte in the end record, too.
  bad = good;
  bad[bad.size() - 12] ^= 1;
  Spit(path, bad);
  EXPECT_EQ(ReadAll(path).code(), Status::Code::kCorruption);
}

TEST_F(MkSceneFormatTest, TruncationAtEveryRecordBoundaryAndInsideIsAnError) {
  const std::string path = dir_ / "scene.mks";
  WriteTanker(path, 20);
  const std::string good = Slurp(path);
  ASSERT_TRUE(ReadAll(path).ok());
  for (size_t cut :
       {good.size() - 1, good.size() - 24, good.size() / 2, size_t{17}, size_t{16}, size_t{10}, size_t{0}}) {
    Spit(path, good.substr(0, cut));
    const Status st = ReadAll(path);
    ASSERT_FALSE(st.ok()) << cut;
    EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
    EXPECT_NE(st.message().find(path), std::string::npos) << st.ToString();
    if (cut >= 16) {
      EXPECT_NE(st.message().find("truncated"), std::string::npos) << st.ToString();
    }
  }
  Spit(path, good + "x");
  EXPECT_NE(ReadAll(path).message().find("trailing"), std::string::npos);
}

TEST_F(MkSceneFormatTest, BadMagicVersionAndMissingFile) {
  const std::string path = dir_ / "scene.mks";
  WriteTanker(path, 3);
  std::string bytes = Slurp(path);
  bytes[0] = 'X';
  Spit(path, bytes);
  Status st = ReadAll(path);
  EXPECT_EQ(st.code(), Status::Code::kCorruption);
  EXPECT_NE(st.message().find("bad magic"), std::string::npos) << st.ToString();
  bytes[0] = 'M';
  bytes[8] = 3;  // version 3
  Spit(path, bytes);
  EXPECT_EQ(ReadAll(path).code(), Status::Code::kUnsupported);
  EXPECT_EQ(ReadAll(dir_ / "missing.mks").code(), Status::Code::kNotFound);
}

TEST_F(MkSceneFormatTest, UnfinishedWriterLeavesNoFile) {
  const std::string path = dir_ / "scene.mks";
  {
    auto writer = MkSceneWriter::Create(path);
    ASSERT_TRUE(writer.ok());
    SceneObject o;
    o.name = "x";
    ASSERT_TRUE((*writer)->Write(o).ok());
    EXPECT_FALSE(fs::exists(path));  // only the temporary exists while writing
  }
  EXPECT_TRUE(fs::is_empty(dir_));  // and the destructor removed it
  EXPECT_FALSE(MkSceneWriter::Create((dir_ / "no_such_dir" / "x.mks").string()).ok());
}

// The objects of a part, read as mktree-mpi reads them; the first error fails the test.
std::vector<SceneObject> ReadPart(const std::string& path, const MkSceneLayout& l, const MkScenePart& p,
                                  uint64_t first) {
  auto source = OpenMkScenePart(path, l, p, first, static_cast<ObjectId>(first));
  EXPECT_TRUE(source.ok()) << source.status().ToString();
  return source.ok() ? Drain(source->get()) : std::vector<SceneObject>{};
}

TEST_F(MkSceneFormatTest, PartsCutAtEveryByteChainAndReadAsTheWhole) {
  const std::string path = dir_ / "scene.mks";
  const std::vector<SceneObject> objects = WriteTanker(path, 6);
  auto layout = ReadMkSceneLayout(path);
  ASSERT_TRUE(layout.ok()) << layout.status().ToString();
  EXPECT_EQ(layout->objects, 6u);
  EXPECT_EQ(layout->body_end + 24, fs::file_size(path));
  // Two parts cut at every byte of the body, and three parts at a stride.
  for (uint64_t cut = layout->body_begin; cut <= layout->body_end; ++cut) {
    std::vector<uint64_t> begins = {layout->body_begin, cut};
    std::vector<MkScenePart> parts;
    for (size_t i = 0; i < 2; ++i) {
      auto p = FindMkScenePart(path, *layout, begins[i], i ? layout->body_end : cut);
      ASSERT_TRUE(p.ok()) << p.status().ToString();
      parts.push_back(*p);
    }
    ASSERT_TRUE(CheckMkSceneParts(path, *layout, begins, parts).ok()) << cut;
    std::vector<SceneObject> got = ReadPart(path, *layout, parts[0], 0);
    for (SceneObject& o : ReadPart(path, *layout, parts[1], parts[0].objects)) got.push_back(std::move(o));
    ASSERT_EQ(got.size(), objects.size()) << cut;
    for (size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].id, i);
      EXPECT_EQ(got[i].name, objects[i].name);
      EXPECT_EQ(got[i].mesh.vertices, objects[i].mesh.vertices);
      EXPECT_EQ(got[i].mesh.triangles, objects[i].mesh.triangles);
    }
  }
  const uint64_t body = layout->body_end - layout->body_begin;
  for (uint64_t r : {3u, 5u, 17u}) {
    std::vector<uint64_t> begins;
    std::vector<MkScenePart> parts;
    uint64_t sum = 0;
    for (uint64_t q = 0; q < r; ++q) begins.push_back(layout->body_begin + body * q / r);
    for (uint64_t q = 0; q < r; ++q) {
      auto p = FindMkScenePart(path, *layout, begins[q], q + 1 < r ? begins[q + 1] : layout->body_end);
      ASSERT_TRUE(p.ok());
      parts.push_back(*p);
      sum += p->objects;
    }
    EXPECT_TRUE(CheckMkSceneParts(path, *layout, begins, parts).ok());
    EXPECT_EQ(sum, 6u);
  }
}

TEST_F(MkSceneFormatTest, ARecordForgedInsideANameIsCaughtByTheChain) {
  // A whole valid record (its checksum right) as the name of object 1: a resync inside the name accepts it,
  // and the parts then do not chain.
  const std::string inner = dir_ / "inner.mks";
  WriteTanker(inner, 1);
  const std::string bytes = Slurp(inner);
  const std::string forged = bytes.substr(16, bytes.size() - 16 - 24);
  const std::string path = dir_ / "scene.mks";
  std::vector<SceneObject> objects = Drain(MakeTankerSource(3, 5).get());
  objects[1].name = forged;
  {
    auto writer = MkSceneWriter::Create(path);
    ASSERT_TRUE(writer.ok());
    for (const SceneObject& o : objects) ASSERT_TRUE((*writer)->Write(o).ok());
    ASSERT_TRUE((*writer)->Finish().ok());
  }
  auto layout = ReadMkSceneLayout(path);
  ASSERT_TRUE(layout.ok());
  const uint64_t record0 = 24 + objects[0].name.size() + 24 * objects[0].mesh.vertex_count() +
                           12 * objects[0].mesh.triangle_count();
  const uint64_t cut = layout->body_begin + record0 + 8;  // the first byte of object 1's name
  const uint64_t record2 =
      layout->body_end - (24 + objects[2].name.size() + 24 * objects[2].mesh.vertex_count() +
                          12 * objects[2].mesh.triangle_count());
  // Two parts: the forged record checks out, but no record follows it, so the resync goes on to object 2.
  auto p0 = FindMkScenePart(path, *layout, layout->body_begin, cut);
  auto p1 = FindMkScenePart(path, *layout, cut, layout->body_end);
  ASSERT_TRUE(p0.ok() && p1.ok()) << p0.status().ToString() << p1.status().ToString();
  EXPECT_EQ(p0->objects, 2u);
  EXPECT_TRUE(p1->found);
  EXPECT_EQ(p1->begin, record2);
  EXPECT_TRUE(CheckMkSceneParts(path, *layout, {layout->body_begin, cut}, {*p0, *p1}).ok());
  // Three parts, the middle one ending inside the forged record: it is fooled, and the chain says so.
  const std::vector<uint64_t> begins = {layout->body_begin, cut, cut + 16};
  std::vector<MkScenePart> parts = {*p0};
  for (size_t i = 1; i < 3; ++i) {
    auto p = FindMkScenePart(path, *layout, begins[i], i == 1 ? begins[2] : layout->body_end);
    ASSERT_TRUE(p.ok());
    parts.push_back(*p);
  }
  EXPECT_EQ(parts[1].begin, cut);  // fooled
  const Status st = CheckMkSceneParts(path, *layout, begins, parts);
  EXPECT_EQ(st.code(), Status::Code::kCorruption);
  EXPECT_NE(st.message().find("do not chain"), std::string::npos) << st.ToString();
  EXPECT_NE(st.message().find(path), std::string::npos);
}

TEST_F(MkSceneFormatTest, DamageInAPartIsAnErrorNamingTheObjectOfTheFile) {
  const std::string path = dir_ / "scene.mks";
  WriteTanker(path, 8);
  auto layout = ReadMkSceneLayout(path);
  ASSERT_TRUE(layout.ok());
  const uint64_t cut = (layout->body_begin + layout->body_end) / 2;
  auto p1 = FindMkScenePart(path, *layout, cut, layout->body_end);
  auto p0 = FindMkScenePart(path, *layout, layout->body_begin, cut);
  ASSERT_TRUE(p0.ok() && p1.ok() && p1->found && p1->objects > 1);
  std::string bytes = Slurp(path);
  bytes[p1->end - 12] ^= 0x10;  // inside the last record's triangles: the walk still chains
  Spit(path, bytes);
  ASSERT_TRUE(CheckMkSceneParts(path, *layout, {layout->body_begin, cut}, {*p0, *p1}).ok());
  auto source = OpenMkScenePart(path, *layout, *p1, p0->objects, static_cast<ObjectId>(p0->objects));
  ASSERT_TRUE(source.ok());
  SceneObject o;
  Status st;
  for (;;) {
    auto more = (*source)->Next(&o);
    if (!more.ok()) {
      st = more.status();
      break;
    }
    ASSERT_TRUE(*more) << "damage not found";
  }
  EXPECT_EQ(st.code(), Status::Code::kCorruption);
  EXPECT_NE(st.message().find(path + ": object 7 "), std::string::npos) << st.ToString();
  // A damaged end record is refused before any part is read.
  bytes[bytes.size() - 10] ^= 1;
  Spit(path, bytes);
  EXPECT_EQ(ReadMkSceneLayout(path).status().code(), Status::Code::kCorruption);
}

}  // namespace
}  // namespace mktree
