// A user's program, built against mktree's public headers and library only (tests/package/run.sh):
//   consumer STORE N
// STORE holds the grid scene run.sh writes: N^3 unit cubes, cube (i, j, k) at 2 * (i, j, k), object id
// (i * N + j) * N + k, named cube_i_j_k. Runs box and point queries through the public API and compares
// each answer with brute force over the grid; prints the mktree version it was compiled against.
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

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: consumer STORE N\n");
    return 2;
  }
  std::printf("mktree %s (%d.%d.%d)\n", MKTREE_VERSION_STRING, MKTREE_VERSION_MAJOR, MKTREE_VERSION_MINOR,
              MKTREE_VERSION_PATCH);
  const int n = std::atoi(argv[2]);
  auto db = mktree::Database::Open(argv[1], {.cache_pages = 64});
  if (!db.ok()) {
    std::fprintf(stderr, "FAIL: %s\n", db.status().ToString().c_str());
    return 1;
  }
  Check((*db)->object_count() == static_cast<uint64_t>(n) * n * n, "object_count");

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
    std::printf("box: %zu hits\n", expected.size());
  }
  mktree::QueryResult r;
  Check((*db)->Run(mktree::Query::Point({2.5, 4.5, 6.5}), &r).ok(), "point query");
  const std::vector<mktree::ObjectId> point_expected = {static_cast<mktree::ObjectId>((1 * n + 2) * n + 3)};
  Check(r.hits == point_expected, "point query answered [" + Join(r.hits) + "]");
  auto name = (*db)->ObjectName(point_expected[0]);
  Check(name.ok() && *name == "cube_1_2_3", "ObjectName");
  if (failures != 0) return 1;
  std::printf("ok\n");
  return 0;
}
