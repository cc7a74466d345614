// The parallel OBJ reader against the reader it replaced (obj_reference_reader.h): the same objects (ids,
// names, vertices bit for bit, triangles, source, attributes) and the same first error, message and line,
// on 0, 1, 2 and 4 parsing threads and chunks from one line to the whole file; the numbers parser against
// std::from_chars on hard and random cases.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "engine/scene/obj_chunk.h"
#include "engine/scene/obj_reader.h"
#include "scene/obj_reference_reader.h"
#include "scene/scene_test_util.h"

namespace mktree {
namespace {

struct Outcome {
  std::vector<SceneObject> objects;
  Status status;  // the error that ended the stream, or Ok
};

Outcome ReadEverything(Result<std::unique_ptr<SceneSource>> src) {
  Outcome out;
  if (!src.ok()) {
    out.status = src.status();
    return out;
  }
  while (true) {
    SceneObject o;
    auto more = (*src)->Next(&o);
    if (!more.ok()) {
      out.status = more.status();
      // Sticky: a second call fails the same way.
      auto again = (*src)->Next(&o);
      EXPECT_FALSE(again.ok());
      if (!again.ok()) {
        EXPECT_EQ(again.status().message(), more.status().message());
      }
      return out;
    }
    if (!*more) return out;
    out.objects.push_back(std::move(o));
  }
}

bool SameBits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

void ExpectSame(const Outcome& want, const Outcome& got, const std::string& what) {
  EXPECT_EQ(got.status.code(), want.status.code()) << what << ": " << got.status.ToString();
  EXPECT_EQ(got.status.message(), want.status.message()) << what;
  ASSERT_EQ(got.objects.size(), want.objects.size()) << what;
  for (size_t i = 0; i < want.objects.size(); ++i) {
    const SceneObject& w = want.objects[i];
    const SceneObject& g = got.objects[i];
    ASSERT_EQ(g.id, w.id) << what << " object " << i;
    ASSERT_EQ(g.name, w.name) << what << " object " << i;
    ASSERT_EQ(g.source, w.source) << what << " object " << i;
    ASSERT_EQ(g.attributes, w.attributes) << what << " object " << i;
    ASSERT_TRUE(SameBits(g.mesh.vertices, w.mesh.vertices)) << what << " object " << i;
    ASSERT_EQ(g.mesh.triangles, w.mesh.triangles) << what << " object " << i;
  }
}

// Every configuration of the parallel reader gives what the reference gives on `path`.
void ExpectMatchesReference(const std::string& path, ObjectId first_id = 0, bool expect_ok = true,
                            std::vector<size_t> chunks = {1, 7, 64, 4096, size_t{1} << 20}) {
  const Outcome want = ReadEverything(reference::OpenObjFile(path, first_id));
  if (expect_ok) {
    ASSERT_TRUE(want.status.ok()) << want.status.ToString();
  } else {
    ASSERT_FALSE(want.status.ok()) << path;
  }
  for (int threads : {0, 1, 2, 4}) {
    for (size_t chunk : chunks) {
      ObjReadOptions options;
      options.threads = threads;
      options.chunk_bytes = chunk;
      ExpectSame(want, ReadEverything(OpenObjFile(path, first_id, options)),
                 path + " threads " + std::to_string(threads) + " chunk " + std::to_string(chunk));
      if (::testing::Test::HasFatalFailure()) return;
    }
  }
  ExpectSame(want, ReadEverything(OpenObjFile(path, first_id)), path + " default options");
}

// Numbers: short and long decimals, exponents, signs, zeros, subnormals.
std::string RandomNumber(std::mt19937_64& rng) {
  static const char* const kHard[] = {"0",
                                      "-0",
                                      "+0",
                                      "0.0",
                                      "-0.0e-5",
                                      "1e-310",
                                      "4.9e-324",
                                      "2.4703282292062328e-324",
                                      "1e-400",
                                      "-1e-400",
                                      "+1e-400",
                                      "2.2250738585072011e-308",
                                      "2.2250738585072014e-308",
                                      "9007199254740993",
                                      "0.1",
                                      "0.30000000000000004",
                                      "1.00000000000000011102230246251565404236316680908203125",
                                      "123456789012345678901234567890",
                                      ".5",
                                      "-.5",
                                      "5.",
                                      "1E5",
                                      "1e+5",
                                      "2.1267647932558654e37",
                                      "-21267647932558654000000000000000000000",
                                      "0000001.5",
                                      "6.02214076e23",
                                      "1.7976931348623157e-300"};
  std::uniform_int_distribution<int> pick(0, 9);
  const int k = pick(rng);
  if (k == 0) return kHard[rng() % (sizeof(kHard) / sizeof(kHard[0]))];
  char buf[64];
  std::uniform_real_distribution<double> coord(-1e4, 1e4);
  if (k < 5) {
    std::snprintf(buf, sizeof buf, "%.*f", static_cast<int>(rng() % 8), coord(rng));
  } else if (k < 8) {
    std::snprintf(buf, sizeof buf, "%.17g", coord(rng));
  } else {
    std::snprintf(buf, sizeof buf, "%.*e", static_cast<int>(rng() % 20),
                  coord(rng) * std::pow(10.0, (int)(rng() % 60) - 30));
  }
  return buf;
}

// A valid OBJ file exercising objects, groups, materials, every face form, relative and absolute indices,
// comments, blank lines, CRLF, continuations and the ignored directives.
std::string RandomObj(uint64_t seed, int objects, bool with_object_lines) {
  std::mt19937_64 rng(seed);
  std::string s = "# generated\nmtllib scene.mtl\n";
  uint64_t v = 0, vt = 0, vn = 0;
  auto eol = [&] { return rng() % 10 == 0 ? "\r\n" : "\n"; };
  for (int o = 0; o < objects; ++o) {
    if (with_object_lines) {
      if (rng() % 8 != 0) s += "o part " + std::to_string(o) + (rng() % 5 == 0 ? "  \t" : "") + eol();
      if (rng() % 3 == 0) s += "g grp" + std::to_string(rng() % 4) + (rng() % 2 ? " shared" : "") + eol();
    } else {
      s += "g grp" + std::to_string(o % 5) + (rng() % 2 ? " extra" : "") + eol();  // names repeat
    }
    if (rng() % 3 == 0) s += "usemtl mat" + std::to_string(rng() % 3) + eol();
    const int nv = 3 + static_cast<int>(rng() % 9);
    for (int i = 0; i < nv; ++i) {
      s += "v " + RandomNumber(rng) + (rng() % 6 == 0 ? " \\" + std::string(eol()) + " " : " ") +
           RandomNumber(rng) + "\t" + RandomNumber(rng);
      if (rng() % 10 == 0) s += " 1";  // w
      s += eol();
      ++v;
      if (rng() % 4 == 0) s += "vt 0.5 0.5" + std::string(eol()), ++vt;
      if (rng() % 5 == 0) s += "vn 0 0 1" + std::string(eol()), ++vn;
      if (rng() % 12 == 0) s += "# comment\n\n";
    }
    const int nf = static_cast<int>(rng() % 6);  // some objects have no faces
    for (int f = 0; f < nf; ++f) {
      const int corners = 3 + static_cast<int>(rng() % 3);
      s += "f";
      const int form = static_cast<int>(rng() % 4);
      for (int c = 0; c < corners; ++c) {
        const uint64_t back = 1 + rng() % static_cast<uint64_t>(nv);  // within this object
        const bool rel = rng() % 2 == 0;
        const uint64_t far = rng() % 16 == 0 ? 1 + rng() % v : 0;  // sometimes an earlier object's vertex
        const uint64_t abs_index = far != 0 ? far : v - back + 1;
        // std::string("-") + ..., not "-" + ...: gcc 12 warns falsely (-Wrestrict) on the latter's insert.
        std::string idx =
            rel ? std::string("-") + std::to_string(v - abs_index + 1) : std::to_string(abs_index);
        if (rng() % 20 == 0 && !rel) idx = "+" + idx;
        std::string t = vt > 0 ? std::to_string(1 + rng() % vt) : "";
        std::string n = vn > 0 ? std::to_string(1 + rng() % vn) : "";
        if (form == 1 && !t.empty()) idx += "/" + t;
        if (form == 2 && !n.empty()) idx += "//" + n;
        if (form == 3 && !t.empty() && !n.empty()) idx += "/" + t + "/" + n;
        s += " " + idx;
      }
      s += eol();
      if (rng() % 10 == 0) s += "s 1\n";
    }
  }
  return s;
}

std::string Write(const std::string& content, const std::string& name) { return WriteTemp(content, name); }

TEST(ObjParallelTest, GeneratedFilesMatchTheReference) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    ExpectMatchesReference(Write(RandomObj(seed, 60, true), std::string("o") + std::to_string(seed) + ".obj"),
                           7);
    if (::testing::Test::HasFatalFailure()) return;
    ExpectMatchesReference(
        Write(RandomObj(seed, 40, false), std::string("g") + std::to_string(seed) + ".obj"));
    if (::testing::Test::HasFatalFailure()) return;
  }
}

TEST(ObjParallelTest, LargerFileMatchesTheReference) {
  ExpectMatchesReference(Write(RandomObj(42, 3000, true), "large.obj"), 0, true, {97, 4096, size_t{1} << 18});
}

// Objects past the reader's direct re-indexing window (16384 vertices after the `o` line) and faces that
// reach back into earlier objects.
TEST(ObjParallelTest, BigObjectsMatchTheReference) {
  std::string s;
  std::mt19937_64 rng(11);
  int total = 0;
  for (int o = 0; o < 3; ++o) {
    const int n = o == 1 ? 20000 : 100;
    s += "o big" + std::to_string(o) + "\n";
    for (int i = 0; i < n; ++i) s += "v " + std::to_string(i) + " " + std::to_string(o) + " 0.5\n";
    total += n;
    for (int f = 0; f < n / 2; ++f) {
      s += "f";
      for (int c = 0; c < 3; ++c) {
        const int back = 1 + static_cast<int>(rng() % (f % 7 == 0 ? total : n));
        s += rng() % 2 ? std::string(" -") + std::to_string(back)
                       : std::string(" ") + std::to_string(total - back + 1);
      }
      s += "\n";
    }
  }
  ExpectMatchesReference(Write(s, "big.obj"), 0, true, {4096, size_t{1} << 18});
}

TEST(ObjParallelTest, EmptyAndTinyFiles) {
  ExpectMatchesReference(Write("", "empty.obj"));
  ExpectMatchesReference(Write("\n", "newline.obj"));
  ExpectMatchesReference(Write("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3", "nonl.obj"));
  ExpectMatchesReference(Write("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\n3\n", "cont.obj"));
  ExpectMatchesReference(Write("v 0 0 0\r\nv 1 0 0\\\r\n\r\nv 0 1 0\r\nf 1 2 3\r\n", "crlfcont.obj"));
}

// Every line of a valid file broken in turn (in the 2nd and later chunks with small chunks): the same
// error, message and line, after the same objects.
TEST(ObjParallelTest, ErrorsInLaterChunksNameTheSameLine) {
  const std::string base = RandomObj(5, 30, true);
  std::vector<size_t> starts;
  for (size_t i = 0; i < base.size(); ++i) {
    if (i == 0 || base[i - 1] == '\n') starts.push_back(i);
  }
  static const char* const kBreakers[] = {"v 1 2\n",
                                          "v 1 2 3 4 5 6 7 8\n",
                                          "v 1 x 3\n",
                                          "v 1e400 0 0\n",
                                          "v nan 0 0\n",
                                          "v 1 2 inf\n",
                                          "v 0x1p3 0 0\n",
                                          "v 1e39 0 0\n",
                                          "f 1 2\n",
                                          "f 0 1 2\n",
                                          "f 1 2 999999\n",
                                          "f 1/0 2 3\n",
                                          "f 1/1/1/1 2 3\n",
                                          "f 1// 2 3\n",
                                          "f -99999 -1 -2\n",
                                          "f 1/99999 2 3\n",
                                          "f 1//99999 2 3\n",
                                          "f 999/x 1 2\n",
                                          "f 1 2 3/1/x\n",
                                          "f 1 2 3 x\n",
                                          "curv 0 1\n",
                                          "bogus 1\n",
                                          "v 1 2 \\\n",
                                          "f 1 9999 2/x 3\n",
                                          "v 1e-400 0 1.0e-500x\n"};
  std::mt19937_64 rng(9);
  for (int trial = 0; trial < 50; ++trial) {  // from 25 on, the broken line ends the file unterminated
    const size_t line = starts[starts.size() / 3 + rng() % (starts.size() * 2 / 3)];
    const char* breaker = kBreakers[trial % (sizeof(kBreakers) / sizeof(kBreakers[0]))];
    std::string content = base.substr(0, line) + breaker + base.substr(line);
    if (trial >= 25)
      content = base.substr(0, line) + std::string(breaker).substr(0, std::strlen(breaker) - 1);
    const std::string path = Write(content, "broken" + std::to_string(trial) + ".obj");
    const Outcome want = ReadEverything(reference::OpenObjFile(path));
    ASSERT_FALSE(want.status.ok()) << breaker;
    ExpectMatchesReference(path, 0, /*expect_ok=*/false);
    if (::testing::Test::HasFatalFailure()) return;
  }
}

TEST(ObjParallelTest, RealFilesMatchTheReference) {
  for (const char* f : {"buildings/duplex.obj", "buildings/steel_mini_project.obj", "city/denhaag_01.obj"}) {
    const std::string path = std::string(MKTREE_SHARED_DATA) + "/" + f;
    if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " missing";
    const Outcome want = ReadEverything(reference::OpenObjFile(path));
    ASSERT_TRUE(want.status.ok()) << want.status.ToString();
    for (int threads : {0, 2, 4}) {
      for (size_t chunk : {size_t{4096}, size_t{1} << 16, size_t{1} << 20}) {
        ObjReadOptions options;
        options.threads = threads;
        options.chunk_bytes = chunk;
        ExpectSame(want, ReadEverything(OpenObjFile(path, 0, options)),
                   path + " threads " + std::to_string(threads) + " chunk " + std::to_string(chunk));
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
  }
}

// The OBJ fuzz corpus (hostile and odd inputs): the same objects or the same error, chunks of 7 and 4096
// bytes on 0 and 2 threads.
TEST(ObjParallelTest, FuzzCorpusMatchesTheReference) {
  const std::filesystem::path dir = std::filesystem::path(MKTREE_TESTS_DIR) / "fuzz" / "corpus" / "obj";
  size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    // Same extension: the readers are told the name, and errors quote it.
    const std::string path = entry.path().string();
    const Outcome want = ReadEverything(reference::OpenObjFile(path));
    for (int threads : {0, 2}) {
      for (size_t chunk : {size_t{7}, size_t{4096}}) {
        ObjReadOptions options;
        options.threads = threads;
        options.chunk_bytes = chunk;
        ExpectSame(want, ReadEverything(OpenObjFile(path, 0, options)),
                   path + " threads " + std::to_string(threads) + " chunk " + std::to_string(chunk));
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
    ++files;
  }
  EXPECT_GT(files, 100u);
}

// `count` one-triangle objects, one after another.
std::string ManyTriangles(int count) {
  std::string s;
  for (int i = 0; i < count; ++i) {
    s += "o t" + std::to_string(i) + "\nv " + std::to_string(i) + " 0 0\nv " + std::to_string(i) +
         ".5 1 0\nv " + std::to_string(i) + " 0 1.25\nf -3 -2 -1\n";
  }
  return s;
}

// A file truncated (or shrunk) while being read: an IOError naming the file and a line at or before the
// first missing byte, after a prefix of the right objects; never SIGBUS. The cut happens between two calls
// of Next() on the calling thread, so which objects come first is fixed; with parsing threads, chunks
// already read ahead (at most threads + 4 of 4 KiB, each with its boundary's lookahead) may still be applied,
// which the checks allow.
TEST(ObjParallelTest, FileTruncatedWhileReadingIsAnError) {
  const std::string content = ManyTriangles(20000);  // about 1 MB, hundreds of 4 KiB chunks
  const Outcome want = ReadEverything(reference::OpenObjFile(Write(content, "cut.obj")));
  ASSERT_TRUE(want.status.ok()) << want.status.ToString();
  for (int threads : {0, 1, 2}) {
    for (size_t cut : {size_t{0}, content.size() / 2 + 3, content.size() - 1}) {
      const std::string what = "threads " + std::to_string(threads) + " cut " + std::to_string(cut);
      const std::string path = Write(content, "cut.obj");
      ObjReadOptions options;
      options.threads = threads;
      options.chunk_bytes = 4096;
      auto src = OpenObjFile(path, 0, options);
      ASSERT_TRUE(src.ok()) << src.status().ToString();
      Outcome got;
      SceneObject o;
      auto more = (*src)->Next(&o);
      ASSERT_TRUE(more.ok() && *more) << what;
      got.objects.push_back(std::move(o));
      ASSERT_EQ(::truncate(path.c_str(), static_cast<off_t>(cut)), 0) << what;
      while (true) {
        more = (*src)->Next(&o);
        if (!more.ok() || !*more) break;
        got.objects.push_back(std::move(o));
      }
      ASSERT_FALSE(more.ok()) << what << ": the truncated file read to its end";
      EXPECT_EQ(more.status().code(), Status::Code::kIOError) << what;
      const std::string& msg = more.status().message();
      ASSERT_EQ(msg.rfind(path + ":", 0), 0u) << what << ": " << msg;
      EXPECT_NE(msg.find("shrank while being read"), std::string::npos) << what << ": " << msg;
      const uint64_t line = std::stoull(msg.substr(path.size() + 1));
      // Lines wholly before the first missing byte (of those the file still had when chunks were read).
      const uint64_t lines_kept =
          std::count(content.begin(), content.begin() + std::max(cut, size_t{32768}), '\n');
      EXPECT_GE(line, 1u) << what;
      EXPECT_LE(line, lines_kept + 1) << what << ": " << msg;
      // Each object is 5 lines; those returned all end before the reported line.
      EXPECT_LE(got.objects.size() * 5, line - 1) << what;
      ASSERT_LE(got.objects.size(), want.objects.size()) << what;
      Outcome prefix;
      prefix.objects.assign(want.objects.begin(), want.objects.begin() + got.objects.size());
      ExpectSame(prefix, got, what);
      // Sticky.
      auto again = (*src)->Next(&o);
      ASSERT_FALSE(again.ok());
      EXPECT_EQ(again.status().message(), msg);
    }
  }
}

TEST(ObjParallelTest, SourceAndAttributes) {
  const std::string path = Write(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
      "g walls  outer\nusemtl  brick \no a\nf 1 2 3\ng roof\nf 1 2 3\n"
      "o b\nusemtl\nf 1 2 3\n"  // no material line in force: groups only
      "o c\nusemtl tile\ng\nf 1 2 3\nusemtl brick\nf 1 2 3\nusemtl tile\nf 1 2 3\n"
      "o empty\ng unused\no d\nf 1 2 3\n",
      "attrs.obj");
  auto got = ReadEverything(OpenObjFile(path));
  ASSERT_TRUE(got.status.ok()) << got.status.ToString();
  ASSERT_EQ(got.objects.size(), 4u);
  using A = std::vector<ObjectAttribute>;
  EXPECT_EQ(got.objects[0].attributes,
            (A{{"group", "walls"}, {"group", "outer"}, {"material", "brick"}, {"group", "roof"}}));
  EXPECT_EQ(got.objects[1].attributes, (A{{"group", "roof"}}));
  EXPECT_EQ(got.objects[2].attributes, (A{{"material", "tile"}, {"material", "brick"}}));
  EXPECT_EQ(got.objects[3].attributes, (A{{"group", "unused"}, {"material", "tile"}}));
  for (const SceneObject& o : got.objects) EXPECT_EQ(o.source, path);
  ExpectMatchesReference(path);
}

TEST(ObjParallelTest, GroupsStartObjectsAndAreTheirAttributes) {
  const std::string path = Write("v 0 0 0\nv 1 0 0\nv 0 1 0\ng a b\nf 1 2 3\ng c\nf 1 2 3\n", "gonly.obj");
  auto got = ReadEverything(OpenObjFile(path));
  ASSERT_TRUE(got.status.ok()) << got.status.ToString();
  ASSERT_EQ(got.objects.size(), 2u);
  EXPECT_EQ(got.objects[0].name, "a b");
  EXPECT_EQ(got.objects[0].attributes, (std::vector<ObjectAttribute>{{"group", "a"}, {"group", "b"}}));
  EXPECT_EQ(got.objects[1].attributes, (std::vector<ObjectAttribute>{{"group", "c"}}));
}

// ParseObjCoordinate (fast_float) against the reference (std::from_chars): the same value bit for bit, or
// the same refusal with the same reason.
void ExpectSameNumber(const std::string& tok) {
  double want = 0, got = 0;
  std::string why_want, why_got;
  const bool ok_want = reference::ParseCoordinate(tok, &want, &why_want);
  const bool ok_got = ParseObjCoordinate(tok.data(), tok.data() + tok.size(), &got, &why_got);
  ASSERT_EQ(ok_got, ok_want) << "'" << tok << "': " << why_got << " / " << why_want;
  if (ok_want) {
    ASSERT_EQ(std::memcmp(&got, &want, sizeof got), 0) << "'" << tok << "'";
  } else {
    ASSERT_EQ(why_got, why_want) << "'" << tok << "'";
  }
}

TEST(ObjParallelTest, NumbersParseAsBefore) {
  for (const char* t : {"0",
                        "-0",
                        "+0",
                        "-0.0",
                        "0e999",
                        "0e-999",
                        "-0e-999",
                        "1e400",
                        "-1e400",
                        "1e-400",
                        "-1e-400",
                        "+-1e-400",
                        "1e-324",
                        "2.4703282292062327e-324",
                        "2.4703282292062328e-324",
                        "4.9406564584124654e-324",
                        "1e-310",
                        "1.7976931348623157e308",
                        "1.7976931348623158e308",
                        "1.7976931348623159e308",
                        "2.1267647932558654e37",
                        "2.1267647932558655e37",
                        "1e38",
                        "nan",
                        "-nan",
                        "NaN",
                        "nan(123)",
                        "nan(",
                        "inf",
                        "-inf",
                        "+inf",
                        "Infinity",
                        "INF",
                        "infinit",
                        "0x1p3",
                        "0X10",
                        "1e",
                        "1e+",
                        "1e-",
                        "1.",
                        ".5",
                        "-.5",
                        ".",
                        "-",
                        "+",
                        "++1",
                        "+-1",
                        "-+1",
                        "1,5",
                        "1.5.5",
                        "1e5e5",
                        "1_000",
                        "00.5",
                        "9007199254740993",
                        "0.1e-5",
                        "5e-324",
                        "1.0000000000000002",
                        "123456789012345678901234567890123456789e-30",
                        "0."
                        "000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
                        "000000000000000000000"
                        "000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
                        "0000000000000000000000"
                        "000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
                        "0000000000000000000000"
                        "0000000000001",
                        "1e-2147483649",
                        "1e2147483648",
                        "1e99999999999999999999"}) {
    ExpectSameNumber(t);
  }
  std::mt19937_64 rng(3);
  const std::string alphabet = "0123456789.eE+-ninfax";
  for (int i = 0; i < 200000; ++i) {
    std::string t;
    if (i % 2 == 0) {
      t = RandomNumber(rng);
    } else {
      const int len = 1 + static_cast<int>(rng() % 12);
      for (int k = 0; k < len; ++k) t += alphabet[rng() % alphabet.size()];
    }
    ExpectSameNumber(t);
    if (::testing::Test::HasFatalFailure()) return;
  }
}

}  // namespace
}  // namespace mktree
