// BCF: the archive of a hand-made run and of a real store's run validates against buildingSMART's XSD
// files (tests/data/bcf, 2.1 and 3.0) with xmllint; the same run gives a byte-identical archive and the
// same GUIDs (UUID v5 of the group's key, checked against known vectors); the reader gets back every
// topic field the writer put in; the camera sees the whole group's box; names are escaped; errors leave
// nothing behind.
#include <gtest/gtest.h>
#include <png.h>
#include <sys/stat.h>

#include <cmath>
#include <set>

#include "engine/report/bcf_reader.h"
#include "engine/report/bcf_writer.h"
#include "engine/report/group_snapshot.h"
#include "engine/report/report_text.h"
#include "engine/report/sha1.h"
#include "engine/report/uuid_v5.h"
#include "report/report_fixtures.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::ProgramDir;

constexpr int64_t kFixedTime = 1767225600;  // 2026-01-01T00:00:00Z

BcfOptions Fixed(BcfVersion v) {
  BcfOptions o;
  o.version = v;
  o.creation_time = kFixedTime;
  return o;
}

std::string Hex(const std::array<uint8_t, 20>& h) {
  std::string s;
  char b[3];
  for (uint8_t v : h) std::snprintf(b, sizeof b, "%02x", v), s += b;
  return s;
}

TEST(BcfGuids, Sha1KnownVectors) {
  EXPECT_EQ(Hex(Sha1("")), "da39a3ee5e6b4b0d3255bfef95601890afd80709");
  EXPECT_EQ(Hex(Sha1("abc")), "a9993e364706816aba3e25717850c26c9cd0d89d");
  EXPECT_EQ(Hex(Sha1("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq")),
            "84983e441c3bd26ebaae4aa1f95129e5e54670f1");
  EXPECT_EQ(Hex(Sha1(std::string(1000000, 'a'))), "34aa973cd4c4daa4f61eeb2bdbad27316534016f");
  for (size_t n = 50; n < 70; ++n) EXPECT_EQ(Sha1(std::string(n, 'x')).size(), 20u);  // padding edges
  EXPECT_EQ(Hex(Sha1(std::string(55, 'a'))), "c1c8bbdc22796e28c0e15163d20899b65621d65a");
  EXPECT_EQ(Hex(Sha1(std::string(64, 'a'))), "0098ba824b5c16427bd7a1122a5a442a25ec644d");
}

TEST(BcfGuids, UuidV5KnownVectors) {
  // Python: uuid.uuid5(uuid.NAMESPACE_DNS, "python.org"), uuid.uuid5(uuid.NAMESPACE_URL,
  // "http://python.org/").
  EXPECT_EQ(UuidV5("6ba7b810-9dad-11d1-80b4-00c04fd430c8", "python.org"),
            "886313e1-3b8a-5372-9b90-0c9aee199e5d");
  EXPECT_EQ(UuidV5(kUuidUrlNamespace, "http://python.org/"), "4c565f0d-3f5a-5890-b41b-20cf47701c5e");
  const std::string g = BcfTopicGuid("mep|a|b");
  EXPECT_EQ(g, BcfTopicGuid("mep|a|b"));
  EXPECT_NE(g, BcfTopicGuid("mep|a|c"));
  EXPECT_NE(g, BcfViewpointGuid("mep|a|b"));
  EXPECT_EQ(g[14], '5');
}

// Validates every XML entry of the archive against the official schema of its version; the entries that
// fail, with xmllint's messages in *log.
int SchemaFailures(const std::string& archive, BcfVersion v, std::string* log) {
  const std::string xsd = std::string(MKTREE_TESTS_DIR) + "/data/bcf/" + BcfVersionId(v) + "/";
  const auto entries = ZipEntries(archive);
  const fs::path out = ProgramDir() / ("unpacked_" + fs::path(archive).stem().string());
  int checked = 0, failed = 0;
  for (const auto& [name, bytes] : entries) {
    std::string schema;
    if (name == "bcf.version") schema = "version.xsd";
    if (name == "project.bcfp") schema = "project.xsd";
    if (name == "extensions.xml") schema = "extensions.xsd";
    if (name.ends_with("/markup.bcf")) schema = "markup.xsd";
    if (name.ends_with(".bcfv")) schema = "visinfo.xsd";
    if (schema.empty()) {
      EXPECT_TRUE(name.ends_with("/snapshot.png")) << name;
      continue;
    }
    const fs::path file = out / name;
    fs::create_directories(file.parent_path());
    std::ofstream(file, std::ios::binary) << bytes;
    const std::string cmd = "xmllint --noout --schema '" + xsd + schema + "' '" + file.string() + "' 2>&1";
    FILE* p = popen(cmd.c_str(), "r");
    char buf[512];
    while (p && fgets(buf, sizeof buf, p)) *log += buf;
    failed += (p ? pclose(p) : -1) != 0;
    ++checked;
  }
  EXPECT_GE(checked, 2);
  if (v == BcfVersion::k3_0) {
    EXPECT_TRUE(entries.count("extensions.xml"));
  }
  return failed;
}

void ExpectValid(const std::string& archive, BcfVersion v) {
  if (!HasProgram("xmllint")) GTEST_SKIP() << "xmllint is not installed (Debian libxml2-utils)";
  std::string log;
  EXPECT_EQ(SchemaFailures(archive, v, &log), 0) << log;
}

// The validation does catch what the schema forbids: BCF 2.1 allows a field of view of 45 to 60 degrees.
TEST(BcfSchema, CatchesAFieldOfViewOutOfRange) {
  if (!HasProgram("xmllint")) GTEST_SKIP() << "xmllint is not installed (Debian libxml2-utils)";
  BcfOptions o;
  o.creation_time = 0;
  o.field_of_view = 75;
  const std::string path = ProgramDir().file("wide.bcf");
  ASSERT_TRUE(WriteBcf(HandRun(), path, o).ok());
  std::string log;
  EXPECT_EQ(SchemaFailures(path, BcfVersion::k2_1, &log), 3) << log;
  EXPECT_NE(log.find("FieldOfView"), std::string::npos) << log;
}

class BcfVersions : public ::testing::TestWithParam<BcfVersion> {};

TEST_P(BcfVersions, HandRunValidatesAndReadsBack) {
  const ClashRun run = HandRun();
  BcfOptions o = Fixed(GetParam());
  const std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 1, 2, 3};
  int calls = 0;
  o.snapshot = [&](const ClashGroup&) -> Result<std::vector<uint8_t>> {
    ++calls;
    return png;
  };
  o.max_snapshots = 2;
  const std::string path = ProgramDir().file(std::string("hand_") + BcfVersionId(GetParam()) + ".bcf");
  auto w = WriteBcf(run, path, o);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  EXPECT_EQ(w->topics, 3u);
  EXPECT_EQ(w->snapshots, 2u);
  EXPECT_EQ(calls, 2);  // each snapshot made once, however often libzip asks for the entry's size
  EXPECT_EQ(w->bytes, fs::file_size(path));
  ExpectValid(path, GetParam());

  auto back = ReadBcf(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->version, BcfVersionId(GetParam()));
  EXPECT_EQ(back->project_name, "duplex.mkt");
  ASSERT_EQ(back->topics.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const BcfTopic want = BcfTopicOf(run.groups[i], o, i < 2);
    const BcfTopic& got = back->topics[i];
    EXPECT_EQ(got.guid, BcfTopicGuid(run.groups[i].key));
    EXPECT_EQ(got.guid, want.guid);
    EXPECT_EQ(got.type, "Clash");
    EXPECT_EQ(got.status, i == 2 ? "Closed" : "Open");
    EXPECT_EQ(got.title, want.title);
    EXPECT_EQ(got.description, want.description);
    EXPECT_EQ(got.labels, want.labels);
    EXPECT_EQ(got.files, std::vector<std::string>{"duplex.ifc"});
    EXPECT_EQ(got.creation_date, "2026-01-01T00:00:00Z");
    EXPECT_EQ(got.author, "mktree");
    ASSERT_EQ(got.viewpoints.size(), 1u);
    const BcfViewpoint& gv = got.viewpoints[0];
    const BcfViewpoint& wv = want.viewpoints[0];
    EXPECT_EQ(gv.guid, BcfViewpointGuid(run.groups[i].key));
    EXPECT_EQ(gv.has_snapshot, i < 2);
    EXPECT_EQ(gv.selected, wv.selected);
    ASSERT_EQ(gv.colours.size(), wv.colours.size());
    for (size_t c = 0; c < gv.colours.size(); ++c) {
      EXPECT_EQ(gv.colours[c].colour, wv.colours[c].colour);
      EXPECT_EQ(gv.colours[c].components, wv.colours[c].components);
    }
    for (int k = 0; k < 3; ++k) {
      EXPECT_DOUBLE_EQ(gv.camera.position[k], wv.camera.position[k]);
      EXPECT_DOUBLE_EQ(gv.camera.direction[k], wv.camera.direction[k]);
      EXPECT_DOUBLE_EQ(gv.camera.up[k], wv.camera.up[k]);
    }
    EXPECT_DOUBLE_EQ(gv.camera.field_of_view, 60);
  }
  // The first group: the beam and both ducts selected by GlobalId, all red (hard); the name came back
  // whole through its escaping.
  const BcfTopic& t0 = back->topics[0];
  EXPECT_EQ(t0.viewpoints[0].selected,
            (std::vector<std::string>{"2O2Fr$t4X7Zf8NOew3FLOH", "1hOSvn6df7F8_7GcBWlR72",
                                      "0M6o6c5d10Dvr_2QzXZ9fY"}));
  ASSERT_EQ(t0.viewpoints[0].colours.size(), 1u);
  EXPECT_EQ(t0.viewpoints[0].colours[0].colour, "E11919");
  EXPECT_NE(t0.description.find("'Beam <B-12> & \"main\" 'east'' (IfcBeam, 2O2Fr$t4X7Zf8NOew3FLOH)"),
            std::string::npos)
      << t0.description;
  EXPECT_NE(t0.description.find("depth 0.04"), std::string::npos);
  EXPECT_NE(t0.description.find("Duct D-2 \xc3\xa9t\xc3\xa9"), std::string::npos);
  // Objects without GlobalIds are named by their AuthoringToolId; the touch is orange.
  EXPECT_EQ(back->topics[1].viewpoints[0].selected, (std::vector<std::string>{"wall-north", "slab-1"}));
  EXPECT_EQ(back->topics[1].viewpoints[0].colours[0].colour, "FA8200");
  EXPECT_EQ(back->topics[2].viewpoints[0].colours[0].colour, "EBC800");
  EXPECT_NE(back->topics[2].description.find("gap 0.03"), std::string::npos);
}

TEST_P(BcfVersions, SameRunGivesTheSameArchive) {
  const ClashRun run = HandRun();
  const std::string a = ProgramDir().file("same_a.bcf"), b = ProgramDir().file("same_b.bcf");
  ASSERT_TRUE(WriteBcf(run, a, Fixed(GetParam())).ok());
  ASSERT_TRUE(WriteBcf(run, b, Fixed(GetParam())).ok());
  EXPECT_EQ(ReadFileBytes(a), ReadFileBytes(b));
  // Another time and author: other bytes, the same GUIDs (a re-export updates the topics).
  BcfOptions later = Fixed(GetParam());
  later.creation_time += 86400 * 7;
  later.author = "coordinator@example.org";
  ASSERT_TRUE(WriteBcf(run, b, later).ok());
  EXPECT_NE(ReadFileBytes(a), ReadFileBytes(b));
  auto ra = ReadBcf(a), rb = ReadBcf(b);
  ASSERT_TRUE(ra.ok() && rb.ok());
  ASSERT_EQ(ra->topics.size(), rb->topics.size());
  for (size_t i = 0; i < ra->topics.size(); ++i) {
    EXPECT_EQ(ra->topics[i].guid, rb->topics[i].guid);
    EXPECT_EQ(ra->topics[i].viewpoints[0].guid, rb->topics[i].viewpoints[0].guid);
  }
  EXPECT_EQ(rb->topics[0].author, "coordinator@example.org");
  // Reordered groups keep their GUIDs: they follow the keys, not the positions.
  ClashRun reordered = run;
  std::reverse(reordered.groups.begin(), reordered.groups.end());
  ASSERT_TRUE(WriteBcf(reordered, b, Fixed(GetParam())).ok());
  rb = ReadBcf(b);
  ASSERT_TRUE(rb.ok());
  EXPECT_EQ(rb->topics[0].guid, ra->topics[2].guid);
  EXPECT_EQ(rb->topics[2].guid, ra->topics[0].guid);
}

// Without a creation time, SOURCE_DATE_EPOCH fixes it (the reproducible-builds convention).
TEST(BcfDates, SourceDateEpoch) {
  const ClashRun run = HandRun();
  const std::string a = ProgramDir().file("epoch_a.bcf"), b = ProgramDir().file("epoch_b.bcf");
  ::setenv("SOURCE_DATE_EPOCH", "1767225600", 1);
  ASSERT_TRUE(WriteBcf(run, a, BcfOptions{}).ok());
  ASSERT_TRUE(WriteBcf(run, b, BcfOptions{}).ok());
  ::unsetenv("SOURCE_DATE_EPOCH");
  EXPECT_EQ(ReadFileBytes(a), ReadFileBytes(b));
  auto r = ReadBcf(a);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->topics.at(0).creation_date, "2026-01-01T00:00:00Z");
  EXPECT_EQ(BcfDateTime(0), "1970-01-01T00:00:00Z");
}

// Blank names, tests and options, control characters and bytes that are not UTF-8 still give valid XML
// (replaced by U+FFFD), and the reader returns what was written.
TEST_P(BcfVersions, HostileTextStillValidates) {
  ClashRun run = HandRun();
  run.store = "/";
  ClashGroup& g = run.groups[1];
  g.title = "  ";
  g.test = "";
  auto a = std::make_shared<ObjectIdentity>(*g.members[0].a);
  auto b = std::make_shared<ObjectIdentity>(*g.members[0].b);
  a->name =
      "\x01"
      "bell\x07 and \xff\xfe bytes ]]> <!-- -->";
  b->name = " ";
  b->stable = "";
  a->source = "dir/";
  g.members[0].a = a;
  g.members[0].b = b;
  BcfOptions o = Fixed(GetParam());
  o.author = " ";
  o.open_status = "";
  const std::string path = ProgramDir().file(std::string("hostile_") + BcfVersionId(GetParam()) + ".bcf");
  auto w = WriteBcf(run, path, o);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  ExpectValid(path, GetParam());
  auto back = ReadBcf(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  const BcfTopic& t = back->topics.at(1);
  EXPECT_EQ(t.title, "Clash group " + g.key);
  EXPECT_EQ(t.author, "mktree");
  EXPECT_EQ(t.status, "Open");
  EXPECT_NE(t.description.find("\xef\xbf\xbd"
                               "bell\xef\xbf\xbd and \xef\xbf\xbd\xef\xbf\xbd bytes ]]> <!-- -->"),
            std::string::npos)
      << t.description;
  EXPECT_EQ(t.viewpoints.at(0).selected.size(), 1u);  // the blank object has nothing to be named by
  EXPECT_EQ(back->project_name, "mktree clash run");
}

INSTANTIATE_TEST_SUITE_P(Versions, BcfVersions, ::testing::Values(BcfVersion::k2_1, BcfVersion::k3_0),
                         [](const auto& info) { return info.param == BcfVersion::k2_1 ? "v2_1" : "v3_0"; });

// Every corner of the group's box lies inside the camera's view (vertical and horizontal field).
TEST(BcfCamera, FramesTheWholeBox) {
  for (const Box3d& box : {BoxOf(0, 0, 2.5, 6, 0.4, 3.1), BoxOf(-100, 20, 0, -99.9, 20.1, 0.1),
                           BoxOf(1000, 2000, 5, 1000, 2000, 5), BoxOf(0, 0, 0, 50, 2, 2)}) {
    for (double aspect : {4.0 / 3, 1.0, 0.5}) {
      const BcfCamera c = BcfCameraFraming(box, 60, aspect);
      const Vec3d& d = c.direction;
      const Vec3d& u = c.up;
      EXPECT_NEAR(d.x * d.x + d.y * d.y + d.z * d.z, 1, 1e-12);
      EXPECT_NEAR(u.x * u.x + u.y * u.y + u.z * u.z, 1, 1e-12);
      EXPECT_NEAR(d.x * u.x + d.y * u.y + d.z * u.z, 0, 1e-12);
      EXPECT_GT(u.z, 0);
      EXPECT_LT(d.z, 0);  // looks down
      const Vec3d r{d.y * u.z - d.z * u.y, d.z * u.x - d.x * u.z, d.x * u.y - d.y * u.x};
      const double tan_v = std::tan(30 * M_PI / 180), tan_h = tan_v * aspect;
      for (int corner = 0; corner < 8; ++corner) {
        const Vec3d p{corner & 1 ? box.max[0] : box.min[0], corner & 2 ? box.max[1] : box.min[1],
                      corner & 4 ? box.max[2] : box.min[2]};
        const Vec3d q{p.x - c.position.x, p.y - c.position.y, p.z - c.position.z};
        const double along = q.x * d.x + q.y * d.y + q.z * d.z;
        ASSERT_GT(along, 0);
        EXPECT_LE(std::abs(q.x * u.x + q.y * u.y + q.z * u.z) / along, tan_v);
        EXPECT_LE(std::abs(q.x * r.x + q.y * r.y + q.z * r.z) / along, tan_h);
      }
    }
  }
}

TEST(BcfErrors, UnwritablePathLeavesNothing) {
  const ClashRun run = HandRun();
  const std::string missing_dir = ProgramDir().file("no_such_dir") + "/out.bcf";
  auto w = WriteBcf(run, missing_dir, Fixed(BcfVersion::k2_1));
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find(missing_dir), std::string::npos) << w.status().message();
  EXPECT_FALSE(fs::exists(ProgramDir().file("no_such_dir")));

  if (::geteuid() != 0) {  // root writes into read-only folders
    const fs::path ro = ProgramDir() / "read_only";
    fs::create_directories(ro);
    fs::permissions(ro, fs::perms::owner_read | fs::perms::owner_exec);
    auto r = WriteBcf(run, (ro / "out.bcf").string(), Fixed(BcfVersion::k2_1));
    fs::permissions(ro, fs::perms::owner_all);
    EXPECT_FALSE(r.ok());
    EXPECT_TRUE(fs::is_empty(ro));
  }
}

TEST(BcfErrors, FailingSnapshotLeavesTheOldArchive) {
  const ClashRun run = HandRun();
  const fs::path dir = ProgramDir() / "failing";
  fs::create_directories(dir);
  const std::string path = (dir / "out.bcf").string();
  ASSERT_TRUE(WriteBcf(run, path, Fixed(BcfVersion::k2_1)).ok());
  const std::string before = ReadFileBytes(path);
  BcfOptions o = Fixed(BcfVersion::k3_0);
  int calls = 0;
  o.snapshot = [&](const ClashGroup& g) -> Result<std::vector<uint8_t>> {
    if (++calls == 2) return Status::IOError("store.mkt: page 7: checksum mismatch (group " + g.key + ")");
    return std::vector<uint8_t>{1, 2, 3};
  };
  auto w = WriteBcf(run, path, o);
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find("checksum mismatch"), std::string::npos) << w.status().message();
  EXPECT_EQ(calls, 2);  // stopped at the failure
  EXPECT_EQ(ReadFileBytes(path), before);
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    ++files;
    EXPECT_EQ(e.path().filename(), "out.bcf");
  }
  EXPECT_EQ(files, 1u);
}

TEST(BcfErrors, KeysMustBeUniqueAndPresent) {
  ClashRun run = HandRun();
  run.groups[2].key = run.groups[0].key;
  const std::string path = ProgramDir().file("dup.bcf");
  auto w = WriteBcf(run, path, Fixed(BcfVersion::k2_1));
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find("two groups have the key"), std::string::npos);
  run.groups[2].key.clear();
  w = WriteBcf(run, path, Fixed(BcfVersion::k2_1));
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find("group 3 has no key"), std::string::npos);
  EXPECT_FALSE(fs::exists(path));
}

TEST(BcfReader, RefusesWhatIsNotBcf) {
  const std::string text = ProgramDir().file("not.bcf");
  std::ofstream(text) << "hello";
  auto r = ReadBcf(text);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(text), std::string::npos);
  // A zip without bcf.version.
  const std::string empty = ProgramDir().file("empty.bcf");
  ASSERT_TRUE(WriteBcf(ClashRun{}, empty, Fixed(BcfVersion::k2_1)).ok());
  auto ok = ReadBcf(empty);
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  EXPECT_TRUE(ok->topics.empty());
}

// A real store: the duplex's self-clash pairs, a group each, with snapshots rendered from the store.
TEST(BcfStore, DuplexWithSnapshotsValidates) {
  auto sr = DuplexRun(ProgramDir(), 6);
  if (!sr) GTEST_SKIP() << "../shared/data/buildings/duplex.obj missing";
  ASSERT_EQ(sr->run.groups.size(), 6u);
  for (BcfVersion v : {BcfVersion::k2_1, BcfVersion::k3_0}) {
    BcfOptions o = Fixed(v);
    GroupSnapshotOptions so;
    so.width = 640;
    so.height = 480;
    o.snapshot = StoreSnapshotSource(*sr->reader, so);
    o.max_snapshots = 3;
    const std::string path = ProgramDir().file(std::string("duplex_") + BcfVersionId(v) + ".bcf");
    auto w = WriteBcf(sr->run, path, o);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    EXPECT_EQ(w->snapshots, 3u);
    ExpectValid(path, v);
    auto back = ReadBcf(path);
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    ASSERT_EQ(back->topics.size(), 6u);
    const auto entries = ZipEntries(path);
    for (size_t i = 0; i < 6; ++i) {
      const BcfTopic& t = back->topics[i];
      EXPECT_EQ(t.title, sr->run.groups[i].title);
      EXPECT_EQ(t.viewpoints[0].has_snapshot, i < 3);
      EXPECT_EQ(t.viewpoints[0].selected.size(), 2u);
      if (i >= 3) continue;
      // The snapshot is a PNG of the asked size with the worst class's colour in it.
      const std::string& bytes = entries.at(t.guid + "/snapshot.png");
      png_image img{};
      img.version = PNG_IMAGE_VERSION;
      ASSERT_TRUE(png_image_begin_read_from_memory(&img, bytes.data(), bytes.size()));
      img.format = PNG_FORMAT_RGB;
      std::vector<uint8_t> rgb(PNG_IMAGE_SIZE(img));
      ASSERT_TRUE(png_image_finish_read(&img, nullptr, rgb.data(), 0, nullptr));
      EXPECT_EQ(img.width, 640u);
      EXPECT_EQ(img.height, 480u);
      const ClashClass c = sr->run.groups[i].worst;
      size_t coloured = 0;
      for (size_t p = 0; p + 2 < rgb.size(); p += 3) {
        const int r = rgb[p], g = rgb[p + 1], b = rgb[p + 2];
        if (c == ClashClass::kHard) coloured += r > 170 && g < 90 && b < 90;
        if (c == ClashClass::kTouch) coloured += r > 200 && g > 90 && g < 170 && b < 60;
        if (c == ClashClass::kClearance) coloured += r > 190 && g > 160 && b < 60;
      }
      EXPECT_GT(coloured, 50u) << "group " << i << " (" << ClashClassName(c) << ") shows no "
                               << ClashClassName(c) << " colour";
    }
  }
}

// A snapshot of a group whose objects are not the store's is refused, naming the store.
TEST(BcfStore, SnapshotOfForeignObjectsIsRefused) {
  auto sr = DuplexRun(ProgramDir(), 1);
  if (!sr) GTEST_SKIP() << "../shared/data/buildings/duplex.obj missing";
  ClashGroup g = sr->run.groups.at(0);
  auto foreign = std::make_shared<ObjectIdentity>(*g.members[0].b);
  foreign->id = g.members[0].pair.b = static_cast<ObjectId>(sr->reader->object_count() + 5);
  g.members[0].b = foreign;
  auto png = RenderGroupSnapshot(*sr->reader, g, {});
  ASSERT_FALSE(png.ok());
  EXPECT_NE(png.status().message().find(sr->store), std::string::npos) << png.status().message();
  GroupSnapshotOptions big;
  big.width = 1600;
  EXPECT_FALSE(RenderGroupSnapshot(*sr->reader, sr->run.groups[0], big).ok());  // BCF's 1500 px
}

}  // namespace
}  // namespace mktree
