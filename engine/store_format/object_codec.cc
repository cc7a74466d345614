#include "engine/store_format/object_codec.h"

#define ZDICT_STATIC_LINKING_ONLY  // ZDICT_optimizeTrainFromBuffer_fastCover
#include <zdict.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <future>
#include <limits>
#include <memory>
#include <string>

#include "storage/byte_io.h"

namespace mktree {

using storage_internal::Get;
using storage_internal::Put;

namespace {

struct CCtxDeleter {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct DCtxDeleter {
  void operator()(ZSTD_DCtx* c) const { ZSTD_freeDCtx(c); }
};

// One context per thread: zstd contexts are expensive to create and not thread-safe.
ZSTD_CCtx* ThreadCCtx() {
  thread_local std::unique_ptr<ZSTD_CCtx, CCtxDeleter> ctx(ZSTD_createCCtx());
  return ctx.get();
}
ZSTD_DCtx* ThreadDCtx() {
  thread_local std::unique_ptr<ZSTD_DCtx, DCtxDeleter> ctx(ZSTD_createDCtx());
  return ctx.get();
}

// memcpy that accepts an empty vector's data(): memcpy's pointers must not be null even for 0 bytes.
void CopyBytes(void* dst, const void* src, size_t n) {
  if (n != 0) std::memcpy(dst, src, n);
}

void Shuffle4(const uint32_t* in, size_t n, uint8_t* out) {
  for (size_t i = 0; i < n; ++i) {
    const uint32_t v = in[i];
    out[i] = static_cast<uint8_t>(v);
    out[n + i] = static_cast<uint8_t>(v >> 8);
    out[2 * n + i] = static_cast<uint8_t>(v >> 16);
    out[3 * n + i] = static_cast<uint8_t>(v >> 24);
  }
}

void Unshuffle4(const uint8_t* in, size_t n, uint32_t* out) {
  for (size_t i = 0; i < n; ++i)
    out[i] = uint32_t{in[i]} | uint32_t{in[n + i]} << 8 | uint32_t{in[2 * n + i]} << 16 |
             uint32_t{in[3 * n + i]} << 24;
}

// Transform 1 (see the header): raw geometry (local vertices, triangles) -> transformed bytes of the
// same size.
void ForwardTransform(const std::vector<float>& local, const std::vector<uint32_t>& triangles, uint8_t* out) {
  const size_t vc = local.size() / 3, nt = triangles.size();
  thread_local std::vector<uint32_t> w;  // per object otherwise: ingest encodes millions
  w.resize(3 * vc + nt);
  for (int c = 0; c < 3; ++c) {
    uint32_t prev = 0;
    for (size_t i = 0; i < vc; ++i) {
      uint32_t bits;
      std::memcpy(&bits, &local[3 * i + c], 4);
      w[c * vc + i] = bits ^ prev;
      prev = bits;
    }
  }
  uint32_t prev = 0;
  for (size_t i = 0; i < nt; ++i) {
    const int32_t d = static_cast<int32_t>(triangles[i] - prev);
    w[3 * vc + i] = (static_cast<uint32_t>(d) << 1) ^ static_cast<uint32_t>(d >> 31);
    prev = triangles[i];
  }
  Shuffle4(w.data(), 3 * vc, out);
  Shuffle4(w.data() + 3 * vc, nt, out + 12 * vc);
  if (w.capacity() > (size_t{1} << 20)) w = {};
}

void InverseTransform(const uint8_t* in, size_t vc, size_t nt, std::vector<float>* local, Mesh* m) {
  std::vector<uint32_t> w(3 * vc + nt);
  Unshuffle4(in, 3 * vc, w.data());
  Unshuffle4(in + 12 * vc, nt, w.data() + 3 * vc);
  local->resize(3 * vc);
  for (int c = 0; c < 3; ++c) {
    uint32_t prev = 0;
    for (size_t i = 0; i < vc; ++i) {
      prev ^= w[c * vc + i];
      std::memcpy(&(*local)[3 * i + c], &prev, 4);
    }
  }
  m->triangles.resize(nt);
  uint32_t prev = 0;
  for (size_t i = 0; i < nt; ++i) {
    const uint32_t z = w[3 * vc + i];
    const uint32_t d = (z >> 1) ^ (0u - (z & 1u));
    prev += d;
    m->triangles[i] = prev;
  }
}

// Every local coordinate on an axis lies in [2^k, 2^k + extent] with 2^k the power of two just above the
// box's extent on that axis (2^-100 for a flat axis): one exponent for all, so that float32 holds them as
// fixed point (the XOR transform then zeroes their high bits as it did for world coordinates;
// bench/coordinate_bench.cc) and rounding costs at most extent * 2^-22.
double LocalBase(float lo, float hi) {
  const double extent = static_cast<double>(hi) - lo;
  return std::ldexp(1.0, extent > 0 ? std::max(std::ilogb(extent) + 1, -100) : -100);
}

}  // namespace

Result<std::shared_ptr<const CodecDictionary>> CodecDictionary::Load(std::vector<uint8_t> bytes,
                                                                     std::optional<int> compress_level) {
  // A zstd dictionary starts with its magic and a non-zero id; anything else zstd would take as raw
  // content, so a damaged one is refused here rather than decoding to wrong bytes.
  if (ZSTD_getDictID_fromDict(bytes.data(), bytes.size()) == 0)
    return Status::Corruption("the codec dictionary is not a zstd dictionary");
  std::shared_ptr<CodecDictionary> d(new CodecDictionary());
  d->bytes_ = std::move(bytes);
  d->ddict_ = ZSTD_createDDict(d->bytes_.data(), d->bytes_.size());
  if (d->ddict_ == nullptr) return Status::Corruption("the codec dictionary's tables are invalid");
  if (compress_level) {
    d->cdict_ = ZSTD_createCDict(d->bytes_.data(), d->bytes_.size(), *compress_level);
    if (d->cdict_ == nullptr) return Status::Corruption("the codec dictionary's tables are invalid");
  }
  return std::shared_ptr<const CodecDictionary>(std::move(d));
}

CodecDictionary::~CodecDictionary() {
  ZSTD_freeCDict(cdict_);
  ZSTD_freeDDict(ddict_);
}

namespace {

// What the samples compress to, each alone (as entries store them: raw where zstd does not shrink one).
uint64_t StoredBytes(std::span<const uint8_t> samples, std::span<const size_t> sizes, int level,
                     const ZSTD_CDict* cdict) {
  ZSTD_CCtx* cctx = ThreadCCtx();
  std::vector<uint8_t> out;
  uint64_t total = 0;
  size_t at = 0;
  for (const size_t n : sizes) {
    out.resize(ZSTD_compressBound(n));
    ZSTD_CCtx_reset(cctx, ZSTD_reset_session_and_parameters);
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, level);
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 0);
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_dictIDFlag, 0);
    if (cdict != nullptr) ZSTD_CCtx_refCDict(cctx, cdict);
    const size_t z = ZSTD_compress2(cctx, out.data(), out.size(), samples.data() + at, n);
    total += !ZSTD_isError(z) && z < n ? z : n;
    at += n;
  }
  return total;
}

}  // namespace

std::vector<uint8_t> TrainDictionary(std::span<const uint8_t> samples, std::span<const size_t> sizes,
                                     int level) {
  if (sizes.empty() || sizes.size() > std::numeric_limits<unsigned>::max()) return {};
  // A sixty-fourth of the sample, within 4-64 KiB: what bench/dict_bench.cc found best across scenes
  // (bench/README.md).
  const size_t capacity = std::clamp<size_t>(samples.size() / 64, size_t{4} << 10, size_t{64} << 10);
  // What the sample stores without a dictionary, on another thread while the dictionary trains.
  std::future<uint64_t> without =
      std::async(std::launch::async, [&] { return StoredBytes(samples, sizes, level, nullptr); });
  std::vector<uint8_t> dict(capacity);
  ZDICT_fastCover_params_t p{};
  p.d = 8;
  p.f = 20;
  p.steps = kDictionaryTrainingSteps;
  p.nbThreads = 1;  // deterministic
  p.zParams.compressionLevel = level;
  // zstd cannot train on a few objects and says so (an error code, not a crash); no dictionary then.
  const size_t n = ZDICT_optimizeTrainFromBuffer_fastCover(
      dict.data(), dict.size(), samples.data(), sizes.data(), static_cast<unsigned>(sizes.size()), &p);
  if (ZDICT_isError(n)) return {};
  dict.resize(n);
  auto loaded = CodecDictionary::Load(dict, level);
  if (!loaded.ok()) return {};
  // On a scene hardly larger than its dictionary the dictionary's own bytes outweigh what it saves.
  const uint64_t with = StoredBytes(samples, sizes, level, (*loaded)->cdict());
  if (with + n >= without.get()) return {};
  return dict;
}

double CoordinateResolution(const Box3f& box) {
  double sum = 0;
  for (int c = 0; c < 3; ++c) {
    const double base = LocalBase(box.min[c], box.max[c]);
    // One float32 ulp of the local coordinate, 2^k * 2^-23 (half from rounding, up to one when the
    // rounded value is stepped back into the box); a few double ulps of the largest magnitude involved
    // from the subtractions and the sum that decodes (bounded generously by 2^-50).
    const double mag = std::fabs(double{box.min[c]}) + std::fabs(double{box.max[c]}) + 2 * base;
    const double e = std::ldexp(base, -23) + std::ldexp(mag, -50);
    sum += e * e;
  }
  return std::sqrt(sum);
}

namespace {

// The object's AABB in the store frame and its vertices in its local frame (see the header).
Status LocalFrame(const SceneObject& obj, const Vec3d& origin, std::vector<float>* local, Box3f* box) {
  const Mesh& m = obj.mesh;
  auto fail = [&](const std::string& what) {
    return Status::InvalidArgument("object " + std::to_string(obj.id) + " ('" + obj.name + "'): " + what);
  };
  if (m.vertices.empty()) return fail("no vertices");
  const size_t n = m.vertices.size();
  Box3d b;  // store frame
  for (size_t i = 0; i < n; i += 3) {
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(m.vertices[i + c])) return fail("non-finite coordinate");
    b.Extend(m.vertices[i] - origin.x, m.vertices[i + 1] - origin.y, m.vertices[i + 2] - origin.z);
  }
  // Within 2^125 of the origin, so that 2^k + extent stays a finite float32.
  for (int c = 0; c < 3; ++c)
    if (!(std::fabs(b.min[c]) < 0x1p125 && std::fabs(b.max[c]) < 0x1p125))
      return fail("coordinates beyond float32's range from the store's origin");
  *box = RoundOutward(b);
  double base[3], extent[3];
  for (int c = 0; c < 3; ++c) {
    base[c] = LocalBase(box->min[c], box->max[c]);
    extent[c] = static_cast<double>(box->max[c]) - box->min[c];
  }
  local->resize(n);
  for (size_t i = 0; i < n; ++i) {
    const int c = static_cast<int>(i % 3);
    float l = static_cast<float>(((m.vertices[i] - origin[c]) - box->min[c]) + base[c]);
    if (static_cast<double>(l) - base[c] > extent[c]) l = std::nextafter(l, 0.0f);  // stay in the box
    (*local)[i] = l;
  }
  return Status::Ok();
}

}  // namespace

Result<uint32_t> EncodeObjectEntry(const SceneObject& obj, const Vec3d& origin, const CodecOptions& opts,
                                   std::vector<uint8_t>* out, uint8_t shape_flags, Box3f* box_out) {
  const Mesh& m = obj.mesh;
  const uint64_t raw64 = 4 * uint64_t{m.vertices.size()} + 4 * uint64_t{m.triangles.size()};
  if (raw64 + kObjectEntryHeaderBytes > std::numeric_limits<uint32_t>::max() || m.vertices.size() % 3 != 0 ||
      m.triangles.size() % 3 != 0)
    return Status::InvalidArgument("object " + std::to_string(obj.id) + " ('" + obj.name +
                                   "'): geometry cannot be encoded (larger than 4 GiB or malformed)");
  // Per-thread buffers: ingest encodes millions of small objects, and three allocations each showed in
  // its profile.
  thread_local std::vector<float> local;
  thread_local std::vector<uint8_t> packed;  // the bytes that go to zstd
  Box3f box;
  MKTREE_RETURN_IF_ERROR(LocalFrame(obj, origin, &local, &box));
  const uint32_t raw = static_cast<uint32_t>(raw64);
  const size_t start = out->size();

  Codec codec = Codec::kNone;
  uint8_t transform = 0;
  size_t compressed = 0;  // zstd writes straight after the header
  if (opts.codec == Codec::kZstd && raw > 0) {
    packed.resize(raw);
    if (opts.shuffle) {
      ForwardTransform(local, m.triangles, packed.data());
    } else {
      CopyBytes(packed.data(), local.data(), 4 * local.size());
      CopyBytes(packed.data() + 4 * local.size(), m.triangles.data(), 4 * m.triangles.size());
    }
    out->resize(start + kObjectEntryHeaderBytes + ZSTD_compressBound(raw));
    ZSTD_CCtx* cctx = ThreadCCtx();
    ZSTD_CCtx_reset(cctx, ZSTD_reset_session_and_parameters);
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, opts.zstd_level);
    // The raw size is in the entry header; leaving it out of the frame saves bytes on small meshes.
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 0);
    const ZSTD_CDict* cdict = opts.dictionary ? opts.dictionary->cdict() : nullptr;
    if (cdict != nullptr) {
      ZSTD_CCtx_setParameter(cctx, ZSTD_c_dictIDFlag, 0);  // a store has one dictionary
      ZSTD_CCtx_refCDict(cctx, cdict);
    }
    const size_t z = ZSTD_compress2(cctx, out->data() + start + kObjectEntryHeaderBytes,
                                    out->size() - start - kObjectEntryHeaderBytes, packed.data(), raw);
    if (!ZSTD_isError(z) && z < raw) {
      compressed = z;
      codec = cdict != nullptr ? Codec::kZstdDict : Codec::kZstd;
      transform = opts.shuffle ? 1 : 0;
    }
  }
  const uint32_t stored = codec != Codec::kNone ? static_cast<uint32_t>(compressed) : raw;
  out->resize(start + kObjectEntryHeaderBytes + stored);
  uint8_t* p = out->data() + start;
  Put<uint32_t>(p + 0, obj.id);
  for (int i = 0; i < 3; ++i) {
    Put<float>(p + 4 + 4 * i, box.min[i]);
    Put<float>(p + 16 + 4 * i, box.max[i]);
  }
  p[28] = static_cast<uint8_t>(codec);
  p[29] = transform;
  p[30] = shape_flags;
  p[31] = 0;
  Put<uint32_t>(p + 32, static_cast<uint32_t>(m.vertex_count()));
  Put<uint32_t>(p + 36, static_cast<uint32_t>(m.triangle_count()));
  Put<uint32_t>(p + 40, raw);
  Put<uint32_t>(p + 44, stored);
  uint8_t* g = p + kObjectEntryHeaderBytes;
  if (codec == Codec::kNone) {
    CopyBytes(g, local.data(), 4 * local.size());
    CopyBytes(g + 4 * local.size(), m.triangles.data(), 4 * m.triangles.size());
  }
  // A huge mesh should not pin its buffers in this thread for good.
  if (packed.capacity() > (size_t{1} << 22)) packed = {};
  if (local.capacity() > (size_t{1} << 20)) local = {};
  if (box_out != nullptr) *box_out = box;
  return kObjectEntryHeaderBytes + stored;
}

Status PackObjectGeometry(const SceneObject& obj, const Vec3d& origin, bool shuffle,
                          std::vector<uint8_t>* out) {
  const Mesh& m = obj.mesh;
  if (m.vertices.size() % 3 != 0 || m.triangles.size() % 3 != 0 ||
      4 * uint64_t{m.vertices.size()} + 4 * uint64_t{m.triangles.size()} >
          std::numeric_limits<uint32_t>::max())
    return Status::InvalidArgument("object " + std::to_string(obj.id) + " ('" + obj.name +
                                   "'): geometry cannot be encoded (larger than 4 GiB or malformed)");
  thread_local std::vector<float> local;
  Box3f box;
  MKTREE_RETURN_IF_ERROR(LocalFrame(obj, origin, &local, &box));
  const size_t start = out->size();
  out->resize(start + 4 * local.size() + 4 * m.triangles.size());
  if (shuffle) {
    ForwardTransform(local, m.triangles, out->data() + start);
  } else {
    CopyBytes(out->data() + start, local.data(), 4 * local.size());
    CopyBytes(out->data() + start + 4 * local.size(), m.triangles.data(), 4 * m.triangles.size());
  }
  if (local.capacity() > (size_t{1} << 20)) local = {};
  return Status::Ok();
}

uint32_t EncodeObjectEntry(const SceneObject& obj, const CodecOptions& opts, std::vector<uint8_t>* out,
                           uint8_t shape_flags) {
  auto n = EncodeObjectEntry(obj, Vec3d{}, opts, out, shape_flags);
  return n.ok() ? *n : 0;
}

Result<ObjectEntryView> CopyObjectEntry(std::span<const uint8_t> entry, ObjectId id,
                                        std::vector<uint8_t>* out) {
  ObjectEntryView e;
  MKTREE_RETURN_IF_ERROR(ParseObjectEntry(entry.data(), entry.size(), &e));
  if (e.entry_bytes() != entry.size())
    return Status::Corruption("object entry (id " + std::to_string(e.id) +
                              "): " + std::to_string(entry.size() - e.entry_bytes()) + " bytes past its end");
  const size_t start = out->size();
  out->insert(out->end(), entry.begin(), entry.end());
  Put<uint32_t>(out->data() + start, id);
  e.id = id;
  e.geometry = std::span<const uint8_t>(out->data() + start + kObjectEntryHeaderBytes, e.geometry.size());
  return e;
}

Result<ObjectEntryView> ParseObjectEntry(const uint8_t* data, size_t n) {
  ObjectEntryView e;
  MKTREE_RETURN_IF_ERROR(ParseObjectEntry(data, n, &e));
  return e;
}

Status ParseObjectEntry(const uint8_t* data, size_t n, ObjectEntryView* out) {
  if (n < kObjectEntryHeaderBytes) return Status::Corruption("object entry truncated");
  ObjectEntryView& e = *out;
  e.id = Get<uint32_t>(data);
  for (int i = 0; i < 3; ++i) {
    e.box.min[i] = Get<float>(data + 4 + 4 * i);
    e.box.max[i] = Get<float>(data + 16 + 4 * i);
  }
  const uint8_t codec = data[28];
  e.transform = data[29];
  e.shape_flags = data[30];
  e.vertex_count = Get<uint32_t>(data + 32);
  e.triangle_count = Get<uint32_t>(data + 36);
  e.raw_bytes = Get<uint32_t>(data + 40);
  const uint32_t stored = Get<uint32_t>(data + 44);
  // The message is built only on failure: queries parse every entry of every leaf they read.
  auto fail = [&](const std::string& what) {
    return Status::Corruption("object entry (id " + std::to_string(e.id) + "): " + what);
  };
  for (int i = 0; i < 3; ++i)
    if (!(std::isfinite(e.box.min[i]) && std::isfinite(e.box.max[i]) && e.box.min[i] <= e.box.max[i]))
      return fail("box is not finite, or its min exceeds its max");
  if (codec > 2) return fail("unknown codec " + std::to_string(codec));
  e.codec = static_cast<Codec>(codec);
  if (e.transform > 1 || (e.codec == Codec::kNone && e.transform != 0))
    return fail("unknown transform " + std::to_string(e.transform));
  if (e.shape_flags > (kShapeKnown | kShapeEvenEdges | kShapeClosed) ||
      (e.shape_flags != 0 && !(e.shape_flags & kShapeKnown)))
    return fail("unknown shape flags " + std::to_string(e.shape_flags));
  if (12 * (uint64_t{e.vertex_count} + e.triangle_count) != e.raw_bytes)
    return fail("geometry size does not match its counts");
  if (e.codec == Codec::kNone && stored != e.raw_bytes) return fail("stored size does not match raw size");
  if (stored > n - kObjectEntryHeaderBytes) return fail("runs past the end of the leaf");
  e.geometry = std::span<const uint8_t>(data + kObjectEntryHeaderBytes, stored);
  return Status::Ok();
}

Status DecodeObjectMesh(const ObjectEntryView& e, Mesh* mesh, const CodecDictionary* dictionary) {
  auto fail = [&](const std::string& what) {
    return Status::Corruption("object " + std::to_string(e.id) + ": " + what);
  };
  const size_t vc = e.vertex_count, nt = 3 * size_t{e.triangle_count};
  thread_local std::vector<float> local;
  if (e.codec == Codec::kNone) {
    if (e.geometry.size() != e.raw_bytes) return fail("geometry size mismatch");
    local.resize(3 * vc);
    mesh->triangles.resize(nt);
    CopyBytes(local.data(), e.geometry.data(), 12 * vc);
    CopyBytes(mesh->triangles.data(), e.geometry.data() + 12 * vc, 4 * nt);
  } else {
    thread_local std::vector<uint8_t> buf;
    buf.resize(e.raw_bytes);
    size_t r;
    if (e.codec == Codec::kZstdDict) {
      if (dictionary == nullptr) return fail("compressed with a dictionary, but the store has none");
      r = ZSTD_decompress_usingDDict(ThreadDCtx(), buf.data(), buf.size(), e.geometry.data(),
                                     e.geometry.size(), dictionary->ddict());
    } else {
      r = ZSTD_decompressDCtx(ThreadDCtx(), buf.data(), buf.size(), e.geometry.data(), e.geometry.size());
    }
    if (ZSTD_isError(r)) return fail(std::string("zstd: ") + ZSTD_getErrorName(r));
    if (r != e.raw_bytes) return fail("decompressed size mismatch");
    if (e.transform == 1) {
      InverseTransform(buf.data(), vc, nt, &local, mesh);
    } else {
      local.resize(3 * vc);
      mesh->triangles.resize(nt);
      CopyBytes(local.data(), buf.data(), 12 * vc);
      CopyBytes(mesh->triangles.data(), buf.data() + 12 * vc, 4 * nt);
    }
  }
  for (uint32_t t : mesh->triangles)
    if (t >= vc) return fail("triangle index out of range");
  double base[3], extent[3];
  for (int c = 0; c < 3; ++c) {
    base[c] = LocalBase(e.box.min[c], e.box.max[c]);
    extent[c] = static_cast<double>(e.box.max[c]) - e.box.min[c];
  }
  mesh->vertices.resize(3 * vc);
  for (size_t i = 0; i < 3 * vc; ++i) {
    const int c = static_cast<int>(i % 3);
    const double offset = static_cast<double>(local[i]) - base[c];  // exact: one exponent
    if (!(offset >= 0 && offset <= extent[c])) return fail("a vertex lies outside the object's box");
    mesh->vertices[i] = e.box.min[c] + offset;
  }
  return Status::Ok();
}

}  // namespace mktree
