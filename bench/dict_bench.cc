// dict_bench: what a zstd dictionary shared by a store's objects would save and cost against one
// dictionary-less zstd frame per object (the leaf entry's geometry, engine/store_format/object_codec.h).
//
// For each object of the workload the bench takes the bytes the codec hands zstd (PackObjectGeometry:
// local vertices and triangles after the shuffle transform), then per configuration:
//   none      ZSTD_compress2 per object at the level, content size left out (the store as built today)
//   dict K L  a dictionary of K KiB trained (ZDICT fastCover, d=8, f=20, the engine's steps, one thread) on
//             the first --sample-mib MiB of objects (whole objects), a ZSTD_CDict at level L referenced by
//             the context for every object (ZSTD_CCtx_refCDict), content size and dictionary id left out
// and reports: training seconds, compression CPU us an object, decompression CPU us an object (with a
// ZSTD_DDict for dictionaries), stored geometry bytes (zstd output or raw, whichever is smaller, as the
// entry stores it) and their ratio to "none" at the same level. CPU is CLOCK_PROCESS_CPUTIME_ID on one
// thread, best of --repeat.
//
// Workloads: tanker:N[:SEED] (the generator, origin 0) or a scene file (OBJ, AC3D, ...; origin as
// ChooseStoreOrigin picks it). Usage:
//   dict_bench [--sample-mib M] [--dict-kib 16,64,112] [--levels 3] [--repeat 3] WORKLOAD...
// "+dict" is the ratio with the dictionary's own bytes counted (a store holds it once).
#define ZDICT_STATIC_LINKING_ONLY
#include <zdict.h>
#include <zstd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/scene_source.h"
#include "engine/store_format/object_codec.h"

namespace {

double CpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::vector<int> ParseList(const char* s) {
  std::vector<int> v;
  for (const char* p = s; *p;) {
    char* end;
    v.push_back(static_cast<int>(std::strtol(p, &end, 10)));
    p = *end == ',' ? end + 1 : end;
    if (end == p && *p) break;
  }
  return v;
}

struct Samples {
  std::vector<uint8_t> bytes;
  std::vector<size_t> sizes;
};

bool Load(const std::string& workload, Samples* s) {
  std::unique_ptr<mktree::SceneSource> src;
  if (workload.rfind("tanker:", 0) == 0) {
    const char* p = workload.c_str() + 7;
    char* end;
    const uint64_t n = std::strtoull(p, &end, 10);
    const uint64_t seed = *end == ':' ? std::strtoull(end + 1, nullptr, 10) : 1;
    src = mktree::MakeTankerSource(n, seed, 0);
  } else {
    auto r = mktree::OpenSceneFile(workload);
    if (!r.ok()) {
      std::fprintf(stderr, "%s\n", r.status().ToString().c_str());
      return false;
    }
    src = std::move(*r);
  }
  mktree::SceneObject o;
  bool first = true;
  mktree::Vec3d origin;
  for (;;) {
    auto more = src->Next(&o);
    if (!more.ok()) {
      std::fprintf(stderr, "%s\n", more.status().ToString().c_str());
      return false;
    }
    if (!*more) break;
    if (o.mesh.vertices.empty()) continue;
    if (first) origin = mktree::ChooseStoreOrigin(o.mesh.Bounds());
    first = false;
    const size_t before = s->bytes.size();
    if (!mktree::PackObjectGeometry(o, origin, true, &s->bytes).ok()) return false;
    s->sizes.push_back(s->bytes.size() - before);
  }
  return true;
}

struct Result {
  double train_s = 0, comp_us = 1e300, decomp_us = 1e300;
  uint64_t stored = 0;
};

Result Run(const Samples& s, const ZSTD_CDict* cdict, const ZSTD_DDict* ddict, int level, int repeat) {
  Result r;
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  ZSTD_DCtx* dctx = ZSTD_createDCtx();
  std::vector<uint8_t> out(ZSTD_compressBound(1 << 20)), back;
  std::vector<std::vector<uint8_t>> frames(s.sizes.size());
  for (int rep = 0; rep < repeat; ++rep) {
    uint64_t stored = 0;
    size_t off = 0;
    const double t0 = CpuSeconds();
    for (size_t i = 0; i < s.sizes.size(); ++i) {
      const size_t n = s.sizes[i];
      if (out.size() < ZSTD_compressBound(n)) out.resize(ZSTD_compressBound(n));
      ZSTD_CCtx_reset(cctx, ZSTD_reset_session_and_parameters);
      ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, level);
      ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 0);
      if (cdict != nullptr) {
        ZSTD_CCtx_setParameter(cctx, ZSTD_c_dictIDFlag, 0);
        ZSTD_CCtx_refCDict(cctx, cdict);
      }
      const size_t z = ZSTD_compress2(cctx, out.data(), out.size(), s.bytes.data() + off, n);
      if (!ZSTD_isError(z) && z < n) {
        stored += z;
        if (rep == 0) frames[i].assign(out.data(), out.data() + z);
      } else {
        stored += n;
        if (rep == 0) frames[i].clear();
      }
      off += n;
    }
    r.comp_us = std::min(r.comp_us, 1e6 * (CpuSeconds() - t0) / static_cast<double>(s.sizes.size()));
    r.stored = stored;
  }
  for (int rep = 0; rep < repeat; ++rep) {
    size_t off = 0;
    const double t0 = CpuSeconds();
    for (size_t i = 0; i < s.sizes.size(); ++i) {
      const size_t n = s.sizes[i];
      if (!frames[i].empty()) {
        back.resize(n);
        const size_t d =
            ddict != nullptr
                ? ZSTD_decompress_usingDDict(dctx, back.data(), n, frames[i].data(), frames[i].size(), ddict)
                : ZSTD_decompressDCtx(dctx, back.data(), n, frames[i].data(), frames[i].size());
        if (ZSTD_isError(d) || d != n || std::memcmp(back.data(), s.bytes.data() + off, n) != 0) {
          std::fprintf(stderr, "round trip failed at object %zu\n", i);
          std::exit(1);
        }
      }
      off += n;
    }
    r.decomp_us = std::min(r.decomp_us, 1e6 * (CpuSeconds() - t0) / static_cast<double>(s.sizes.size()));
  }
  ZSTD_freeCCtx(cctx);
  ZSTD_freeDCtx(dctx);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  double sample_mib = 4;
  std::vector<int> dict_kib = {16, 64, 112}, levels = {3};
  int repeat = 3;
  std::vector<std::string> workloads;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--sample-mib" && i + 1 < argc) {
      sample_mib = std::atof(argv[++i]);
    } else if (a == "--dict-kib" && i + 1 < argc) {
      dict_kib = ParseList(argv[++i]);
    } else if (a == "--levels" && i + 1 < argc) {
      levels = ParseList(argv[++i]);
    } else if (a == "--repeat" && i + 1 < argc) {
      repeat = std::atoi(argv[++i]);
    } else {
      workloads.push_back(a);
    }
  }
  std::printf("dict_bench: zstd %s, sample %.1f MiB, repeat %d, one thread (CPU time)\n",
              ZSTD_versionString(), sample_mib, repeat);
  std::printf("%-40s %6s %5s %4s %8s %8s %8s %12s %8s %8s %10s\n", "workload", "objs", "dict", "lvl",
              "train_s", "comp_us", "dec_us", "stored_B", "vs_none", "+dict", "sample_B");
  for (const std::string& w : workloads) {
    Samples s;
    if (!Load(w, &s)) return 1;
    const std::string name = w.size() > 40 ? w.substr(w.size() - 40) : w;
    for (int level : levels) {
      const Result base = Run(s, nullptr, nullptr, level, repeat);
      std::printf("%-40s %6zu %5s %4d %8s %8.2f %8.2f %12llu %8.4f\n", name.c_str(), s.sizes.size(), "none",
                  level, "-", base.comp_us, base.decomp_us, static_cast<unsigned long long>(base.stored),
                  1.0);
      // The sample: whole objects from the first, up to sample_mib MiB.
      size_t sample_bytes = 0, sample_n = 0;
      while (sample_n < s.sizes.size() && sample_bytes + s.sizes[sample_n] <= sample_mib * (1 << 20))
        sample_bytes += s.sizes[sample_n++];
      for (int kib : dict_kib) {
        std::vector<uint8_t> dict(static_cast<size_t>(kib) << 10);
        ZDICT_fastCover_params_t p{};
        p.d = 8;
        p.f = 20;
        p.steps = mktree::kDictionaryTrainingSteps;
        p.nbThreads = 1;
        p.zParams.compressionLevel = level;
        const double t0 = CpuSeconds();
        const size_t dn = ZDICT_optimizeTrainFromBuffer_fastCover(
            dict.data(), dict.size(), s.bytes.data(), s.sizes.data(), static_cast<unsigned>(sample_n), &p);
        const double train = CpuSeconds() - t0;
        if (ZDICT_isError(dn)) {
          std::printf("%-40s %6zu %5d %4d training failed on %zu objects: %s\n", name.c_str(), s.sizes.size(),
                      kib, level, sample_n, ZDICT_getErrorName(dn));
          continue;
        }
        ZSTD_CDict* cd = ZSTD_createCDict(dict.data(), dn, level);
        ZSTD_DDict* dd = ZSTD_createDDict(dict.data(), dn);
        Result r = Run(s, cd, dd, level, repeat);
        r.train_s = train;
        std::printf("%-40s %6zu %5d %4d %8.3f %8.2f %8.2f %12llu %8.4f %8.4f %10zu\n", name.c_str(),
                    s.sizes.size(), kib, level, r.train_s, r.comp_us, r.decomp_us,
                    static_cast<unsigned long long>(r.stored),
                    static_cast<double>(r.stored) / static_cast<double>(base.stored),
                    static_cast<double>(r.stored + dn) / static_cast<double>(base.stored), sample_bytes);
        ZSTD_freeCDict(cd);
        ZSTD_freeDDict(dd);
      }
    }
  }
  return 0;
}
