// narrow_bench: the narrow phase (Separate) on every candidate pair of a scene, with the per-object bound
// as the plain AABB (3 directions), an 18-DOP (9) and the 26-DOP (13, the default), and with the
// brute-force / hierarchy switch moved. Candidate pairs are the pairs whose AABBs, grown by C, meet (what
// a broad phase hands over). Reports per setting: pairs rejected by the bound, triangle tests, point-in-
// solid tests, narrow-phase seconds; and the meeting pairs' depth classes (T = 2 mm).
// Workloads: the tanker (generator API, seed 1) and the files named.
// Usage: narrow_bench [--tanker N] [--clearance C] [FILE...]
//   default: --tanker 20000, ../shared/data/buildings/steel_mini_project.obj, C = 0 and C = 0.05.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/geometry/mesh_separation.h"
#include "engine/scene/scene_source.h"

namespace mktree {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct Scene {
  std::string name;
  std::deque<Mesh> meshes;  // deque: ClashShape keeps a reference, so the meshes must not move
};

bool ReadAll(SceneSource* src, Scene* scene) {
  SceneObject o;
  for (;;) {
    auto more = src->Next(&o);
    if (!more.ok()) {
      std::fprintf(stderr, "error: %s\n", more.status().message().c_str());
      return false;
    }
    if (!*more) return true;
    const Status v = ValidateClashMesh(o.mesh);
    if (!v.ok()) {
      std::fprintf(stderr, "error: %s object %u: %s\n", scene->name.c_str(), o.id, v.message().c_str());
      return false;
    }
    scene->meshes.push_back(std::move(o.mesh));
  }
}

struct PairId {
  uint32_t a, b;
};

// Pairs whose boxes grown by c meet: sweep along x.
std::vector<PairId> CandidatePairs(const std::vector<Box3d>& boxes, double c) {
  std::vector<uint32_t> order(boxes.size());
  for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](uint32_t x, uint32_t y) { return boxes[x].min[0] < boxes[y].min[0]; });
  std::vector<PairId> pairs;
  for (size_t i = 0; i < order.size(); ++i) {
    const Box3d& a = boxes[order[i]];
    if (a.empty()) continue;
    for (size_t j = i + 1; j < order.size(); ++j) {
      const Box3d& b = boxes[order[j]];
      if (b.min[0] > a.max[0] + c) break;
      if (b.empty() || b.min[1] > a.max[1] + c || a.min[1] > b.max[1] + c || b.min[2] > a.max[2] + c ||
          a.min[2] > b.max[2] + c)
        continue;
      pairs.push_back({std::min(order[i], order[j]), std::max(order[i], order[j])});
    }
  }
  std::sort(pairs.begin(), pairs.end(),
            [](PairId x, PairId y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
  return pairs;
}

void Run(const Scene& scene, const std::vector<double>& clearances) {
  uint64_t triangles = 0;
  for (const Mesh& m : scene.meshes) triangles += m.triangle_count();
  auto t0 = Clock::now();
  std::vector<ClashShape> shapes;
  shapes.reserve(scene.meshes.size());
  size_t bytes = 0, solids = 0;
  for (const Mesh& m : scene.meshes) {
    shapes.emplace_back(m);
    bytes += shapes.back().MemoryBytes();
    solids += shapes.back().solid();
  }
  const double build_s = Since(t0);
  std::vector<Box3d> boxes;
  for (const ClashShape& s : shapes) boxes.push_back(s.bounds());
  std::printf("\n## %s: %zu objects (%zu solids), %llu triangles; ClashShape build %.3f s, %.1f MiB\n",
              scene.name.c_str(), shapes.size(), solids, static_cast<unsigned long long>(triangles), build_s,
              bytes / 1048576.0);
  struct Setting {
    const char* name;
    SeparateOptions options;
  };
  std::vector<Setting> settings = {
      {"AABB", {kAabbDirections, kBruteForceTriangles}},
      {"18-DOP", {kDop18Directions, kBruteForceTriangles}},
      {"26-DOP", {kKdopDirections, kBruteForceTriangles}},
      {"26-DOP, hierarchy always", {kKdopDirections, 0}},
      {"26-DOP, brute <= 128", {kKdopDirections, 128}},
      {"26-DOP, depth_lower to T", {kKdopDirections, kBruteForceTriangles, 0.002}}};
  for (double c : clearances) {
    t0 = Clock::now();
    const std::vector<PairId> pairs = CandidatePairs(boxes, c);
    std::printf("C = %g: %zu candidate pairs (AABBs grown by C meet; sweep %.3f s)\n", c, pairs.size(),
                Since(t0));
    std::printf("  %-26s %12s %12s %14s %12s %9s %9s %9s %9s\n", "bound", "bound rejects", "tri tests",
                "in-solid tests", "seconds", "meet", "inside", "clearance", "mismatch");
    std::vector<Separation> reference;
    for (const Setting& s : settings) {
      NarrowStats st;
      uint64_t meet = 0, inside = 0, near = 0, mismatch = 0;
      std::vector<Separation> out(pairs.size());
      t0 = Clock::now();
      for (size_t i = 0; i < pairs.size(); ++i)
        out[i] = Separate(shapes[pairs[i].a], shapes[pairs[i].b], c, &st, s.options);
      const double secs = Since(t0);
      for (size_t i = 0; i < pairs.size(); ++i) {
        const Separation& r = out[i];
        meet += r.meeting == Meeting::kSurfacesMeet;
        inside += r.meeting == Meeting::kAInsideB || r.meeting == Meeting::kBInsideA;
        near += r.meeting == Meeting::kApart && r.distance < c;
        if (!reference.empty() && (reference[i].meeting != r.meeting ||
                                   (r.meeting == Meeting::kApart && reference[i].distance != r.distance)))
          ++mismatch;
      }
      std::printf("  %-26s %12llu %12llu %14llu %12.4f %9llu %9llu %9llu %9llu\n", s.name,
                  static_cast<unsigned long long>(st.bound_rejects),
                  static_cast<unsigned long long>(st.triangle_tests),
                  static_cast<unsigned long long>(st.containment_tests), secs,
                  static_cast<unsigned long long>(meet), static_cast<unsigned long long>(inside),
                  static_cast<unsigned long long>(near), static_cast<unsigned long long>(mismatch));
      if (reference.empty()) reference = std::move(out);
    }
    // Depth classes of the meeting pairs with T = 2 mm.
    const double T = 0.002;
    uint64_t hard = 0, touch = 0, inexact = 0, exact_depth = 0;
    for (const Separation& r : reference) {
      if (r.meeting == Meeting::kApart) continue;
      exact_depth += r.depth_lower == r.depth_upper;
      if (r.depth_lower > T)
        ++hard;
      else if (r.depth_upper <= T)
        ++touch;
      else
        ++inexact;
    }
    std::printf(
        "  meeting pairs, T = 2 mm: %llu hard (depth_lower > T), %llu touch (depth_upper <= T), %llu hard "
        "with inexact depth; %llu with depth_lower == depth_upper\n",
        static_cast<unsigned long long>(hard), static_cast<unsigned long long>(touch),
        static_cast<unsigned long long>(inexact), static_cast<unsigned long long>(exact_depth));
  }
}

}  // namespace
}  // namespace mktree

int main(int argc, char** argv) {
#ifndef NDEBUG
  std::printf("WARNING: built without optimisation; timings are meaningless\n");
#endif
  uint64_t tanker = 20000;
  std::vector<double> clearances;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--tanker") && i + 1 < argc) {
      tanker = std::strtoull(argv[++i], nullptr, 10);
    } else if (!std::strcmp(argv[i], "--clearance") && i + 1 < argc) {
      clearances.push_back(std::strtod(argv[++i], nullptr));
    } else if (argv[i][0] == '-') {
      std::fprintf(stderr, "usage: narrow_bench [--tanker N] [--clearance C] [FILE...]\n");
      return 2;
    } else {
      files.push_back(argv[i]);
    }
  }
  if (clearances.empty()) clearances = {0, 0.05};
  if (files.empty() && argc == 1)
    files.push_back(std::string(MKTREE_SHARED_DATA_DIR) + "/buildings/steel_mini_project.obj");
  std::printf("# narrow_bench: Separate on every candidate pair, one thread\n");
  if (tanker > 0) {
    mktree::Scene scene;
    scene.name = "tanker " + std::to_string(tanker) + " seed 1";
    auto src = mktree::MakeTankerSource(tanker, 1);
    if (!mktree::ReadAll(src.get(), &scene)) return 1;
    mktree::Run(scene, clearances);
  }
  for (const std::string& f : files) {
    mktree::Scene scene;
    scene.name = f;
    auto src = mktree::OpenSceneFile(f);
    if (!src.ok()) {
      std::fprintf(stderr, "error: %s\n", src.status().message().c_str());
      return 1;
    }
    if (!mktree::ReadAll(src->get(), &scene)) return 1;
    mktree::Run(scene, clearances);
  }
  return 0;
}
