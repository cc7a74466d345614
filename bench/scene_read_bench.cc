// scene_read_bench: reads scene files through OpenSceneFile (the path `mktree build` takes) and reports
// objects, triangles, objects/s, MB/s and peak RSS. Workload: whatever files are named; the README and
// issue notes use the tanker (`mktree generate tanker --objects N --seed 1 -o t.obj|t.mks`).
// Workload obj_parse (--obj-threads 0,1,2): each .obj file is read through OpenObjFile with each number of
// parsing threads listed (0: the caller's thread only), to show what the parallel OBJ reader gains. Peak RSS
// is the process's: give one number per run to compare it.
// Usage: scene_read_bench [--obj-threads N[,N...]] [--chunk-bytes N] FILE...
#include <sys/resource.h>
#include <sys/stat.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "engine/scene/obj_reader.h"
#include "engine/scene/scene_source.h"

namespace {

struct Run {
  std::string label;
  mktree::Result<std::unique_ptr<mktree::SceneSource>> (*open)(const char*, const mktree::ObjReadOptions&);
  mktree::ObjReadOptions options;
};

mktree::Result<std::unique_ptr<mktree::SceneSource>> OpenAny(const char* path,
                                                             const mktree::ObjReadOptions&) {
  return mktree::OpenSceneFile(path, 0);
}
mktree::Result<std::unique_ptr<mktree::SceneSource>> OpenObj(const char* path,
                                                             const mktree::ObjReadOptions& o) {
  return mktree::OpenObjFile(path, 0, o);
}

bool Measure(const char* path, const Run& run) {
  const auto t0 = std::chrono::steady_clock::now();
  struct rusage ru0 {};
  getrusage(RUSAGE_SELF, &ru0);
  auto src = run.open(path, run.options);
  if (!src.ok()) {
    std::fprintf(stderr, "error: %s\n", src.status().message().c_str());
    return false;
  }
  // What opening took (assimp and STEP parse the whole file there; OBJ and .mks start streaming).
  const double open_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  mktree::SceneObject o;
  uint64_t objects = 0, triangles = 0;
  for (;;) {
    auto more = (*src)->Next(&o);
    if (!more.ok()) {
      std::fprintf(stderr, "error: %s\n", more.status().message().c_str());
      return false;
    }
    if (!*more) break;
    ++objects;
    triangles += o.mesh.triangle_count();
  }
  src->reset();
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  struct stat st {};
  ::stat(path, &st);
  struct rusage ru {};
  getrusage(RUSAGE_SELF, &ru);
  auto secs = [](const timeval& t) { return t.tv_sec + t.tv_usec / 1e6; };
  const double cpu = secs(ru.ru_utime) + secs(ru.ru_stime) - secs(ru0.ru_utime) - secs(ru0.ru_stime);
  std::printf("%-32s %-10s %10llu %12llu %8.2f %8.2f %11.0f %8.1f %12.1f %8.2f\n", path, run.label.c_str(),
              static_cast<unsigned long long>(objects), static_cast<unsigned long long>(triangles), s, cpu,
              objects / s, st.st_size / 1e6 / s, ru.ru_maxrss / 1024.0, open_s);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
#ifndef NDEBUG
  std::printf("WARNING: built without optimisation; timings are meaningless\n");
#endif
  bool obj_threads = false;
  std::vector<int> thread_counts;
  size_t chunk_bytes = mktree::ObjReadOptions().chunk_bytes;
  std::vector<const char*> files;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--obj-threads") == 0 && i + 1 < argc) {
      obj_threads = true;
      std::stringstream list(argv[++i]);
      for (std::string n; std::getline(list, n, ',');) thread_counts.push_back(std::stoi(n));
    } else if (std::strcmp(argv[i], "--chunk-bytes") == 0 && i + 1 < argc) {
      chunk_bytes = std::stoull(argv[++i]);
    } else {
      files.push_back(argv[i]);
    }
  }
  if (files.empty()) {
    std::fprintf(stderr, "usage: scene_read_bench [--obj-threads N[,N...]] [--chunk-bytes N] FILE...\n");
    return 2;
  }
  std::printf(
      "# scene_read_bench: streaming read, one file after another%s; peak RSS is the process's so far\n",
      obj_threads ? " (obj_parse: OpenObjFile, t = parsing threads)" : " through OpenSceneFile");
  std::printf("%-32s %-10s %10s %12s %8s %8s %11s %8s %12s %8s\n", "file", "reader", "objects", "triangles",
              "seconds", "cpu s", "objects/s", "MB/s", "peak RSS MiB", "open s");
  for (const char* f : files) {
    const size_t n = std::strlen(f);
    const bool obj = n > 4 && strcasecmp(f + n - 4, ".obj") == 0;
    std::vector<Run> runs;
    if (obj_threads && obj) {
      for (int t : thread_counts) {
        mktree::ObjReadOptions o;
        o.threads = t;
        o.chunk_bytes = chunk_bytes;
        runs.push_back({"obj t=" + std::to_string(t), OpenObj, o});
      }
    } else {
      runs.push_back({"default", OpenAny, {}});
    }
    for (const Run& r : runs) {
      if (!Measure(f, r)) return 1;
    }
  }
  return 0;
}
