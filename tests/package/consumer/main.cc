// A user's program, built against mktree's public headers and library only (tests/package/run.sh):
//   consumer STORE N
// STORE holds the grid scene run.sh writes: N^3 unit cubes, cube (i, j, k) at 2 * (i, j, k), object id
// (i * N + j) * N + k, named cube_i_j_k. Runs box and point queries through the public API and compares
// each answer with brute force over the grid; then builds the same grid from objects through the build
// API (STORE.api.mkt beside it) and checks that store the same way. Prints the mktree version it was
// compiled against.
#include <mktree/build.h>
#include <mktree/database.h>
#include <mktree/version.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

int failures = 0;

void Check(bool ok, const std::string& what) {
  if (!ok) {
    std::fprintf(stderr, "FAIL: %s\n", what.c_str());
    ++failures;
  }
}

// The ids of the grid's cubes whose boxes meet `q` (closed intervals).
std::vector<mktree::ObjectId> BruteForce(int n, const mktree::Box3d& q) {
  std::vector<mktree::ObjectId> ids;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      for (int k = 0; k < n; ++k) {
        const double lo[3] = {2.0 * i, 2.0 * j, 2.0 * k};
        bool meets = true;
        for (int a = 0; a < 3; ++a) meets = meets && lo[a] <= q.max[a] && q.min[a] <= lo[a] + 1.0;
        if (meets) ids.push_back(static_cast<mktree::ObjectId>((i * n + j) * n + k));
      }
    }
  }
  return ids;
}

std::string Join(const std::vector<mktree::ObjectId>& ids) {
  std::string s;
  for (mktree::ObjectId id : ids) s += (s.empty() ? "" : " ") + std::to_string(id);
  return s;
}

// The grid as objects: cube (i, j, k) as 8 corners and 12 triangles, named as run.sh names them.
std::vector<mktree::SceneObject> Grid(int n) {
  static const uint32_t kFaces[36] = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                      2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
  std::vector<mktree::SceneObject> objects;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      for (int k = 0; k < n; ++k) {
        mktree::SceneObject o;
        o.name = "cube_" + std::to_string(i) + "_" + std::to_string(j) + "_" + std::to_string(k);
        for (int c = 0; c < 8; ++c)
          o.mesh.vertices.insert(o.mesh.vertices.end(),
                                 {2.0 * i + (c & 1), 2.0 * j + ((c >> 1) & 1), 2.0 * k + ((c >> 2) & 1)});
        o.mesh.triangles.assign(kFaces, kFaces + 36);
        objects.push_back(std::move(o));
      }
    }
  }
  return objects;
}

// Box and point queries against brute force over the grid, and a name.
void CheckStore(const std::string& path, int n) {
  auto db = mktree::Database::Open(path, {.cache_pages = 64});
  if (!db.ok()) {
    Check(false, db.status().ToString());
    return;
  }
  Check((*db)->object_count() == static_cast<uint64_t>(n) * n * n, path + ": object_count");

  // A box within one corner, one across most leaves, and one that misses everything.
  const std::vector<mktree::Box3d> boxes = {{{1.5, 1.5, 1.5}, {4.5, 4.5, 4.5}},
                                            {{1.5, -1.0, 2.5}, {12.5, 4.5, 100.0}},
                                            {{0.2, 0.2, 1.2}, {0.8, 0.8, 1.8}}};
  for (const mktree::Box3d& box : boxes) {
    const std::vector<mktree::ObjectId> expected = BruteForce(n, box);
    for (mktree::QueryMode mode : {mktree::QueryMode::kAabb, mktree::QueryMode::kExact}) {
      mktree::QueryResult r;
      const mktree::Status st = (*db)->Run(mktree::Query::Box(box, mode), &r);
      Check(st.ok(), "box query: " + st.ToString());
      Check(r.hits == expected,
            "box query answered [" + Join(r.hits) + "], brute force [" + Join(expected) + "]");
    }
    std::printf("%s: box: %zu hits\n", path.c_str(), expected.size());
  }
  mktree::QueryResult r;
  Check((*db)->Run(mktree::Query::Point({2.5, 4.5, 6.5}), &r).ok(), "point query");
  const std::vector<mktree::ObjectId> point_expected = {static_cast<mktree::ObjectId>((1 * n + 2) * n + 3)};
  Check(r.hits == point_expected, "point query answered [" + Join(r.hits) + "]");
  auto name = (*db)->ObjectName(point_expected[0]);
  Check(name.ok() && *name == "cube_1_2_3", "ObjectName");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: consumer STORE N\n");
    return 2;
  }
  std::printf("mktree %s (%d.%d.%d)\n", MKTREE_VERSION_STRING, MKTREE_VERSION_MAJOR, MKTREE_VERSION_MINOR,
              MKTREE_VERSION_PATCH);
  const int n = std::atoi(argv[2]);
  const std::string store = argv[1];
  CheckStore(store, n);

  // The same grid through the build API.
  const std::string api_store = store + ".api.mkt";
  mktree::BuildOptions options;
  options.backend = mktree::BuildOptions::Backend::kPagedFile;
  options.block_size = 1024;
  options.blocks_per_page = 1;
  uint64_t progress_calls = 0;
  options.progress = [&](mktree::BuildStage, uint64_t, uint64_t) { ++progress_calls; };
  auto built = mktree::BuildFromObjects(Grid(n), api_store, options);
  Check(built.ok(), "BuildFromObjects: " + built.status().ToString());
  if (built.ok()) {
    Check(built->objects == static_cast<uint64_t>(n) * n * n && built->triangles == 12 * built->objects,
          "BuildFromObjects: counts");
    Check(progress_calls > 0, "BuildFromObjects: no progress");
    std::printf("built %s: %llu objects, %llu pages\n", api_store.c_str(),
                static_cast<unsigned long long>(built->objects),
                static_cast<unsigned long long>(built->pages));
    CheckStore(api_store, n);
  }
  auto bad = mktree::BuildFromFiles({store + ".missing.obj"}, api_store);
  Check(!bad.ok() && bad.status().code() == mktree::Status::Code::kNotFound, "BuildFromFiles: missing input");
  if (failures != 0) return 1;
  std::printf("ok\n");
  return 0;
}
