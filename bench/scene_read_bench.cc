// scene_read_bench: reads scene files through OpenSceneFile (the path `mktree build` takes) and reports
// objects, triangles, objects/s, MB/s and peak RSS. Workload: whatever files are named; the README and
// issue notes use the tanker (`mktree generate tanker --objects N --seed 1 -o t.obj|t.mks`).
// Usage: scene_read_bench FILE...
#include <sys/resource.h>
#include <sys/stat.h>

#include <chrono>
#include <cstdio>

#include "engine/scene/scene_source.h"

int main(int argc, char** argv) {
#ifndef NDEBUG
  std::printf("WARNING: built without optimisation; timings are meaningless\n");
#endif
  if (argc < 2) {
    std::fprintf(stderr, "usage: scene_read_bench FILE...\n");
    return 2;
  }
  std::printf("# scene_read_bench: streaming read through OpenSceneFile, one file after another\n");
  std::printf("%-40s %12s %14s %9s %12s %9s %12s\n", "file", "objects", "triangles", "seconds", "objects/s",
              "MB/s", "peak RSS MiB");
  for (int i = 1; i < argc; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    auto src = mktree::OpenSceneFile(argv[i], 0);
    if (!src.ok()) {
      std::fprintf(stderr, "error: %s\n", src.status().message().c_str());
      return 1;
    }
    mktree::SceneObject o;
    uint64_t objects = 0, triangles = 0;
    for (;;) {
      auto more = (*src)->Next(&o);
      if (!more.ok()) {
        std::fprintf(stderr, "error: %s\n", more.status().message().c_str());
        return 1;
      }
      if (!*more) break;
      ++objects;
      triangles += o.mesh.triangle_count();
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    struct stat st {};
    ::stat(argv[i], &st);
    struct rusage ru {};
    getrusage(RUSAGE_SELF, &ru);
    std::printf("%-40s %12llu %14llu %9.2f %12.0f %9.1f %12.1f\n", argv[i],
                static_cast<unsigned long long>(objects), static_cast<unsigned long long>(triangles), s,
                objects / s, st.st_size / 1e6 / s, ru.ru_maxrss / 1024.0);
  }
  return 0;
}
