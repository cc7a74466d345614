// Object names are bytes: any of them (NUL, newline, quotes, backslashes, invalid UTF-8, empty, 1 MiB long)
// round-trips through both backends, and a store's size and the memory to build or open it follow the
// names' total length (HDF5 stores padded every name to the longest one).
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>

#include "engine/store_format/store_file.h"
#include "store_format/store_test_util.h"
#include "tool_runner.h"

// GCC defines __SANITIZE_*__, Clang answers __has_feature.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define MKTREE_UNDER_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define MKTREE_UNDER_SANITIZER 1
#endif
#endif
#ifndef MKTREE_UNDER_SANITIZER
#define MKTREE_UNDER_SANITIZER 0
#endif

namespace mktree {
namespace {

using testing::BuiltStore;
using testing::TempDir;

class ObjectNamesTest : public ::testing::TestWithParam<Backend> {
 protected:
  Status Write(const std::string& path, const std::vector<SceneObject>& objects) {
    StoreOptions o;
    o.backend = GetParam();
    auto w = StoreWriter::Create(path, o);
    if (!w.ok()) return w.status();
    BuiltStore built;
    MKTREE_RETURN_IF_ERROR(testing::BuildTestStore(objects, o.codec, o.params, &(*w)->pages(), &built));
    for (const SceneObject& ob : objects)
      MKTREE_RETURN_IF_ERROR((*w)->AppendObject(ob.id, built.object_leaf[ob.id], ob.name));
    return (*w)->Commit(built.tree, "{}");
  }
  TempDir dir_;
};

std::vector<std::string> OddNames() {
  return {std::string("a\0b", 3),
          std::string("\0", 1),
          std::string("trailing\0\0", 10),
          "line\nbreak",
          "carriage\rreturn",
          "quote\"d 'single'",
          "back\\slash\\",
          "\xff\xfe\x80 invalid UTF-8 \xc3",
          "",
          "tab\there",
          std::string(1 << 20, 'x'),
          "\xe6\x97\xa5\xe6\x9c\xac valid UTF-8"};
}

TEST_P(ObjectNamesTest, AnyBytesRoundTrip) {
  const std::string path = dir_.file("names.mkt");
  std::vector<SceneObject> objects = testing::MakeObjects(400, 41);
  const std::vector<std::string> odd = OddNames();
  for (size_t i = 0; i < odd.size(); ++i) objects[i * 31 % objects.size()].name = odd[i];
  ASSERT_TRUE(Write(path, objects).ok());
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ((*r)->object_count(), objects.size());
  for (const SceneObject& o : objects) {
    auto name = (*r)->ObjectName(o.id);
    ASSERT_TRUE(name.ok());
    ASSERT_EQ(*name, o.name) << "object " << o.id;
  }
}

// One 1 MiB name among 2,000 objects: the store holds it once (it was 2,000 times in HDF5's padded table).
TEST_P(ObjectNamesTest, OneLongNameCostsItsOwnSize) {
  const std::string path = dir_.file("long.mkt"), plain = dir_.file("plain.mkt");
  std::vector<SceneObject> objects = testing::MakeObjects(2000, 42, /*with_big=*/false);
  ASSERT_TRUE(Write(plain, objects).ok());
  const uint64_t replaced = objects[1234].name.size();
  objects[1234].name = std::string(1 << 20, 'n');
  ASSERT_TRUE(Write(path, objects).ok());
  const uint64_t with = std::filesystem::file_size(path), without = std::filesystem::file_size(plain);
  EXPECT_GE(with, without + (1 << 20) - replaced);
  EXPECT_LE(with, without + (1 << 20) + 64 * 1024) << "the long name costs more than itself";
  auto r = StoreReader::Open(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(*(*r)->ObjectName(1234), objects[1234].name);
  EXPECT_EQ(*(*r)->ObjectName(1235), objects[1235].name);
}

// Building and opening that store fits in a few times its size of memory: in a child with an address-space
// limit, well below the 2 GB the padded table needed.
TEST_P(ObjectNamesTest, OneLongNameNeedsNoMoreMemoryThanItsSize) {
#if MKTREE_UNDER_SANITIZER
  GTEST_SKIP() << "an address-space limit cannot apply under a sanitizer's shadow memory";
#endif
  const std::string path = dir_.file("long.mkt");
  std::vector<SceneObject> objects = testing::MakeObjects(2000, 43, /*with_big=*/false);
  objects[10].name = std::string(1 << 20, 'n');
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    // The current mapping (libraries, heap, the objects above) plus 256 MiB.
    long pages = 0;
    std::ifstream("/proc/self/statm") >> pages;
    const rlim_t limit = static_cast<rlim_t>(pages) * ::sysconf(_SC_PAGESIZE) + (rlim_t{256} << 20);
    const rlimit r{limit, limit};
    ::setrlimit(RLIMIT_AS, &r);
    Status st = Write(path, objects);
    if (!st.ok()) std::_Exit(2);
    auto opened = StoreReader::Open(path);
    std::_Exit(opened.ok() && *(*opened)->ObjectName(10) == objects[10].name ? 0 : 3);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status) << " (out of memory?)";
  EXPECT_EQ(WEXITSTATUS(status), 0) << (WEXITSTATUS(status) == 2 ? "build failed" : "open failed");
}

INSTANTIATE_TEST_SUITE_P(Backends, ObjectNamesTest, ::testing::Values(Backend::kHdf5, Backend::kPagedFile),
                         [](const auto& info) { return std::string(BackendName(info.param)); });

// The report's case, through the tool: an OBJ object named "a\0b" builds a store that opens, and whose
// name `info` and `query` can read; a failed build of it would have replaced the previous store.
TEST(ObjectNamesCliTest, NulInAnObjNameBuildsAStoreThatOpens) {
  TempDir dir;
  const std::string obj = dir.file("nul.obj"), store = dir.file("s.mkt");
  {
    std::ofstream f(obj, std::ios::binary);
    const std::string text("o a\0b\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 37);
    f.write(text.data(), static_cast<std::streamsize>(text.size()));
  }
  for (const char* backend : {"hdf5", "pagefile"}) {
    SCOPED_TRACE(backend);
    auto build = testing::RunMktree("build " + obj + " -q -o " + store + " --backend " + backend, dir.path());
    ASSERT_EQ(build.code, 0) << build.err;
    auto info = testing::RunMktree("info " + store, dir.path());
    EXPECT_EQ(info.code, 0) << info.err;
    auto query = testing::RunMktree("query " + store + " --point 0.2,0.2,0", dir.path());
    EXPECT_EQ(query.code, 0) << query.err;
    EXPECT_NE(query.out.find("\"hits\": [0]"), std::string::npos) << query.out;
    auto r = StoreReader::Open(store);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    EXPECT_EQ(*(*r)->ObjectName(0), std::string("a\0b", 3));
  }
}

}  // namespace
}  // namespace mktree
