// Object records (docs/store_format.md, "Object record pages"): names, sources and attributes of any bytes
// go through ingest into the record pages of both backends and come back through Database::Object with the
// object's world box; ObjectGeometry gives the stored triangles in world coordinates; records cost counted
// page reads and open reads none of them, so a damaged record page fails that object's record only.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <vector>

#include "engine/ingest/store_builder.h"
#include "engine/scene/vector_scene_source.h"
#include "engine/store_format/store_file.h"
#include "mktree/database.h"
#include "storage/page_codec.h"
#include "store_format/store_test_util.h"
#include "store_format/stored_geometry.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::TempDir;

// Objects with a record of every kind: odd names (NUL, newline, tab, invalid UTF-8, empty, 1 MiB), two
// sources, attributes (none, a few, 10,000 on one object, empty and NUL-holding keys and values).
std::vector<SceneObject> RecordObjects(uint32_t n, uint32_t seed, const Vec3d& shift = {}) {
  std::vector<SceneObject> objects = testing::MakeObjects(n, seed);
  const std::vector<std::string> odd = {std::string("a\0b", 3),
                                        "line\nbreak",
                                        "tab\there",
                                        "\xff\xfe invalid \xc3",
                                        "",
                                        std::string(1 << 20, 'x'),
                                        "\xe6\x97\xa5 valid UTF-8"};
  for (size_t i = 0; i < odd.size(); ++i) objects[(i * 37 + 5) % n].name = odd[i];
  for (SceneObject& o : objects) {
    o.source = o.id < n / 2 ? "/data/first part.obj" : std::string("second\0.ifc", 11);
    if (o.id % 4 == 1) {
      o.attributes = {{"IfcType", "IfcWall"}, {"GlobalId", "2O2Fr$t4X7Zf8NOew3FLOH"}, {"", ""}};
      o.attributes.push_back({std::string("k\0ey", 4), std::string(300, '\n')});
    }
    for (size_t i = 0; i < o.mesh.vertices.size(); ++i) o.mesh.vertices[i] += shift[i % 3];
  }
  SceneObject& many = objects[n - 3];
  for (int i = 0; i < 10000; ++i)
    many.attributes.push_back({"key" + std::to_string(i), std::to_string(i * 7)});
  return objects;
}

Status BuildManyRecordPages(const std::vector<SceneObject>& objects, const std::string& path,
                            Backend backend) {
  std::vector<SceneOpener> in{[&objects](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(new VectorSceneSource(&objects, first));
  }};
  IngestOptions o;
  o.store.backend = backend;
  o.store.params.block_size = 1024;  // small pages: many record pages, the 1 MiB name spans ~1000
  o.store.params.blocks_per_page = 2;
  o.threads = 2;
  auto r = BuildStore(in, path, o);
  return r.ok() ? Status::Ok() : r.status();
}

class ObjectRecordTest : public ::testing::TestWithParam<Backend> {
 protected:
  TempDir dir_;
};

void ExpectRecords(const Database& db, const std::vector<SceneObject>& objects, const Vec3d& origin) {
  const std::vector<testing::StoredObject> stored = testing::StoredScene(objects, origin);
  for (const SceneObject& o : objects) {
    SCOPED_TRACE("object " + std::to_string(o.id));
    auto r = db.Object(o.id);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    EXPECT_EQ(r->id, o.id);
    ASSERT_EQ(r->name, o.name);
    EXPECT_EQ(r->source, o.source);
    ASSERT_EQ(r->attributes, o.attributes);
    const Box3f& b = stored[o.id].box;
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(r->box.min[i], origin[i] + b.min[i]);
      EXPECT_EQ(r->box.max[i], origin[i] + b.max[i]);
    }
    // The world box holds the input's vertices.
    const Box3d in = o.mesh.Bounds();
    for (int i = 0; i < 3; ++i) EXPECT_TRUE(r->box.min[i] <= in.min[i] && in.max[i] <= r->box.max[i]);
    if (o.id % 5 != 0) continue;
    auto g = db.ObjectGeometry(o.id);
    ASSERT_TRUE(g.ok()) << g.status().ToString();
    Mesh want = stored[o.id].mesh;
    for (size_t v = 0; v < want.vertices.size(); ++v) want.vertices[v] += origin[v % 3];
    EXPECT_EQ(g->vertices, want.vertices);
    EXPECT_EQ(g->triangles, o.mesh.triangles);
  }
}

TEST_P(ObjectRecordTest, AnyBytesRoundTripThroughIngest) {
  const std::string path = dir_.file("records.mkt");
  const std::vector<SceneObject> objects = RecordObjects(600, 51);
  ASSERT_TRUE(BuildManyRecordPages(objects, path, GetParam()).ok());
  auto db = Database::Open(path, {.cache_pages = 8});
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  ASSERT_EQ((*db)->object_count(), objects.size());
  ExpectRecords(**db, objects, ChooseStoreOrigin(objects[0].mesh.Bounds()));
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ((*r)->objects().sources,
            (std::vector<std::string>{"/data/first part.obj", objects.back().source}));
  EXPECT_GT((*r)->objects().record_directory.size(), (1u << 20) / 2048);  // the 1 MiB name spans pages
}

// Far from 0 (a UTM-like position): the world box and geometry carry the store's origin.
TEST_P(ObjectRecordTest, WorldBoxAndGeometryCarryTheOrigin) {
  const std::string path = dir_.file("far.mkt");
  const std::vector<SceneObject> objects = RecordObjects(120, 52, {5e5, 5e6, 100});
  ASSERT_TRUE(BuildManyRecordPages(objects, path, GetParam()).ok());
  auto db = Database::Open(path);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  const Vec3d origin = ChooseStoreOrigin(objects[0].mesh.Bounds());
  ASSERT_NE(origin.x, 0.0);
  ExpectRecords(**db, objects, origin);
}

TEST_P(ObjectRecordTest, IdsPastTheEndAreInvalidArguments) {
  const std::string path = dir_.file("ids.mkt");
  const std::vector<SceneObject> objects = RecordObjects(40, 53);
  ASSERT_TRUE(BuildManyRecordPages(objects, path, GetParam()).ok());
  auto db = Database::Open(path);
  ASSERT_TRUE(db.ok());
  for (ObjectId id : {ObjectId{40}, ObjectId{41}, ObjectId{UINT32_MAX}}) {
    EXPECT_EQ((*db)->Object(id).status().code(), Status::Code::kInvalidArgument);
    EXPECT_EQ((*db)->ObjectGeometry(id).status().code(), Status::Code::kInvalidArgument);
    EXPECT_EQ((*db)->ObjectName(id).status().code(), Status::Code::kInvalidArgument);
    EXPECT_NE((*db)->Object(id).status().message().find(path), std::string::npos);
  }
}

// A record is a counted read through the cache: a miss the first time, a hit the next.
TEST_P(ObjectRecordTest, RecordsAreCountedPageReads) {
  const std::string path = dir_.file("count.mkt");
  const std::vector<SceneObject> objects = RecordObjects(300, 54);
  ASSERT_TRUE(BuildManyRecordPages(objects, path, GetParam()).ok());
  auto db = Database::Open(path, {.cache_pages = 64});
  ASSERT_TRUE(db.ok());
  QueryStats s;
  ASSERT_TRUE((*db)->Object(10, &s).ok());
  EXPECT_EQ(s.pages_read, 1u);
  EXPECT_EQ(s.pages_touched, 1u);
  ASSERT_TRUE((*db)->Object(10, &s).ok());
  EXPECT_EQ(s.pages_read, 0u);
  EXPECT_EQ(s.cache_hits, 1u);
  // The object's leaf comes from its record (cached now), then the leaf's pages are read.
  (*db)->ClearCache();
  ASSERT_TRUE((*db)->ObjectGeometry(10, &s).ok());
  EXPECT_GE(s.pages_read, 2u);
  ASSERT_TRUE((*db)->ObjectGeometry(10, &s).ok());
  EXPECT_EQ(s.pages_read, 0u);
  EXPECT_GE(s.cache_hits, 2u);
}

// Open reads no record page: every record page damaged, the store still opens and answers queries; the
// record of an object fails, as a Corruption naming the store and its page, never a wrong name (and so does
// its geometry, whose leaf is in the record).
TEST_P(ObjectRecordTest, DamagedRecordPagesFailOnlyTheirRecords) {
  const std::string path = dir_.file("damaged.mkt");
  const std::vector<SceneObject> objects = RecordObjects(200, 55);
  ASSERT_TRUE(BuildManyRecordPages(objects, path, GetParam()).ok());
  uint64_t first_record_page = 0, record_pages = 0, mem_page = 0;
  std::vector<std::vector<uint8_t>> pages;
  {
    auto r = StoreReader::Open(path);
    ASSERT_TRUE(r.ok());
    first_record_page = (*r)->leaf_page_count();
    record_pages = (*r)->objects().record_directory.size();
    mem_page = (*r)->pages().page_bytes();
    for (uint64_t p = first_record_page; p < first_record_page + record_pages; ++p) {
      pages.emplace_back(mem_page);
      ASSERT_TRUE((*r)->pages().ReadPage(p, pages.back().data()).ok());
    }
  }
  auto before = Database::Open(path);
  ASSERT_TRUE(before.ok());
  QueryResult want;
  ASSERT_TRUE((*before)->Run(Query::Box((*before)->bounds()), &want).ok());
  before->reset();

  // Flip a byte in the middle of every record page, wherever the backend keeps it.
  std::vector<uint8_t> file;
  {
    std::ifstream f(path, std::ios::binary);
    file.assign(std::istreambuf_iterator<char>(f), {});
  }
  for (const auto& page : pages) {
    auto at = std::search(file.begin(), file.end(), page.begin(), page.end());
    ASSERT_NE(at, file.end());
    at[static_cast<std::ptrdiff_t>(mem_page / 2)] ^= 0x10;
  }
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(file.data()), static_cast<std::streamsize>(file.size()));
  }
  auto db = Database::Open(path);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  QueryResult got;
  ASSERT_TRUE((*db)->Run(Query::Box((*db)->bounds()), &got).ok());
  EXPECT_EQ(got.hits, want.hits);
  for (ObjectId id : {ObjectId{0}, ObjectId{77}, ObjectId{199}}) {
    // The geometry too: the object's leaf is in its record.
    const Status geometry = (*db)->ObjectGeometry(id).status();
    EXPECT_EQ(geometry.code(), Status::Code::kCorruption) << geometry.ToString();
    EXPECT_EQ(geometry.message().rfind(path + ": page ", 0), 0u) << geometry.message();
    auto r = (*db)->Object(id);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), Status::Code::kCorruption) << r.status().ToString();
    EXPECT_EQ(r.status().message().rfind(path + ": page ", 0), 0u) << r.status().message();
    EXPECT_NE(r.status().message().find("checksum mismatch"), std::string::npos) << r.status().message();
    EXPECT_FALSE((*db)->ObjectName(id).ok());
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, ObjectRecordTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

// A record page whose fields disagree with the directory, or whose payload is cut, behind a valid checksum
// (a checksum is not a MAC): Corruption naming the page.
TEST(ObjectRecordCraftedTest, ResealedRecordPagesWithWrongFieldsAreRefused) {
  TempDir dir;
  const std::string path = dir.file("crafted.mkt");
  const std::vector<SceneObject> objects = RecordObjects(200, 56);
  ASSERT_TRUE(BuildManyRecordPages(objects, path, Backend::kPagedFile).ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok());
  const uint64_t mem_page = (*r)->pages().page_bytes(), first = (*r)->leaf_page_count();
  const std::vector<uint32_t> dir_ids = (*r)->objects().record_directory;
  r->reset();
  const std::vector<uint8_t> good = [&] {
    std::ifstream f(path, std::ios::binary);
    return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), {});
  }();
  // Page 2 of the records: (1 + first + 2) * mem_page in the paged file.
  const uint64_t offset = (1 + first + 2) * mem_page;
  const ObjectId in_page = dir_ids[2];
  auto edit = [&](const std::function<void(PageHeader*, uint8_t*)>& change,
                  uint32_t magic = kRecordPageMagic) {
    std::vector<uint8_t> f = good;
    uint8_t* p = f.data() + offset;
    auto h = CheckPage(p, mem_page, true, "x", 0, kRecordPageMagic);
    ASSERT_TRUE(h.ok()) << h.status().ToString();
    change(&*h, p);
    SealPage(*h, p, mem_page, magic);
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(f.data()), static_cast<std::streamsize>(f.size()));
  };
  const std::vector<std::pair<std::string, std::function<void(PageHeader*, uint8_t*)>>> cases = {
      {"starts at object", [](PageHeader* h, uint8_t*) { ++h->leaf_index; }},
      {"where the directory makes it", [](PageHeader* h, uint8_t*) { h->page_count = 2; }},
      {"object record", [](PageHeader* h, uint8_t*) { h->payload_bytes -= 7; }},
      {"records where the directory says", [](PageHeader*, uint8_t* p) { ++p[kPageHeaderBytes]; }},
      {"object record", [](PageHeader*, uint8_t* p) { p[kPageHeaderBytes + 8] ^= 0x40; }},
  };
  for (size_t c = 0; c <= cases.size(); ++c) {
    // The last case: a leaf page where a record page should be.
    const std::string words =
        c < cases.size() ? cases[c].first : "bad page magic (not an object record page)";
    SCOPED_TRACE(words);
    if (c < cases.size()) {
      edit(cases[c].second);
    } else {
      edit([](PageHeader*, uint8_t*) {}, kPageMagic);
    }
    auto db = Database::Open(path);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    auto rec = (*db)->Object(in_page);
    ASSERT_FALSE(rec.ok());
    EXPECT_EQ(rec.status().code(), Status::Code::kCorruption);
    EXPECT_EQ(rec.status().message().rfind(path + ": page " + std::to_string(first + 2), 0), 0u)
        << rec.status().message();
    EXPECT_NE(rec.status().message().find(words), std::string::npos) << rec.status().message();
    EXPECT_TRUE((*db)->Object(0).ok());
  }
}

// The tool: query --names, clash --names and info --object print names escaped on one line.
TEST(ObjectRecordCliTest, NamesAndRecordsInTheTool) {
  TempDir dir;
  const std::string path = dir.file("cli.mkt");
  std::vector<SceneObject> objects = RecordObjects(60, 57);
  objects[0].name = "tab\there\nnewline \"q\"";
  ASSERT_TRUE(BuildManyRecordPages(objects, path, Backend::kPagedFile).ok());
  auto db = Database::Open(path);
  ASSERT_TRUE(db.ok());
  QueryResult all;
  ASSERT_TRUE((*db)->Run(Query::Box((*db)->bounds()), &all).ok());
  ASSERT_EQ(all.hits.size(), objects.size());

  auto q = testing::RunMktree("query " + path + " --names --box -1e9,-1e9,-1e9,1e9,1e9,1e9", dir.path());
  ASSERT_EQ(q.code, 0) << q.err;
  EXPECT_NE(q.out.find("\"names\": [\"tab\\u0009here\\u000anewline \\\"q\\\"\", "), std::string::npos)
      << q.out;
  EXPECT_EQ(std::count(q.out.begin(), q.out.end(), '\n'), 1);
  // Invalid UTF-8 shows as U+FFFD; NUL as \u0000.
  EXPECT_NE(q.out.find("\"\xef\xbf\xbd\xef\xbf\xbd invalid \xef\xbf\xbd\""), std::string::npos);
  EXPECT_NE(q.out.find("\"a\\u0000b\""), std::string::npos);
  auto bad = testing::RunMktree("query " + path + " --names --count --point 0,0,0", dir.path());
  EXPECT_NE(bad.code, 0);

  auto info = testing::RunMktree("info " + path + " --object 1 --json", dir.path());
  ASSERT_EQ(info.code, 0) << info.err;
  EXPECT_NE(info.out.find("\"attributes\": [{\"key\": \"IfcType\", \"value\": \"IfcWall\"}"),
            std::string::npos)
      << info.out;
  EXPECT_NE(info.out.find("\"source\": \"/data/first part.obj\""), std::string::npos) << info.out;
  auto text = testing::RunMktree("info " + path + " --object 0", dir.path());
  ASSERT_EQ(text.code, 0) << text.err;
  EXPECT_NE(text.out.find("name         tab\\u0009here\\u000anewline \\\"q\\\"\n"), std::string::npos)
      << text.out;
  auto past = testing::RunMktree("info " + path + " --object 60", dir.path());
  EXPECT_NE(past.code, 0);
  EXPECT_NE(past.err.find("out of range"), std::string::npos) << past.err;
  auto summary = testing::RunMktree("info " + path, dir.path());
  EXPECT_NE(summary.out.find("bounds       ("), std::string::npos) << summary.out;

  auto clash = testing::RunMktree("clash " + path + " --names --max-pairs 5", dir.path());
  ASSERT_EQ(clash.code, 0) << clash.err;
  auto plain = testing::RunMktree("clash " + path + " --max-pairs 5", dir.path());
  ASSERT_EQ(plain.code, 0) << plain.err;
  if (!plain.out.empty()) {
    EXPECT_NE(clash.out.find("\"name_a\": \""), std::string::npos) << clash.out;
  }
  // The same pairs, names beside them.
  EXPECT_EQ(std::count(clash.out.begin(), clash.out.end(), '\n'),
            std::count(plain.out.begin(), plain.out.end(), '\n'));
}

}  // namespace
}  // namespace mktree
