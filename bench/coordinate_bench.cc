// coordinate_bench: what each way of storing vertex coordinates costs in leaf bytes and what precision it
// keeps, on the synthetic tanker at its own coordinates and moved to UTM-like coordinates. This is the
// measurement behind the leaf entry's coordinate frame (engine/store_format/object_codec.h).
//
// Representations, each run through the codec's transform (XOR with the previous value per coordinate
// plane, byte shuffle) and zstd level 3, as leaf entries are:
//   float32 world   float32 of the world coordinates (the entry format before store format version 3)
//   f32 from min    float32 of (world - box min): a local frame whose values span many exponents
//   f32 local       float32 of (world - box min + 2^k), 2^k the power of two above the box's extent: one
//                   exponent per axis (store format version 3, engine/store_format/object_codec.h)
//   float64 world   the world coordinates as doubles
// Reported per workload: mean geometry bytes an object after zstd, and the largest vertex error, absolute
// and relative to the object's extent (the largest side of its box).
//
// Workloads: tanker (seed 1, at its own coordinates, 0-300 m) and tanker_utm (the same objects moved by
// (500000, 5000000, 100) m in double precision before rounding). Usage: coordinate_bench [--objects N]
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/store_builder.h"

namespace {

using mktree::Box3d;
using mktree::SceneObject;

// The codec's transform generalised to words of W bytes: per coordinate plane, each value XORed with the
// previous one, then bytes shuffled (all byte 0s, then all byte 1s, ...).
template <typename Word>
std::vector<uint8_t> Transform(const std::vector<Word>& xyz) {
  const size_t vc = xyz.size() / 3;
  std::vector<Word> w(xyz.size());
  for (size_t c = 0; c < 3; ++c) {
    Word prev = 0;
    for (size_t i = 0; i < vc; ++i) {
      w[c * vc + i] = xyz[3 * i + c] ^ prev;
      prev = xyz[3 * i + c];
    }
  }
  std::vector<uint8_t> out(w.size() * sizeof(Word));
  for (size_t i = 0; i < w.size(); ++i)
    for (size_t b = 0; b < sizeof(Word); ++b) out[b * w.size() + i] = static_cast<uint8_t>(w[i] >> (8 * b));
  return out;
}

size_t Compressed(const std::vector<uint8_t>& vertex_bytes, const std::vector<uint32_t>& triangles) {
  // Triangles as the codec stores them: zigzag deltas, shuffled.
  std::vector<uint32_t> d(triangles.size());
  uint32_t prev = 0;
  for (size_t i = 0; i < triangles.size(); ++i) {
    const int32_t delta = static_cast<int32_t>(triangles[i] - prev);
    d[i] = (static_cast<uint32_t>(delta) << 1) ^ static_cast<uint32_t>(delta >> 31);
    prev = triangles[i];
  }
  std::vector<uint8_t> in = vertex_bytes;
  for (size_t b = 0; b < 4; ++b)
    for (size_t i = 0; i < d.size(); ++i) in.push_back(static_cast<uint8_t>(d[i] >> (8 * b)));
  std::vector<uint8_t> z(ZSTD_compressBound(in.size()));
  const size_t n = ZSTD_compress(z.data(), z.size(), in.data(), in.size(), 3);
  return ZSTD_isError(n) ? in.size() : std::min(n, in.size());
}

float RoundDown(double x) { return mktree::RoundDownToFloat(x); }
float RoundUp(double x) { return mktree::RoundUpToFloat(x); }

struct Tally {
  double bytes = 0, max_abs = 0, max_rel = 0;
  void Error(double abs_err, double extent) {
    max_abs = std::max(max_abs, abs_err);
    max_rel = std::max(max_rel, extent > 0 ? abs_err / extent : 0.0);
  }
};

void Run(const char* name, uint64_t objects, const double shift[3]) {
  auto src = mktree::MakeTankerSource(objects, 1, 0);
  SceneObject o;
  Tally f32, local, local_aligned, f64;
  uint64_t n = 0;
  std::vector<double> world;
  double store_origin[3] = {0, 0, 0};
  for (;;) {
    auto more = src->Next(&o);
    if (!more.ok() || !*more) break;
    const size_t nv = o.mesh.vertex_count();
    world.resize(3 * nv);
    Box3d b;
    for (size_t i = 0; i < nv; ++i) {
      for (int c = 0; c < 3; ++c) world[3 * i + c] = o.mesh.vertices[3 * i + c] + shift[c];
      b.Extend(world[3 * i], world[3 * i + 1], world[3 * i + 2]);
    }
    if (n == 0) {
      const mktree::Vec3d o = mktree::ChooseStoreOrigin(b);
      for (int c = 0; c < 3; ++c) store_origin[c] = o[c];
    }
    double extent = 0;
    for (int c = 0; c < 3; ++c) extent = std::max(extent, b.max[c] - b.min[c]);

    std::vector<uint32_t> wf(3 * nv), wl(3 * nv), wa(3 * nv);
    std::vector<uint64_t> wd(3 * nv);
    double origin[3], aligned[3];
    for (int c = 0; c < 3; ++c) {
      const float lo = RoundDown(b.min[c] - store_origin[c]);
      const double e = static_cast<double>(RoundUp(b.max[c] - store_origin[c])) - lo;
      origin[c] = store_origin[c] + lo;
      aligned[c] = origin[c] - std::ldexp(1.0, e > 0 ? std::max(std::ilogb(e) + 1, -100) : -100);
    }
    for (size_t i = 0; i < 3 * nv; ++i) {
      const float fw = static_cast<float>(world[i]);
      const float fl = static_cast<float>(world[i] - origin[i % 3]);
      const float fa = static_cast<float>(world[i] - aligned[i % 3]);
      std::memcpy(&wf[i], &fw, 4);
      std::memcpy(&wl[i], &fl, 4);
      std::memcpy(&wa[i], &fa, 4);
      std::memcpy(&wd[i], &world[i], 8);
      f32.Error(std::fabs(static_cast<double>(fw) - world[i]), extent);
      local.Error(std::fabs(origin[i % 3] + static_cast<double>(fl) - world[i]), extent);
      local_aligned.Error(std::fabs(aligned[i % 3] + static_cast<double>(fa) - world[i]), extent);
    }
    f32.bytes += Compressed(Transform(wf), o.mesh.triangles);
    local.bytes += Compressed(Transform(wl), o.mesh.triangles);
    local_aligned.bytes += Compressed(Transform(wa), o.mesh.triangles);
    f64.bytes += Compressed(Transform(wd), o.mesh.triangles);
    ++n;
  }
  auto row = [&](const char* rep, const Tally& t) {
    std::printf("%-12s %-14s %10.1f %14.3g %14.3g\n", name, rep, t.bytes / n, t.max_abs, t.max_rel);
  };
  row("float32 world", f32);
  row("f32 from min", local);
  row("f32 local", local_aligned);
  row("float64 world", f64);
}

}  // namespace

int main(int argc, char** argv) {
  uint64_t objects = 200000;
  for (int i = 1; i + 1 < argc; i += 2)
    if (std::string(argv[i]) == "--objects") objects = std::strtoull(argv[i + 1], nullptr, 10);
  std::printf(
      "# coordinate_bench: tanker seed 1, %llu objects; geometry bytes an object after the codec's "
      "transform\n"
      "# and zstd 3; vertex error against the double-precision world coordinates\n",
      static_cast<unsigned long long>(objects));
  std::printf("%-12s %-14s %10s %14s %14s\n", "workload", "vertices as", "bytes/obj", "max error",
              "max error/size");
  const double none[3] = {0, 0, 0}, utm[3] = {500000, 5000000, 100};
  Run("tanker", objects, none);
  Run("tanker_utm", objects, utm);
  return 0;
}
