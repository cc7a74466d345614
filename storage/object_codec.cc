#include "storage/object_codec.h"

#include <zstd.h>

#include <cstring>
#include <limits>
#include <memory>

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

// Transform 1 (see the header): raw geometry -> transformed bytes of the same size.
void ForwardTransform(const Mesh& m, uint8_t* out) {
  const size_t vc = m.vertex_count(), nt = m.triangles.size();
  std::vector<uint32_t> w(3 * vc + nt);
  for (int c = 0; c < 3; ++c) {
    uint32_t prev = 0;
    for (size_t i = 0; i < vc; ++i) {
      uint32_t bits;
      std::memcpy(&bits, &m.vertices[3 * i + c], 4);
      w[c * vc + i] = bits ^ prev;
      prev = bits;
    }
  }
  uint32_t prev = 0;
  for (size_t i = 0; i < nt; ++i) {
    const int32_t d = static_cast<int32_t>(m.triangles[i] - prev);
    w[3 * vc + i] = (static_cast<uint32_t>(d) << 1) ^ static_cast<uint32_t>(d >> 31);
    prev = m.triangles[i];
  }
  Shuffle4(w.data(), 3 * vc, out);
  Shuffle4(w.data() + 3 * vc, nt, out + 12 * vc);
}

void InverseTransform(const uint8_t* in, size_t vc, size_t nt, Mesh* m) {
  std::vector<uint32_t> w(3 * vc + nt);
  Unshuffle4(in, 3 * vc, w.data());
  Unshuffle4(in + 12 * vc, nt, w.data() + 3 * vc);
  m->vertices.resize(3 * vc);
  for (int c = 0; c < 3; ++c) {
    uint32_t prev = 0;
    for (size_t i = 0; i < vc; ++i) {
      prev ^= w[c * vc + i];
      std::memcpy(&m->vertices[3 * i + c], &prev, 4);
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

}  // namespace

uint32_t EncodeObjectEntry(const SceneObject& obj, const CodecOptions& opts, std::vector<uint8_t>* out,
                           uint8_t shape_flags) {
  const Mesh& m = obj.mesh;
  const uint64_t raw64 = 4 * uint64_t{m.vertices.size()} + 4 * uint64_t{m.triangles.size()};
  if (raw64 + kObjectEntryHeaderBytes > std::numeric_limits<uint32_t>::max() || m.vertices.size() % 3 != 0 ||
      m.triangles.size() % 3 != 0)
    return 0;
  const uint32_t raw = static_cast<uint32_t>(raw64);
  const size_t start = out->size();

  Codec codec = Codec::kNone;
  uint8_t transform = 0;
  std::vector<uint8_t> packed;  // the bytes that go to zstd
  std::vector<uint8_t> compressed;
  if (opts.codec == Codec::kZstd && raw > 0) {
    packed.resize(raw);
    if (opts.shuffle) {
      ForwardTransform(m, packed.data());
    } else {
      CopyBytes(packed.data(), m.vertices.data(), 4 * m.vertices.size());
      CopyBytes(packed.data() + 4 * m.vertices.size(), m.triangles.data(), 4 * m.triangles.size());
    }
    compressed.resize(ZSTD_compressBound(raw));
    ZSTD_CCtx* cctx = ThreadCCtx();
    ZSTD_CCtx_reset(cctx, ZSTD_reset_session_and_parameters);
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, opts.zstd_level);
    // The raw size is in the entry header; leaving it out of the frame saves bytes on small meshes.
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 0);
    const size_t z = ZSTD_compress2(cctx, compressed.data(), compressed.size(), packed.data(), raw);
    if (!ZSTD_isError(z) && z < raw) {
      compressed.resize(z);
      codec = Codec::kZstd;
      transform = opts.shuffle ? 1 : 0;
    }
  }
  const uint32_t stored = codec == Codec::kZstd ? static_cast<uint32_t>(compressed.size()) : raw;
  out->resize(start + kObjectEntryHeaderBytes + stored);
  uint8_t* p = out->data() + start;
  const Box3f box = obj.Aabb();
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
  if (codec == Codec::kZstd) {
    std::memcpy(g, compressed.data(), stored);
  } else if (raw > 0) {
    CopyBytes(g, m.vertices.data(), 4 * m.vertices.size());
    CopyBytes(g + 4 * m.vertices.size(), m.triangles.data(), 4 * m.triangles.size());
  }
  return kObjectEntryHeaderBytes + stored;
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
  if (codec > 1) return fail("unknown codec " + std::to_string(codec));
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

Status DecodeObjectMesh(const ObjectEntryView& e, Mesh* mesh) {
  auto fail = [&](const std::string& what) {
    return Status::Corruption("object " + std::to_string(e.id) + ": " + what);
  };
  const size_t vc = e.vertex_count, nt = 3 * size_t{e.triangle_count};
  if (e.codec == Codec::kNone) {
    if (e.geometry.size() != e.raw_bytes) return fail("geometry size mismatch");
    mesh->vertices.resize(3 * vc);
    mesh->triangles.resize(nt);
    CopyBytes(mesh->vertices.data(), e.geometry.data(), 12 * vc);
    CopyBytes(mesh->triangles.data(), e.geometry.data() + 12 * vc, 4 * nt);
  } else {
    thread_local std::vector<uint8_t> buf;
    buf.resize(e.raw_bytes);
    const size_t r = ZSTD_decompressDCtx(ThreadDCtx(), buf.data(), buf.size(), e.geometry.data(), e.geometry.size());
    if (ZSTD_isError(r)) return fail(std::string("zstd: ") + ZSTD_getErrorName(r));
    if (r != e.raw_bytes) return fail("decompressed size mismatch");
    if (e.transform == 1) {
      InverseTransform(buf.data(), vc, nt, mesh);
    } else {
      mesh->vertices.resize(3 * vc);
      mesh->triangles.resize(nt);
      CopyBytes(mesh->vertices.data(), buf.data(), 12 * vc);
      CopyBytes(mesh->triangles.data(), buf.data() + 12 * vc, 4 * nt);
    }
  }
  for (uint32_t t : mesh->triangles)
    if (t >= vc) return fail("triangle index out of range");
  return Status::Ok();
}

}  // namespace mktree
